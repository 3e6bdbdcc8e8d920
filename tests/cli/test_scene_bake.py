"""`atlasgen bake --scene`: the atlas holds exactly the scene's materials, with their library IDs."""

import json

import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app

SCENE = """
[camera]
position = [0, 0, 5]
target = [0, 0, 0]
fov = 40

[[objects]]
shape = "sphere"
material = "{first}"

[[objects]]
shape = "box"
material = "{second}"
translate = [1.5, 0, 0]
"""


def _bake(*args):
    res = CliRunner().invoke(app, ["bake", *map(str, args)])
    return res


def test_scene_atlas_holds_exactly_its_materials_with_stable_ids(tmp_path, write_material):
    for name in ("alpha", "bravo", "charlie", "delta"):
        write_material(name, 'type = "lambert"\n')
    library = tmp_path / "materials"
    full = tmp_path / "full.dds"
    assert _bake(library, "-o", full, "-q").exit_code == 0
    full_ids = {m["name"]: m["id"] for m in json.loads(full.with_suffix(".json").read_text())["materials"]}

    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(first="delta", second="bravo"))
    out = tmp_path / "scene.dds"
    res = _bake(library, "--scene", scene, "--ids-from", full.with_suffix(".json"), "-o", out, "-q")
    assert res.exit_code == 0, res.output
    entries = json.loads(out.with_suffix(".json").read_text())["materials"]
    assert {m["name"] for m in entries} == {"bravo", "delta"}
    assert all(m["id"] == full_ids[m["name"]] for m in entries)
    assert "MATERIAL_ALPHA" not in out.with_suffix(".wgsl").read_text()


def test_a_scene_atlas_baked_again_takes_the_library_s_new_ids(tmp_path, write_material):
    """The scene atlas's own old manifest outranked --ids-from: once the library was renumbered (its manifest
    deleted, a material added before the others by name), a re-baked scene kept its old IDs, and one g-buffer
    ID meant two materials in the two atlases."""
    for name in ("bravo", "delta"):
        write_material(name, 'type = "lambert"\n')
    library, full, out = tmp_path / "materials", tmp_path / "full.dds", tmp_path / "scene.dds"
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(first="delta", second="bravo"))
    assert _bake(library, "-o", full, "-q").exit_code == 0
    assert _bake(library, "--scene", scene, "--ids-from", full.with_suffix(".json"), "-o", out, "-q").exit_code == 0
    write_material("alpha", 'type = "lambert"\n')
    full.with_suffix(".json").unlink()
    assert _bake(library, "-o", full, "-q").exit_code == 0  # renumbered by name: alpha 0, bravo 1, delta 2
    res = _bake(library, "--scene", scene, "--ids-from", full.with_suffix(".json"), "-o", out, "-q")
    assert res.exit_code == 0, res.output
    ids = {path: {m["name"]: m["id"] for m in json.loads(path.read_text())["materials"]}
           for path in (full.with_suffix(".json"), out.with_suffix(".json"))}  # fmt: skip
    assert ids[full.with_suffix(".json")] == {"alpha": 0, "bravo": 1, "delta": 2}
    assert ids[out.with_suffix(".json")] == {"bravo": 1, "delta": 2}


def test_ids_from_wins_over_the_atlas_s_own_manifest_whatever_the_names(tmp_path, write_material):
    """The atlas's own manifest gave 'grey' slice 0, --ids-from gave 'terracotta' slice 0: by name grey kept it, so
    terracotta took 1 against the library's 0, and the same command into an empty folder wrote other bytes."""
    for name in ("grey", "terracotta", "toon"):
        write_material(name, 'type = "lambert"\n')
    m = tmp_path / "materials"
    library = tmp_path / "lib.json"
    library.write_text(json.dumps({"materials": [{"name": "terracotta", "first_slice": 0}, {"name": "toon", "first_slice": 1}]}))
    used, fresh = tmp_path / "used" / "a.dds", tmp_path / "fresh" / "a.dds"
    assert _bake(m / "grey.toml", "-o", used, "-q").exit_code == 0
    for out in (used, fresh):
        res = _bake(m / "grey.toml", m / "terracotta.toml", "--ids-from", library, "-o", out, "-q")
        assert res.exit_code == 0, res.output
    ids = {m["name"]: m["id"] for m in json.loads(used.with_suffix(".json").read_text())["materials"]}
    assert ids == {"terracotta": 0, "grey": 2}  # not 1 either: the library gives it to toon, which this atlas lacks
    assert used.read_bytes() == fresh.read_bytes()


def test_an_explicit_id_on_an_ids_from_slice_names_the_ids_from_manifest(tmp_path, write_material):
    """It blamed "the previous manifest", which did not exist, and told the user to delete it."""
    write_material("grey", 'type = "lambert"\nid = 0\n')
    write_material("terracotta", 'type = "lambert"\n')
    library = tmp_path / "lib.json"
    library.write_text(json.dumps({"materials": [{"name": "terracotta", "first_slice": 0}]}))
    out = tmp_path / "out" / "a.dds"
    res = _bake(tmp_path / "materials", "--ids-from", library, "-o", out)
    assert res.exit_code == 3 and not out.parent.exists()
    assert res.output.strip().endswith(
        f"material 'terracotta' needs slice 0 where --ids-from {library.as_posix()} puts it, and slice 0 holds 'grey'; "
        f"expected the library's slices free (re-bake {library.as_posix()}, or change the explicit id)"
    )
    assert len(res.output.strip().splitlines()) == 1 and "previous manifest" not in res.output


def test_a_scene_with_no_objects_says_the_atlas_holds_no_materials(tmp_path, write_material):
    """It baked an empty atlas with exit 0 and no word, where an empty folder is warned about."""
    write_material("alpha", 'type = "lambert"\n')
    scene = tmp_path / "empty.toml"
    scene.write_text(SCENE.split("[[objects]]")[0])
    out = tmp_path / "a.dds"
    res = _bake(tmp_path / "materials", "--scene", scene, "-o", out)
    assert res.exit_code == 0, res.output
    assert f"{scene.as_posix()}: the scene has no objects; the atlas holds no materials" in res.output
    assert json.loads(out.with_suffix(".json").read_text())["materials"] == []


def test_scene_with_an_unknown_material_is_refused(tmp_path, write_material):
    write_material("alpha", 'type = "lambert"\n')
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(first="alpha", second="zulu"))
    res = _bake(tmp_path / "materials", "--scene", scene, "-o", tmp_path / "a.dds")
    assert res.exit_code == 3
    assert "scene.toml: field 'objects[1].material': unknown material 'zulu'; known: alpha" in res.stderr
    assert not (tmp_path / "a.dds").exists()


def test_a_misspelt_material_gets_the_closest_library_name(tmp_path, write_material):
    for name in ("alpha", "bravo"):
        write_material(name, 'type = "lambert"\n')
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(first="alpha", second="brava"))
    res = _bake(tmp_path / "materials", "--scene", scene, "-o", tmp_path / "a.dds")
    assert res.exit_code == 3
    assert "unknown material 'brava' (did you mean 'bravo'?); known: alpha, bravo" in res.stderr


def test_the_depfile_names_exactly_the_scene_materials_and_their_cache_entries(tmp_path, write_material):
    for name in ("alpha", "bravo", "charlie"):
        write_material(name, 'type = "lambert"\n')
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(first="charlie", second="alpha"))
    out, dep, cache = tmp_path / "s.dds", tmp_path / "s.d", tmp_path / "cache"
    res = _bake(tmp_path / "materials", "--scene", scene, "--cache", cache, "--depfile", dep, "-o", out, "-q")
    assert res.exit_code == 0, res.output
    rule = dep.read_text().split("\n\n")[0].replace("\\\n", " ")
    target, prerequisites = rule.split(":", 1)
    assert target == out.as_posix()
    named = set(prerequisites.split())
    materials = tmp_path / "materials"
    assert named == {
        (materials / "alpha.toml").as_posix(),
        (materials / "charlie.toml").as_posix(),
        scene.as_posix(),
        (cache / "alpha.npz").as_posix(),
        (cache / "charlie.npz").as_posix(),
    }
    assert all((cache / f"{n}.npz").is_file() for n in ("alpha", "charlie")) and not (cache / "bravo.npz").exists()


def test_a_cache_only_bake_writes_a_depfile_for_the_target_it_is_given(tmp_path, write_material):
    """--cache-only writes no atlas: its depfile names the --depfile-target (the Makefile's stamp of a MaterialX
    document) against the material files; without one it is refused before anything is baked."""
    write_material("alpha", 'type = "lambert"\n')
    source, dep, cache = tmp_path / "materials" / "alpha.toml", tmp_path / "cache" / "alpha.d", tmp_path / "cache"
    refused = _bake(source, "--cache", cache, "--cache-only", "--depfile", dep)
    assert refused.exit_code == 2 and "--depfile with --cache-only needs --depfile-target" in refused.stderr
    assert not cache.exists()
    stamp = cache / "alpha.stamp"
    res = _bake(source, "--cache", cache, "--cache-only", "--depfile", dep, "--depfile-target", stamp, "-q")
    assert res.exit_code == 0, res.output
    assert dep.read_text() == f"{stamp.as_posix()}: \\\n  {source.as_posix()}\n\n{source.as_posix()}:\n"
    assert (cache / "alpha.npz").is_file() and not stamp.exists()


@pytest.mark.parametrize("option", [("-o", "x.dds"), ("--preview", "p.png"), ("--strict",), ("--linear",),
                                    ("--include", "wgsl"), ("--ids-from", "a.json"), ("--zstd",), ("--layout", "volume"),
                                    ("--allow-empty",)])  # fmt: skip
def test_an_atlas_option_with_cache_only_is_refused_not_ignored(tmp_path, write_material, option):
    write_material("alpha", 'type = "lambert"\n')
    cache = tmp_path / "cache"
    res = _bake(tmp_path / "materials" / "alpha.toml", "--cache", cache, "--cache-only", *option)
    long_name = {"-o": "--output"}.get(option[0], option[0])
    assert res.exit_code == 2 and f"{long_name} has no effect with --cache-only, which writes no atlas" in res.stderr
    assert not cache.exists()


def test_an_unknown_include_language_is_named_on_a_short_line(tmp_path, write_material):
    """A 100,000-character value was echoed whole, a 100 kB error line."""
    write_material("alpha", 'type = "lambert"\n')
    for value, shown in (("wgsl,metal", "'metal'"), ("x" * 100_000, "'xxxxxxxx")):
        res = _bake(tmp_path / "materials" / "alpha.toml", "-o", tmp_path / "a.dds", "--include", value)
        assert res.exit_code == 2 and f"--include: unknown language {shown}" in res.stderr, res.stderr
        assert len(res.stderr) < 300 and not (tmp_path / "a.dds").exists()
