"""The CLI: exit codes, messages on stderr, untouched outputs on failure, and the summary line."""

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path
from xml.etree import ElementTree

import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app


@pytest.fixture
def runner():
    return CliRunner()


@pytest.fixture
def library(write_material, tmp_path):
    write_material("clay", 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n')
    write_material("snow", 'type = "lambert"\nid = 9\n')
    return tmp_path / "materials"


def test_bake_writes_all_outputs_and_a_texconv_summary(runner, library, tmp_path):
    out = tmp_path / "build" / "atlas.dds"
    res = runner.invoke(app, ["bake", str(library), "-o", str(out), "--preview", str(tmp_path / "build" / "p.png")])
    assert res.exit_code == 0, res.output
    assert res.stdout.strip() == f"{out.as_posix()} (64x32, 7 mips, 256 layers, R8G8B8A8_UNORM_SRGB, 2DArray)"
    for suffix in (".dds", ".json", ".wgsl", ".timings.json"):
        assert (tmp_path / "build" / f"atlas{suffix}").stat().st_size > 0
    assert (tmp_path / "build" / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    manifest = json.loads((tmp_path / "build" / "atlas.json").read_text())
    assert [m["name"] for m in manifest["materials"]] == ["clay", "snow"]
    assert not list((tmp_path / "build").glob(".*.tmp"))


def test_volume_and_linear_summary(runner, library, tmp_path):
    out = tmp_path / "v.dds"
    res = runner.invoke(app, ["bake", str(library), "-o", str(out), "--layout", "volume", "--linear"])
    assert res.exit_code == 0
    assert res.stdout.strip() == f"{out.as_posix()} (64x32x256, 9 mips, R8G8B8A8_UNORM, 3D)"
    assert "volume layout" in res.stderr


def test_quiet_prints_nothing(runner, library, tmp_path):
    res = runner.invoke(app, ["bake", str(library), "-o", str(tmp_path / "a.dds"), "-q"])
    assert res.exit_code == 0 and res.output == ""


def test_info_text_and_json(runner, library, tmp_path):
    out = tmp_path / "a.dds"
    runner.invoke(app, ["bake", str(library), "-o", str(out), "-q"])
    text = runner.invoke(app, ["info", str(out)])
    assert text.exit_code == 0 and "R8G8B8A8_UNORM_SRGB" in text.output and "snow" in text.output
    data = json.loads(runner.invoke(app, ["info", str(out), "--format", "json"]).output)
    assert data["header"]["layers"] == 256 and data["header"]["mip_count"] == 7
    assert data["manifest"]["slices_used"] == 2


BAD_CASES = {
    "malformed TOML": ('type = "lambert"\ncolour = [', "bad.toml: malformed TOML"),
    "unknown type": ('type = "plasticky"\n', "bad.toml: field 'type': unknown model"),
    "unknown key": ('type = "lambert"\ncolur = [1, 1, 1]\n', "bad.toml: field 'colur': unknown key"),
    "nan": ('type = "lambert"\ncolour = [nan, 0, 0]\n', "bad.toml: field 'colour'"),
    "duplicate id": ('type = "lambert"\nid = 9\n', "field 'id'"),
    "duplicate name": ('type = "lambert"\nname = "clay"\n', "field 'name': duplicate material name 'clay'"),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_material_fails_cleanly_and_leaves_outputs_untouched(runner, library, write_material, tmp_path, case):
    out = tmp_path / "build" / "atlas.dds"
    assert runner.invoke(app, ["bake", str(library), "-o", str(out), "-q"]).exit_code == 0
    before = {p.name: p.read_bytes() for p in out.parent.iterdir() if p.is_file()}  # the outputs, through their links
    text, expected = BAD_CASES[case]
    write_material("bad", text)
    res = runner.invoke(app, ["bake", str(library), "-o", str(out)])
    assert res.exit_code == 3
    assert res.stdout == ""
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("atlasgen: error: ") and expected in lines[0]
    assert {p.name: p.read_bytes() for p in out.parent.iterdir() if p.is_file()} == before


@pytest.mark.slow
def test_more_materials_than_slices(runner, tmp_path):
    folder = tmp_path / "many"
    folder.mkdir()
    for i in range(257):
        (folder / f"m{i:03d}.toml").write_text('type = "lambert"\n')
    res = runner.invoke(app, ["bake", str(folder), "-o", str(tmp_path / "a.dds")])
    assert res.exit_code == 3 and "expected at most 256" in res.stderr
    assert not (tmp_path / "a.dds").exists()


def test_missing_input_path(runner, tmp_path):
    res = runner.invoke(app, ["bake", str(tmp_path / "nowhere"), "-o", str(tmp_path / "a.dds")])
    assert res.exit_code == 3 and "nowhere: no such file or folder" in res.stderr


def test_a_folder_given_as_a_scene_or_an_atlas_is_bad_input(runner, tmp_path):
    """Exit 3 with the reader's line, as a missing scene gets, not click's usage error (2)."""
    folder = tmp_path / "scene.toml"
    folder.mkdir()
    res = runner.invoke(app, ["render", str(folder), "-o", str(tmp_path / "a.exr")])
    assert res.exit_code == 3 and res.stderr.strip().endswith(f"{folder.as_posix()}: expected UTF-8 TOML text, got a directory")
    scene = Path(__file__).resolve().parents[2] / "scenes" / "demo.toml"
    for command in (["render", str(scene), "--atlas", str(folder), "-o", str(tmp_path / "a.exr")],
                    ["validate", "--atlas", str(folder)]):  # fmt: skip
        res = runner.invoke(app, command)
        assert res.exit_code == 3, res.stderr
        assert res.stderr.strip().endswith(f"{folder.as_posix()}: expected an atlas texture (DDS or KTX2), got a directory")


def test_an_atlas_that_is_a_pipe_a_device_or_too_large_is_refused_before_it_is_read(runner, tmp_path):
    """``info`` read a named pipe forever and /dev/zero until memory ran out (exit 1)."""
    pipe, big = tmp_path / "pipe.dds", tmp_path / "big.ktx2"
    os.mkfifo(pipe)
    big.write_bytes(b"\0" * (16 * 2**20 + 1))
    for path, expected in ((big, "16777217 bytes; expected an atlas texture (DDS or KTX2), at most 16777216 bytes"),
                           (pipe, "expected a regular file, got a named pipe")):  # fmt: skip
        res = runner.invoke(app, ["info", str(path)])
        assert res.exit_code == 3 and res.stderr.strip() == f"atlasgen: error: {path.as_posix()}: {expected}", res.stderr


def test_unwritable_output_folder(runner, library, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    res = runner.invoke(app, ["bake", str(library), "-o", str(blocker / "atlas.dds")])
    assert res.exit_code == 4 and "the atlas (-o): cannot write its folder" in res.stderr, res.stderr
    assert blocker.read_text() == "not a folder"


@pytest.mark.slow
def test_lut_bake_imports_no_heavy_backend(library, tmp_path):
    code = (
        "import sys; from atlasgen.cli.main import main\n"
        f"try: main(['bake', {str(library)!r}, '-o', {str(tmp_path / 'a.dds')!r}, '-q'])\n"
        "except SystemExit as e: assert not e.code, e.code\n"
        "heavy = sorted(m for m in ('mitsuba', 'drjit', 'wgpu', 'matplotlib', 'OpenImageIO', 'MaterialX', 'moderngl')"
        " if m in sys.modules)\n"
        "print(','.join(heavy))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_help_lists_commands(runner):
    res = runner.invoke(app, ["--help"])
    assert res.exit_code == 0 and "bake" in res.output and "info" in res.output


@pytest.mark.parametrize("module, name", [("report_cmd", "report"), ("render_cmd", "render"), ("preview_cmd", "preview"),
                                          ("validate_cmd", "validate")])  # fmt: skip
def test_a_command_run_on_its_own_keeps_its_help_options(module, name):
    """click keeps the help option it first builds for a command: built for a command run on its own (a test's
    CliRunner, with no parent to inherit -h from), it was --help alone, and the generated reference then
    depended on which tests a worker had run before (it failed so once)."""
    import importlib

    command = getattr(importlib.import_module(f"atlasgen.cli.{module}"), name)
    res = CliRunner().invoke(command, ["-h"])
    assert res.exit_code == 0 and res.output.startswith(f"Usage: {name} [OPTIONS]"), res.output
    assert "-h, --help  " in res.output


def test_cli_reference_is_generated_from_the_app():
    from pathlib import Path

    from atlasgen.cli.docgen import render_cli_reference

    text = render_cli_reference()
    assert "## `atlasgen bake`" in text and "--layout [array|volume]" in text
    stale = Path(__file__).resolve().parents[2] / "docs" / "cli.md"
    assert stale.read_text() == text, "docs/cli.md is stale: run python -m atlasgen.cli.docgen"


@pytest.mark.parametrize(
    "argv",
    [["-m", "atlasgen"], ["-c", "from atlasgen.cli.main import main; main([])"]],
    ids=["python -m atlasgen", "bare atlasgen"],
)
@pytest.mark.slow
def test_bare_atlasgen_and_python_m_print_the_help_and_succeed(argv):
    out = subprocess.run([sys.executable, *argv], capture_output=True, text=True)
    assert out.returncode == 0 and out.stderr == ""
    assert out.stdout.startswith("Usage: atlasgen [OPTIONS] [COMMAND] [ARGS]...") and "validate" in out.stdout


def test_bake_verbose_says_what_each_material_took(runner, library, tmp_path):
    args = ["bake", str(library), "-o", str(tmp_path / "a.dds"), "--cache", str(tmp_path / "cache"), "-v"]
    first = runner.invoke(app, args)
    assert first.exit_code == 0, first.output
    lines = first.stderr.splitlines()
    assert [line.split(", baked in ")[0] for line in lines] == ["  clay: lambert, slice 0", "  snow: lambert, slice 9"]
    again = runner.invoke(app, args)
    assert again.stderr.splitlines() == ["  clay: lambert, slice 0, loaded from the cache",
                                         "  snow: lambert, slice 9, loaded from the cache"]  # fmt: skip
    assert again.stdout == first.stdout and again.stdout.startswith(f"{(tmp_path / 'a.dds').as_posix()} (64x32")


def test_bake_library_bakes_the_installed_library(runner, tmp_path, monkeypatch, shipped_library_cache):
    from atlasgen.io.package_data import shipped_library

    monkeypatch.chdir(tmp_path)  # no materials/ here: the library is found in the package
    # Assembled from the session's cache of the same files: the fits are the goldens' to check.
    res = runner.invoke(app, ["bake", "--library", "--layout", "volume", "-q", "--cache", str(shipped_library_cache)])
    assert res.exit_code == 0, res.output
    manifest = json.loads((tmp_path / "build" / "atlas.json").read_text())
    shipped = sorted([*shipped_library().glob("*.toml"), *shipped_library().glob("*.mtlx")])
    # A TOML file is one material named by its stem, hashed by its bytes; a MaterialX document is
    # one per surfacematerial (read here with the standard library's XML parser, not atlasgen's
    # reader), hashed by its name and the parameters the manifest shows, as canonical JSON.
    entries = {m["name"]: m for m in manifest["materials"]}
    expected = []
    for p in shipped:
        data = p.read_bytes()
        if p.suffix == ".toml":
            expected.append((p.stem, hashlib.sha256(data).hexdigest()))
        else:
            for node in ElementTree.fromstring(data).iter("surfacematerial"):
                name = node.get("name")
                shown = {"name": name, "params": entries[name]["params"]}
                assert shown["params"]["materialx"]["document"] == p.name  # no path: the same wherever it lies
                expected.append((name, hashlib.sha256(json.dumps(shown, sort_keys=True).encode()).hexdigest()))
    assert any(p.suffix == ".mtlx" for p in shipped)
    # Slots, and so the manifest's entries, go in name order (atlasgen/bake/slots.py).
    assert [(m["name"], m["content_hash"]) for m in manifest["materials"]] == sorted(expected)
    # The repository's materials/ is that library (atlasgen/data/materials links to it).
    root = Path(__file__).resolve().parents[2]
    mine = sorted([*(root / "materials").glob("*.toml"), *(root / "materials").glob("*.mtlx")])
    assert [p.read_bytes() for p in shipped] == [p.read_bytes() for p in mine]


def test_info_quiet_and_verbose(runner, library, tmp_path):
    out = tmp_path / "a.dds"
    runner.invoke(app, ["bake", str(library), "-o", str(out), "-q"])
    normal = runner.invoke(app, ["info", str(out)]).stdout.splitlines()
    assert runner.invoke(app, ["info", str(out), "-q"]).stdout.splitlines() == normal[:1]
    verbose = runner.invoke(app, ["info", str(out), "-v"]).stdout.splitlines()
    assert verbose[: len(normal) - 2] == normal[:-2]
    assert verbose[-1].strip() == f"(no description); from {(library / 'snow.toml').as_posix()}"
    assert len(verbose) == len(normal) + 2


def test_info_keeps_a_description_s_control_characters_on_its_line(runner, tmp_path):
    """A description is free text: its line break and a terminal escape broke info -v's lines."""
    material = tmp_path / "clay.toml"
    material.write_text('type = "lambert"\ndescription = "line one\\nline two\\u001b[31m red"\n')
    out = tmp_path / "a.dds"
    assert runner.invoke(app, ["bake", str(material), "-o", str(out), "-q"]).exit_code == 0
    lines = runner.invoke(app, ["info", str(out), "-v"]).stdout.splitlines()
    assert lines[-1].strip() == f"line one\\nline two\\x1b[31m red; from {material.as_posix()}", lines


def test_every_command_that_asks_an_entry_s_model_refuses_an_unknown_one(runner, library, tmp_path):
    """A manifest edited to a type no model has: report library and validate ended in KeyError (exit 1)."""
    atlas = tmp_path / "a.dds"
    assert runner.invoke(app, ["bake", str(library), "-o", str(atlas), "-q"]).exit_code == 0
    manifest = atlas.with_suffix(".json")
    data = json.loads(manifest.read_text())
    data["materials"][0]["type"] = "nosuchmodel"
    manifest.unlink()  # a link into the bake's output set: replaced, not written through
    manifest.write_text(json.dumps(data))
    for command in (["report", "library", "--atlas", str(atlas), "-o", str(tmp_path / "report"), "--no-physical"],
                    ["validate", "--atlas", str(atlas), "-o", str(tmp_path / "validation")]):  # fmt: skip
        res = runner.invoke(app, command)
        assert res.exit_code == 3, (command, res.output)
        assert res.stderr.strip().startswith(f"atlasgen: error: {manifest.as_posix()}: field 'materials[0].type': expected "
                                             "one of the models atlasgen knows (")  # fmt: skip
    assert not (tmp_path / "report").exists() and not (tmp_path / "validation").exists()


def _edit_manifest(atlas: Path, edit) -> Path:
    """Apply ``edit`` to the manifest beside ``atlas`` (a link into the bake's output set: replaced, not written through)."""
    manifest = atlas.with_suffix(".json")
    data = json.loads(manifest.read_text())
    edit(data["materials"])
    manifest.unlink()
    manifest.write_text(json.dumps(data))
    return manifest


def test_every_command_that_reads_a_manifest_refuses_a_parameter_its_model_would(runner, library, tmp_path):
    """A colour edited to a string: info and report library exited 0 (the page's Pareto note named '<manifest
    params>'); each command now names the manifest's field, as a material file's would be."""
    atlas = tmp_path / "a.dds"
    assert runner.invoke(app, ["bake", str(library), "-o", str(atlas), "-q"]).exit_code == 0
    manifest = _edit_manifest(atlas, lambda materials: materials[0]["params"].update(colour="oops"))
    for command in (["info", str(atlas)],
                    ["report", "library", "--atlas", str(atlas), "-o", str(tmp_path / "report")],
                    ["report", "library", "--atlas", str(atlas), "-o", str(tmp_path / "report"), "--no-physical"],
                    ["validate", "--atlas", str(atlas), "-o", str(tmp_path / "validation")]):  # fmt: skip
        res = runner.invoke(app, command)
        assert res.exit_code == 3, (command, res.output)
        assert res.stderr == (f"atlasgen: error: {manifest.as_posix()}: field 'materials[0].params.colour': expected a "
                              "colour [r, g, b] or '#rrggbb', got 'oops'\n")  # fmt: skip
    assert not (tmp_path / "report").exists() and not (tmp_path / "validation").exists()


def test_a_parameter_nested_beyond_the_recursion_limit_is_named_in_one_line(runner, library, tmp_path):
    """A colour of lists 600 deep: writing the value into the line recursed past Python's limit (RecursionError,
    an internal error) in info, render and validate."""
    atlas = tmp_path / "a.dds"
    assert runner.invoke(app, ["bake", str(library), "-o", str(atlas), "-q"]).exit_code == 0
    nested = 0
    for _ in range(600):
        nested = [nested]
    manifest = _edit_manifest(atlas, lambda materials: materials[0]["params"].update(colour=nested))
    res = runner.invoke(app, ["info", str(atlas)])
    assert res.exit_code == 3, res.output
    assert res.stderr.startswith(f"atlasgen: error: {manifest.as_posix()}: field 'materials[0].params.colour': expected a "
                                 "colour [r, g, b] of 3 numbers in [0, 1], got [[[[")  # fmt: skip
    assert len(res.stderr.splitlines()) == 1


def test_a_manifest_of_another_model_version_is_named_by_every_command(runner, library, tmp_path):
    """A parameter set other than the model's (another atlasgen's bake): said once for every command, not only by
    validate."""
    atlas = tmp_path / "a.dds"
    assert runner.invoke(app, ["bake", str(library), "-o", str(atlas), "-q"]).exit_code == 0
    manifest = _edit_manifest(atlas, lambda materials: materials[1]["params"].update(gain=2.0))
    res = runner.invoke(app, ["info", str(atlas)])
    assert res.exit_code == 3, res.output
    assert res.stderr == (f"atlasgen: error: {manifest.as_posix()}: field 'materials[1].params': expected the current "
                          "'lambert' model's parameters, got others (unknown gain): an atlas baked by another atlasgen; "
                          "re-run atlasgen bake\n")  # fmt: skip


def test_the_library_report_checks_the_params_its_charts_rebuild_references_from(runner, write_material, tmp_path):
    """Thresholds edited out of order, which only the model's own check sees: the Pareto charts rebuild each
    material's reference from its params, so the report refuses them, naming the field; without the charts
    (--no-physical) nothing reads them."""
    write_material("cel", 'type = "toon"\nthresholds = [0.2, 0.6]\ncolours = [[0.1, 0.1, 0.1], [0.5, 0.5, 0.5], '
                          '[1, 1, 1]]\n')  # fmt: skip
    atlas = tmp_path / "a.dds"
    assert runner.invoke(app, ["bake", str(tmp_path / "materials"), "-o", str(atlas), "-q"]).exit_code == 0
    manifest = _edit_manifest(atlas, lambda materials: materials[0]["params"].update(thresholds=[0.6, 0.2]))
    res = runner.invoke(app, ["report", "library", "--atlas", str(atlas), "-o", str(tmp_path / "report")])
    assert res.exit_code == 3, res.output
    assert res.stderr == (f"atlasgen: error: {manifest.as_posix()}: field 'materials[0].params.thresholds': expected "
                          "strictly ascending values, got [0.6, 0.2]\n")  # fmt: skip
    assert not (tmp_path / "report").exists()
    res = runner.invoke(app, ["report", "library", "--atlas", str(atlas), "-o", str(tmp_path / "report"), "--no-physical"])
    assert res.exit_code == 0, res.output
