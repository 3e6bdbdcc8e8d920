"""The Makefile's dependency graph: each change re-runs exactly the per-material jobs it affects.

Dry runs (``make -n``) in a copy of the tree whose outputs all exist and are up to
date; one input is then made newer and the commands make would run are read back.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from atlasgen.io.depfile import write_depfile

ROOT = Path(__file__).resolve().parents[1]
MATERIALS = ("clay", "snow", "separable-gold")
SEPARABLE = ("separable-gold",)
#: Scene -> the materials it uses, as the bake's --depfile records them.
SCENES = {"one": ("clay",), "two": ("snow", "separable-gold")}
#: Files a scene's render reads besides its scene file and atlas set, as the render's --depfile records them.
RENDER_READS = {"one": ["scenes/env/sky.exr", "elsewhere/gem.obj"]}
#: What a scene's bake writes, one set (the Makefile's BAKE_SUFFIXES).
SCENE_SET = ("dds", "json", "wgsl", "glsl", "hlsl", "timings.json")
T0 = 1_700_000_000  # sources
T_BUILT = T0 + 100  # every output, all equally new: make treats them as up to date

pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="GNU make is not installed")


def _outputs(build: Path) -> list[Path]:
    """Every file the pipeline's rules name as a target (what `make demo` leaves behind)."""
    out = [build / "validation" / "report.json", build / "report" / "separable" / "index.md", build / "report" / "index.html"]
    out += [build / f"atlas{suffix}" for suffix in (".dds", ".json", ".wgsl", ".glsl", ".hlsl", ".timings.json", "-preview.png")]
    out += [build / "cache" / f"{m}.{ext}" for m in MATERIALS for ext in ("npz", "d")]
    out += [build / "validation" / "materials" / m / "report.json" for m in MATERIALS]
    out += [build / "report" / "separable" / "materials" / m / "report.json" for m in SEPARABLE]
    out += [build / "scenes" / f"{scene}.{ext}" for scene in SCENES for ext in SCENE_SET + ("exr", "png", "d", "png.d")]
    out += [build / "scenes" / ".pruned"]
    return out


@pytest.fixture
def tree(tmp_path):
    """A copy of the Makefile, the code and scenes it names, three material files, and a
    complete, up-to-date build folder."""
    root = tmp_path / "tree"
    root.mkdir()
    shutil.copy(ROOT / "Makefile", root)
    for folder in ("atlasgen", "scenes"):
        shutil.copytree(ROOT / folder, root / folder, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    for scene in (root / "scenes").glob("*.toml"):
        scene.unlink()
    for scene in SCENES:
        (root / "scenes" / f"{scene}.toml").write_text("")
    (root / "materials").mkdir()
    for m in MATERIALS:
        # Make finds separable materials by their type, whatever the file is called.
        kind = "separable" if m in SEPARABLE else "lambert"
        (root / "materials" / f"{m}.toml").write_text(f"type = '{kind}'\n" if kind == "separable" else f'type = "{kind}"\n')
    (root / "pyproject.toml").write_text("")
    (root / ".venv").mkdir()
    (root / ".venv" / ".stamp").write_text("")
    for path in _outputs(root / "build"):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("")
    for m in MATERIALS:  # what a cache entry's bake records (--depfile): the material file, and any file it names
        write_depfile(root / "build" / "cache" / f"{m}.d", f"build/cache/{m}.npz", [f"materials/{m}.toml"])
    for scene, used in SCENES.items():
        inputs = [f"materials/{m}.toml" for m in used] + [f"scenes/{scene}.toml"] + [f"build/cache/{m}.npz" for m in used]
        write_depfile(root / "build" / "scenes" / f"{scene}.d", f"build/scenes/{scene}.dds", inputs)
        # What the render read, as its --depfile records it: scene one lights with an image of its own.
        read = [f"scenes/{scene}.toml"] + [f"build/scenes/{scene}.{ext}" for ext in ("dds", "json", "wgsl")]
        read += RENDER_READS.get(scene, [])
        write_depfile(root / "build" / "scenes" / f"{scene}.png.d", f"build/scenes/{scene}.png", read)
    for path in {p for files in RENDER_READS.values() for p in files}:
        (root / path).parent.mkdir(parents=True, exist_ok=True)
        (root / path).write_text("")
    # Reading the Makefile writes build/materials.list, and with a goal that validates, build/budget.args.
    _make(root, "-n", "atlas", "validate")
    for path in root.rglob("*"):
        if path.is_file():
            os.utime(path, (T0, T0))
    built = [root / "build" / f for f in ("materials.list", "scenes.list", "separable.list", "budget.args")]
    built += [root / ".venv" / ".stamp"]
    for path in [*_outputs(root / "build"), *built]:
        os.utime(path, (T_BUILT, T_BUILT))
    return root


def _make(root: Path, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "MAKEFLAGS": "", "MAKELEVEL": ""}
    return subprocess.run(["make", "--no-print-directory", *args], cwd=root, env=env, capture_output=True, text=True,
                          timeout=60)  # fmt: skip


def _commands(root: Path, *goals: str) -> list[str]:
    """The atlasgen commands ``make -n`` would run for ``goals``."""
    result = _make(root, "-n", *goals)
    assert result.returncode == 0, result.stderr
    return [line for line in result.stdout.splitlines() if "/atlasgen " in line]


def _touch(path: Path) -> None:
    os.utime(path, (T_BUILT + 100, T_BUILT + 100))


def _validated(commands) -> list[str]:
    """Material files validated (not merged) by ``commands``."""
    return [re.search(r"validate (\S+)", c).group(1) for c in commands if " validate " in c and "--merge" not in c]


def _studied(commands) -> list[str]:
    return [re.search(r"report separable (\S+)", c).group(1) for c in commands
            if " report separable " in c and "--merge" not in c]  # fmt: skip


def test_nothing_changed_runs_nothing(tree):
    assert _commands(tree, "atlas", "render", "validate", "report") == []
    assert _make(tree, "-q", "render", "validate", "report").returncode == 0


def test_switching_between_the_demo_budget_and_convergence_redoes_the_validation_and_reports(tree):
    """make demo validates at a budget (DEMO_VALIDATE_ARGS), make validate converges: the reports
    of one are never taken as the other's."""
    demo = ["VALIDATE_ARGS=--max-physical-spp 64", "REPORT_ARGS=--no-physical", "STUDY_ARGS=--repeats 1"]
    commands = _commands(tree, "validate", "report", *demo)
    assert sorted(_validated(commands)) == [f"materials/{m}.toml" for m in sorted(MATERIALS)]
    assert all(c.endswith("--max-physical-spp 64") for c in commands if " validate materials/" in c)
    assert sorted(_studied(commands)) == [f"materials/{m}.toml" for m in sorted(SEPARABLE)]
    assert any(" report library " in c and c.endswith("--no-physical") for c in commands)
    # `make -n` wrote the demo's budget while reading the Makefile: the converged one is now stale.
    assert sorted(_validated(_commands(tree, "validate"))) == [f"materials/{m}.toml" for m in sorted(MATERIALS)]
    assert (tree / "build" / "budget.args").read_text().startswith("validate ; report library ;")


def test_a_changed_material_revalidates_only_itself(tree):
    _touch(tree / "materials" / "snow.toml")
    commands = _commands(tree, "validate", "report")
    assert _validated(commands) == ["materials/snow.toml"]
    assert _studied(commands) == []  # snow is not separable
    bakes = [c for c in commands if "--cache-only" in c]
    assert len(bakes) == 1 and "materials/snow.toml" in bakes[0]
    # The atlas is re-assembled (before validation: it is an order-only prerequisite), the
    # combined validation page is merged again, and the library page re-assembled.
    assert sum(" -o build/atlas.dds" in c for c in commands) == 1
    assert commands.index(next(c for c in commands if " -o build/atlas.dds" in c)) < commands.index(
        next(c for c in commands if "validate materials/snow.toml" in c)
    )
    assert sum("validate --merge" in c for c in commands) == 1
    assert sum("report library" in c for c in commands) == 1
    assert not any("report separable --merge" in c for c in commands)


def test_a_rebaked_separable_material_is_validated_and_studied_alone(tree):
    # The cache entry is rewritten (or touched) exactly when make re-bakes the material.
    _touch(tree / "build" / "cache" / "separable-gold.npz")
    commands = _commands(tree, "validate", "report")
    assert _validated(commands) == ["materials/separable-gold.toml"]
    assert _studied(commands) == ["materials/separable-gold.toml"]
    assert not any("--cache-only" in c for c in commands)
    assert sum("report separable --merge" in c for c in commands) == 1


def test_another_materials_atlas_change_does_not_revalidate(tree):
    # A newer atlas alone (what another material's bake leaves) does not make a report stale.
    _touch(tree / "build" / "atlas.dds")
    commands = _commands(tree, "validate", "report")
    assert _validated(commands) == [] and _studied(commands) == []
    assert [c.split()[1:3] for c in commands] == [["report", "library"]]


def test_validation_code_revalidates_every_material_and_nothing_else(tree):
    _touch(tree / "atlasgen" / "validate" / "metrics.py")
    commands = _commands(tree, "validate", "report")
    assert sorted(_validated(commands)) == sorted(f"materials/{m}.toml" for m in MATERIALS)
    assert _studied(commands) == [] and not any("bake" in c for c in commands)


def test_a_removed_material_re_merges_without_revalidating(tree):
    (tree / "materials" / "clay.toml").unlink()
    commands = _commands(tree, "validate", "report")
    assert _validated(commands) == []
    merge = next(c for c in commands if "validate --merge" in c)
    assert "materials/clay" not in merge and "build/validation/materials/snow" in merge


def test_strict_checks_the_merged_goals_on_every_run(tree):
    # Up to date: without STRICT nothing runs; with it the check runs all the same, so a
    # second `make validate STRICT=1` fails again rather than passing on a stale merge.
    assert _commands(tree, "validate") == []
    [check] = _commands(tree, "validate", "STRICT=1")
    assert check.split()[1:3] == ["validate", "--merge"] and check.endswith(" -o build/validation -q --strict")
    assert all(f"build/validation/materials/{m}" in check for m in MATERIALS)


FAKE_ATLASGEN = """#!/bin/sh
# Stands in for atlasgen: only touches what the real command writes for its -o.
out=""; prev=""
for a in "$@"; do [ "$prev" = "-o" ] && out="$a"; prev="$a"; done
case "$out" in
  "") ;;
  *.dds) touch "$out" ;;
  *) mkdir -p "$out" && touch "$out/report.json" "$out/index.md" "$out/index.html" ;;
esac
"""


def test_a_removed_materials_folders_are_pruned_by_the_merges(tree):
    # Every recipe runs, with a stand-in for atlasgen: what is left is what the Makefile
    # itself does to the build folder.
    fake = tree / "fake-atlasgen"
    fake.write_text(FAKE_ATLASGEN)
    fake.chmod(0o755)
    (tree / "materials" / "separable-gold.toml").unlink()
    stray = tree / "build" / "validation" / "materials" / "separable-gold"
    result = _make(tree, f"ATLASGEN={fake}", "validate", "report")
    assert result.returncode == 0, result.stderr
    assert not stray.exists()
    # It was the only separable material: its study, and the merged report, go too.
    assert not (tree / "build" / "report" / "separable").exists()
    assert (tree / "build" / "validation" / "materials" / "snow" / "report.json").is_file()
    assert "removing build/validation/materials/separable-gold/" in result.stdout


def test_a_document_beside_a_toml_file_of_its_name_is_validated_apart_and_pruned(tree):
    """materials/snow.mtlx beside snow.toml: both went to build/validation/materials/snow/, one target with two
    recipes (make warned, kept the document's, never validated the TOML file, and the merge got the folder twice).
    Each has its own folder now, and a removed document's folder is pruned as a removed TOML file's is."""
    fake = tree / "fake-atlasgen"
    fake.write_text(FAKE_ATLASGEN)
    fake.chmod(0o755)
    (tree / "materials" / "snow.mtlx").write_text("")
    (tree / "build" / "validation" / "materials" / "snow" / "report.json").unlink()  # so that make -n shows both jobs
    result = _make(tree, "-n", "validate")
    assert result.returncode == 0 and "overriding recipe" not in result.stderr, result.stderr
    validations = {re.search(r"validate (\S+)", c).group(1): re.search(r" -o (\S+)", c).group(1)
                   for c in result.stdout.splitlines() if " validate materials/snow." in c}  # fmt: skip
    assert validations == {"materials/snow.toml": "build/validation/materials/snow",
                           "materials/snow.mtlx": "build/validation/documents/snow"}  # fmt: skip
    result = _make(tree, f"ATLASGEN={fake}", "validate")
    assert result.returncode == 0, result.stderr
    merge = next(line for line in result.stdout.splitlines() if "validate --merge" in line)
    assert merge.count("build/validation/materials/snow ") == 1 and "build/validation/documents/snow " in merge
    (tree / "materials" / "snow.mtlx").unlink()
    result = _make(tree, f"ATLASGEN={fake}", "validate")
    assert result.returncode == 0, result.stderr
    assert "removing build/validation/documents/snow/ (no materials/snow.mtlx)" in result.stdout
    assert not (tree / "build" / "validation" / "documents" / "snow").exists()
    assert (tree / "build" / "validation" / "materials" / "snow" / "report.json").is_file()


def test_no_two_jobs_write_the_same_place(tree):
    shutil.rmtree(tree / "build")
    commands = _commands(tree, "validate", "report")
    outputs = []
    for c in commands:
        if "--cache-only" in c:
            outputs.append("cache/" + re.search(r"materials/(\S+)\.toml", c).group(1))
        else:
            outputs.append(re.search(r" -o (\S+)", c).group(1))
    assert len(outputs) == len(set(outputs)), outputs
    assert len(_validated(commands)) == len(MATERIALS) and len(_studied(commands)) == len(SEPARABLE)
    # Every per-material folder is its own; the merges write beside them, never into them.
    per_material = [o for o in outputs if "/materials/" in o]
    assert len(per_material) == len(MATERIALS) + len(SEPARABLE)


def _scene_jobs(commands) -> list[tuple[str, str]]:
    """(verb, scene) of each scene-atlas bake and scene render in ``commands``."""
    jobs = []
    for c in commands:
        bake = re.search(r"--scene scenes/(\S+)\.toml", c)
        render = re.search(r" render scenes/(\S+)\.toml", c)
        if bake:
            jobs.append(("bake", bake.group(1)))
        elif render:
            jobs.append(("render", render.group(1)))
    return jobs


def test_a_material_rebakes_and_rerenders_only_the_scenes_that_use_it(tree):
    _touch(tree / "build" / "cache" / "snow.npz")
    assert _scene_jobs(_commands(tree, "render")) == [("bake", "two"), ("render", "two")]
    _touch(tree / "build" / "cache" / "clay.npz")
    assert sorted(_scene_jobs(_commands(tree, "render"))) == [
        ("bake", "one"),
        ("bake", "two"),
        ("render", "one"),
        ("render", "two"),
    ]


def test_a_changed_scene_rebakes_and_rerenders_only_itself(tree):
    _touch(tree / "scenes" / "one.toml")
    commands = _commands(tree, "render")
    assert _scene_jobs(commands) == [("bake", "one"), ("render", "one")]
    bake = next(c for c in commands if "--scene" in c)
    # Library IDs, the shared cache, and a fresh dependency file.
    assert "--ids-from build/atlas.json" in bake and "--cache build/cache" in bake
    assert "--depfile build/scenes/one.d" in bake and " -o build/scenes/one.dds" in bake


_FAKE_ATLASGEN = """#!{python}
# Stands in for atlasgen in a real (not dry) make run: logs each call and touches what it would write.
import sys, pathlib
args = sys.argv[1:]
with open({log!r}, "a") as log:
    log.write(" ".join(args) + "\\n")
if "--cache-only" in args:  # a material's cache entry
    cache = pathlib.Path(args[args.index("--cache") + 1])
    cache.mkdir(parents=True, exist_ok=True)
    (cache / (pathlib.Path(args[1]).stem + ".npz")).write_text("")
    raise SystemExit(0)
out = pathlib.Path(args[args.index("-o") + 1])
out.parent.mkdir(parents=True, exist_ok=True)
if args[0] == "bake":
    for suffix in {suffixes!r}:
        out.with_suffix("." + suffix).write_text("")
    if "--depfile" in args:
        pathlib.Path(args[args.index("--depfile") + 1]).write_text(out.as_posix() + ":\\n")
else:
    out.write_text("")  # the EXR, and its PNG beside it
    out.with_suffix(".png").write_text("")
    if "--depfile" in args:
        pathlib.Path(args[args.index("--depfile") + 1]).write_text(out.with_suffix(".png").as_posix() + ":\\n")
"""


def _make_with_fake_atlasgen(root: Path, *goals: str) -> list[str]:
    """Run make for real with a stand-in atlasgen (:data:`_FAKE_ATLASGEN`); the calls it received."""
    import sys

    fake, log = root / "fake-atlasgen", root / "calls.log"
    fake.write_text(_FAKE_ATLASGEN.format(python=sys.executable, log=str(log), suffixes=SCENE_SET))
    fake.chmod(0o755)
    log.write_text("")
    result = _make(root, *goals, f"ATLASGEN={fake}")
    assert result.returncode == 0, result.stderr
    return log.read_text().splitlines()


@pytest.mark.parametrize("suffix", SCENE_SET[1:])
def test_a_deleted_file_of_a_scene_set_rebakes_that_set_once(tree, suffix):
    """A scene's bake writes one set: any of its files deleted re-bakes it (one bake for the whole set) and
    re-renders the scene, in one run; where only X.dds was a target, a deleted X.json made the render fail."""
    (tree / "build" / "scenes" / f"one.{suffix}").unlink()
    assert _make(tree, "-q", "render").returncode == 1
    calls = _make_with_fake_atlasgen(tree, "render")
    assert [c.split()[0] for c in calls] == ["bake", "render"] and "--scene scenes/one.toml" in calls[0], calls
    assert "scenes/one.toml" in calls[1]
    assert _make(tree, "-q", "render").returncode == 0


def test_a_scene_atlas_whose_depfile_is_gone_is_baked_again(tree):
    """Without build/scenes/X.d make does not know the scene's materials, so a change to one of them would
    leave X.dds stale: it is baked again (which writes the depfile), and only that scene."""
    (tree / "build" / "scenes" / "two.d").unlink()
    assert _commands(tree, "atlas") == []  # no other goal bakes a scene to remake a depfile
    assert _make(tree, "-q", "render").returncode == 1
    calls = _make_with_fake_atlasgen(tree, "render")
    assert [c.split()[0] for c in calls] == ["bake", "render"] and "--scene scenes/two.toml" in calls[0], calls
    assert (tree / "build" / "scenes" / "two.d").exists()
    assert _make(tree, "-q", "render").returncode == 0


def test_the_makefile_bake_code_is_what_the_cache_key_hashes(tree):
    from atlasgen.bake.cache import bake_relevant_files

    result = _make(tree, "--eval", "print-bake-code: ; @echo $(BAKE_CODE)", "print-bake-code")
    assert result.returncode == 0, result.stderr
    assert set(result.stdout.split()) == {f.relative_to(ROOT).as_posix() for f in bake_relevant_files()}


def test_shader_code_rebakes_every_material(tree):
    # The shader package is a layer below bake/: its code is in every cache key (BAKE_RELEVANT),
    # so make re-bakes every material when it changes, as the key would.
    _touch(tree / "atlasgen" / "shaders" / "include.py")
    bakes = [re.search(r"bake (\S+) --cache", c).group(1) for c in _commands(tree, "atlas") if "--cache-only" in c]
    assert sorted(bakes) == [f"materials/{m}.toml" for m in sorted(MATERIALS)]


def test_a_renderer_shader_file_rerenders_without_rebaking(tree):
    # The .wgsl files are the renderer's (RENDER_CODE): no material's slices depend on them.
    _touch(tree / "atlasgen" / "shaders" / "lighting.wgsl")
    commands = _commands(tree, "atlas", "render")
    assert sorted(_scene_jobs(commands)) == [("render", "one"), ("render", "two")]
    assert not any(" bake " in c for c in commands)


def test_a_file_a_materialx_document_includes_rebakes_the_document(tree):
    """The document's stamp depends on what its bake's depfile lists: a change to an included file re-bakes the
    document (and so re-validates it), one to a file it does not include nothing."""
    (tree / "materials" / "shared").mkdir()
    for name in ("doc.mtlx", "shared/base.mtlx", "shared/unused.mtlx"):
        (tree / "materials" / name).write_text("")
    stamp = tree / "build" / "cache" / "doc.mtlx.stamp"
    report = tree / "build" / "validation" / "documents" / "doc" / "report.json"
    report.parent.mkdir(parents=True)
    for path in (stamp, report):
        path.write_text("")
    write_depfile(stamp.with_suffix(".d"), "build/cache/doc.mtlx.stamp", ["materials/doc.mtlx", "materials/shared/base.mtlx"])
    _make(tree, "-n", "atlas")  # reads the Makefile: the material list now names the document
    hashed = tree / "build" / "hashes" / "materials" / "doc.mtlx.sha256"  # written as the Makefile was read
    for path in [tree / "materials" / "doc.mtlx", hashed, *(tree / "materials" / "shared").iterdir()]:
        os.utime(path, (T0, T0))
    for path in (stamp, stamp.with_suffix(".d"), report, tree / "build" / "materials.list", tree / "build" / "atlas.dds"):
        os.utime(path, (T_BUILT, T_BUILT))
    assert _commands(tree, "atlas", "validate") == []
    _touch(tree / "materials" / "shared" / "unused.mtlx")
    assert _commands(tree, "atlas", "validate") == []
    _touch(tree / "materials" / "shared" / "base.mtlx")
    commands = _commands(tree, "atlas", "validate")
    bake = next(c for c in commands if "--cache-only" in c)
    assert (
        "bake materials/doc.mtlx " in bake
        and "--depfile build/cache/doc.mtlx.d --depfile-target build/cache/doc.mtlx.stamp" in bake
    )
    assert _validated(commands) == ["materials/doc.mtlx"]


def test_a_material_whose_content_changed_rebakes_whatever_its_time_stamp(tree):
    """Two files swapped by renaming keep every name and time stamp, as does an older file copied in with
    its time (cp -p): make saw nothing to do, and the atlas kept the old materials."""
    clay, snow = tree / "materials" / "clay.toml", tree / "materials" / "snow.toml"
    clay.write_text('type = "lambert"\ncolour = [0.9, 0.2, 0.1]\n')
    os.utime(clay, (T0, T0))  # older than its cache entry, as a swapped file is
    commands = _commands(tree, "atlas", "validate")
    assert [c for c in commands if "--cache-only" in c] == [
        ".venv/bin/atlasgen bake materials/clay.toml --cache build/cache --cache-only --depfile build/cache/clay.d "
        "--depfile-target build/cache/clay.npz -q"
    ] and _validated(commands) == ["materials/clay.toml"], commands
    assert snow.read_text() == 'type = "lambert"\n'


def test_a_scene_whose_content_changed_rebakes_and_re_renders_whatever_its_time_stamp(tree):
    """As a material file: a scene swapped in by renaming, or copied with its time, left the image as it was."""
    scene = tree / "scenes" / "two.toml"
    scene.write_text("[camera]\nposition = [0, 0, 4]\ntarget = [0, 0, 0]\n")
    os.utime(scene, (T0, T0))  # older than its atlas and image
    assert _scene_jobs(_commands(tree, "render")) == [("bake", "two"), ("render", "two")]


def test_outputs_atlasgen_commits_are_kept_when_make_is_interrupted(tree):
    """A run interrupted just after its commit exits 130 with the new set in place; make deleted build/atlas.dds."""
    database = _make(tree, "-p", "-q", "atlas").stdout
    precious = next(line for line in database.splitlines() if line.startswith(".PRECIOUS:")).split()[1:]
    for target in (
        "build/atlas.dds",
        "build/cache/%.npz",
        "build/scenes/one.dds",
        "build/scenes/one.png",
        "build/validation/report.json",
        "build/validation/materials/clay/report.json",
        "build/report/index.html",
    ):
        assert target in precious, (target, precious)


def test_the_bake_command_s_defaults_re_assemble_the_atlas(tree):
    """cli/main.py holds bake's defaults (the include languages, the layout); a change to it did nothing, and then
    re-assembled the library's atlas but not the scenes' (a volume library beside array scene atlases)."""
    (tree / "cli").mkdir()
    (tree / "cli" / "main.py").write_text("")
    os.utime(tree / "cli" / "main.py", (T0, T0))
    assert _commands(tree, "atlas", "render") == []
    _touch(tree / "cli" / "main.py")
    commands = _commands(tree, "atlas")
    assert len(commands) == 1 and " -o build/atlas.dds " in commands[0] and "--cache-only" not in commands[0], commands
    scene_bakes = [c for c in _commands(tree, "render") if " bake " in c and "--scene" in c]
    assert sorted(c.split("--scene ")[1].split()[0] for c in scene_bakes) == ["scenes/one.toml", "scenes/two.toml"]


def test_the_render_command_s_code_re_renders_the_scenes_alone(tree):
    """cli/render_cmd.py (the render's options and defaults) was no prerequisite of the images."""
    (tree / "cli").mkdir()
    (tree / "cli" / "render_cmd.py").write_text("")
    os.utime(tree / "cli" / "render_cmd.py", (T0, T0))
    assert _commands(tree, "render") == []
    _touch(tree / "cli" / "render_cmd.py")
    commands = _commands(tree, "atlas", "render")
    assert len(commands) == 2 and all(" render scenes/" in c for c in commands), commands


def test_a_deleted_exr_renders_its_scene_again(tree):
    """A render writes the EXR and its PNG as one set, but only the PNG was a target: without the EXR,
    make -q said the scene was up to date."""
    (tree / "build" / "scenes" / "one.exr").unlink()
    assert _make(tree, "-q", "render").returncode == 1
    calls = _make_with_fake_atlasgen(tree, "render")
    assert calls == [c for c in calls if c.startswith("render scenes/one.toml")] and len(calls) == 1, calls
    assert _make(tree, "-q", "render").returncode == 0


def test_make_clean_atlas_keeps_the_content_hashes_it_makes(tree):
    """With clean among the goals nothing writes build/hashes while the Makefile is read, so the hash rule makes
    them, and make deleted them as intermediates at the end: the next make wrote them anew, newer than every cache
    entry, and re-baked every material."""
    _make_with_fake_atlasgen(tree, "clean", "atlas")
    hashes = sorted(p.relative_to(tree).as_posix() for p in (tree / "build" / "hashes").rglob("*.sha256"))
    assert hashes == [f"build/hashes/materials/{m}.toml.sha256" for m in sorted(MATERIALS)]


def test_a_materialx_document_whose_depfile_is_gone_is_baked_again(tree):
    """Without build/cache/X.mtlx.d make does not know the files the document includes, so a change to one of
    them would leave its cache entries stale: it is baked again, which writes the depfile."""
    (tree / "materials" / "doc.mtlx").write_text("")
    stamp = tree / "build" / "cache" / "doc.mtlx.stamp"
    stamp.write_text("")
    _make(tree, "-n", "atlas")  # reads the Makefile: the material list now names the document
    os.utime(tree / "materials" / "doc.mtlx", (T0, T0))
    os.utime(tree / "build" / "hashes" / "materials" / "doc.mtlx.sha256", (T0, T0))
    for path in (stamp, tree / "build" / "materials.list", tree / "build" / "atlas.dds"):
        os.utime(path, (T_BUILT, T_BUILT))
    bakes = [c for c in _commands(tree, "atlas") if "--cache-only" in c]
    assert len(bakes) == 1 and "bake materials/doc.mtlx " in bakes[0] and "--depfile build/cache/doc.mtlx.d" in bakes[0]
    write_depfile(stamp.with_suffix(".d"), "build/cache/doc.mtlx.stamp", ["materials/doc.mtlx"])
    os.utime(stamp.with_suffix(".d"), (T_BUILT, T_BUILT))
    assert not [c for c in _commands(tree, "atlas") if "--cache-only" in c]


@pytest.mark.parametrize("name", ["atlas.json", "atlas.wgsl", "atlas-preview.png"])
def test_a_deleted_file_of_the_atlas_s_set_re_assembles_it(tree, name):
    """Only atlas.dds was a target: with build/atlas.json deleted, make saw nothing to do."""
    (tree / "build" / name).unlink()
    commands = _commands(tree, "atlas")
    assert len(commands) == 1 and " -o build/atlas.dds --preview build/atlas-preview.png" in commands[0], commands


def test_an_image_or_mesh_a_scene_reads_re_renders_that_scene_alone(tree):
    """The render rule listed scenes/meshes/* (every scene re-rendered for any mesh) and no environment image (a
    new sky left the image stale, make -q 0). The render's depfile names what each scene reads, wherever it is."""
    for path in RENDER_READS["one"]:
        _touch(tree / path)
        assert _scene_jobs(_commands(tree, "render")) == [("render", "one")]
        assert _make(tree, "-q", "render").returncode == 1
        os.utime(tree / path, (T0, T0))
    render = next(c for c in _commands(tree, "render", "-B") if " render scenes/one.toml" in c)
    assert "--depfile build/scenes/one.png.d" in render and " -o build/scenes/one.exr" in render


def test_a_render_whose_depfile_is_gone_is_rendered_again(tree):
    """Without build/scenes/X.png.d make does not know the files the render read: it renders again (which writes
    the depfile), and only that scene, without re-baking its atlas."""
    (tree / "build" / "scenes" / "one.png.d").unlink()
    assert _make(tree, "-q", "render").returncode == 1
    calls = _make_with_fake_atlasgen(tree, "render")
    assert [c.split()[:2] for c in calls] == [["render", "scenes/one.toml"]], calls
    assert (tree / "build" / "scenes" / "one.png.d").exists()
    assert _make(tree, "-q", "render").returncode == 0


def test_make_render_removes_the_sets_of_scenes_that_are_gone_and_nothing_else(tree):
    """A deleted (or renamed) scene left build/scenes/X.* behind, read as current by whoever lists the folder. Once
    the scenes change, the links into a store that no current scene's output is named go, and then the stores no
    current scene writes to; a scene's own set, a file of the user's and its own links stay, and make -q still finds
    render up to date. A store is named by the set's name up to its first dot: scenes one and one.extra share one."""
    scenes = tree / "build" / "scenes"

    def link(name: str, store: str) -> Path:
        (scenes / store / "current").mkdir(parents=True, exist_ok=True)
        (scenes / store / "current" / name).write_text("" if name.endswith(".d") else name)  # make includes X.d
        (scenes / name).unlink(missing_ok=True)  # the fixture's plain file: atlasgen's outputs are links
        (scenes / name).symlink_to(f"{store}/current/{name}")
        os.utime(scenes / name, (T_BUILT, T_BUILT))  # as new as the outputs the fixture made: the tree is up to date
        return scenes / name

    kept = [link("one.separable.bin", ".one.atlasgen")]
    gone = [link("one.extra.dds", ".one.atlasgen"), link("one.extra.png", ".one.atlasgen")]
    gone += [link(f"{stem}.{suffix}", f".{stem.split('.')[0]}.atlasgen") for stem in ("two", "gone", "old.name")
             for suffix in ("dds", "json", "png", "d")]  # fmt: skip
    (scenes / "notes.txt").write_text("mine")
    (scenes / "mine.txt").symlink_to("notes.txt")
    assert _make(tree, "-q", "render").returncode == 0  # the scenes have not changed since the last prune
    (tree / "scenes" / "two.toml").unlink()  # build/scenes.list changes as the Makefile is read
    assert _make(tree, "-q", "render").returncode == 1
    assert _make_with_fake_atlasgen(tree, "render") == []
    assert _make(tree, "-q", "render").returncode == 0
    assert not any(p.is_symlink() for p in gone), [p.name for p in gone if p.is_symlink()]
    assert not any((scenes / f".{store}.atlasgen").exists() for store in ("two", "gone", "old"))
    assert all(p.read_text() == p.name for p in kept) and (scenes / ".one.atlasgen").is_dir()
    assert (scenes / "mine.txt").read_text() == "mine" and (scenes / "one.dds").exists()


def test_a_renamed_material_re_bakes_the_scenes_that_named_it_not_the_missing_file(tree):
    """A scene's depfile still names the old material file and its cache entry: the cache's pattern rule took the entry
    for one to remake from the file the depfile made a target (gcc -MP), and every make failed with "materials/clay.toml:
    no such file" until the depfiles were deleted by hand. Only the library's materials have that rule now."""
    (tree / "materials" / "clay.toml").rename(tree / "materials" / "loam.toml")
    commands = _commands(tree, "render")
    assert not [c for c in commands if "bake materials/clay.toml" in c], commands
    assert [c for c in commands if "bake materials/loam.toml" in c and "--cache-only" in c]
    assert [c for c in commands if "--scene scenes/one.toml" in c] and [c for c in commands if "render scenes/one.toml" in c]


def test_a_material_no_longer_separable_re_merges_the_separable_report(tree):
    """separable-gold made lambert kept its study in the merged separable report: the merge re-ran only when the
    material list or a remaining study changed. It now also follows the list of separable materials."""
    build = tree / "build"
    (tree / "materials" / "sep2.toml").write_text("type = 'separable'\n")
    os.utime(tree / "materials" / "sep2.toml", (T0, T0))
    made = [build / "cache" / "sep2.npz", build / "validation" / "materials" / "sep2" / "report.json",
            build / "report" / "separable" / "materials" / "sep2" / "report.json"]  # fmt: skip
    for path in made:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("")
    write_depfile(build / "cache" / "sep2.d", "build/cache/sep2.npz", ["materials/sep2.toml"])
    made.append(build / "cache" / "sep2.d")
    _make(tree, "-n", "atlas", "validate", "report")  # writes the lists for the library of four
    for path in [*made, build / "materials.list", build / "separable.list"]:
        os.utime(path, (T_BUILT, T_BUILT))
    for path in (build / "hashes" / "materials" / "sep2.toml.sha256",):
        os.utime(path, (T0, T0))
    assert not [c for c in _commands(tree, "report") if "report separable" in c]
    (tree / "materials" / "separable-gold.toml").write_text('type = "lambert"\n')
    merges = [c for c in _commands(tree, "report") if "report separable --merge" in c]
    assert merges == [merges[0]] and "separable-gold" not in merges[0] and "sep2" in merges[0], merges


@pytest.mark.parametrize("name", ["materials/wet clay.toml", "scenes/toon stage.toml", "materials/a:b.toml",
                                  "materials/50%.toml", "materials/it's.toml", 'materials/dq"x.toml', "materials/cost$5.toml",
                                  "materials/h#x.toml", "materials/w[1].toml", "materials/a>b.toml", "materials/a&b.toml",
                                  "materials/a(b).toml", "materials/a`b.toml", "materials/a|b.toml", "materials/a{b,c}.toml",
                                  "materials/a\tb.toml"])  # fmt: skip
def test_a_file_name_make_cannot_name_is_refused_on_one_line(tree, name):
    """make splits names on spaces: every make printed sha256sum errors, render failed with "No rule to make target"
    and a material with a space was left out of the atlas without a word. A colon or a percent sign broke the Makefile
    ("target pattern contains no '%'"), a quote the recipes (shell syntax errors), a dollar sign the name."""
    (tree / name).write_text('type = "lambert"\n')
    result = _make(tree, "-n", "atlas", "render")
    assert result.returncode == 2 and result.stdout == "", result.stdout
    shown = name.replace("\t", "?")
    assert result.stderr.splitlines() == [f"Makefile:{_line_of(tree, '$(error $(UNNAMEABLE_FILES)')}: *** {shown}: a file name "
                                          "with a space, a control character or one of : % ' \" $ # ; \\ * ? [ < > | & ( ) "
                                          "` { }, which make cannot name; expected names without them (rename it; atlasgen "
                                          "itself reads it as it is).  Stop."]  # fmt: skip
    assert not (tree / "build" / "hashes" / f"{name.split(' ')[0]}.sha256").exists()  # the junk hash it wrote
    assert not (tree / "b.toml").exists()  # "a>b.toml" emptied (or made) a file b.toml


@pytest.mark.parametrize("kind", ["folder", "dangling link"])
def test_a_folder_or_dangling_link_named_as_a_material_is_refused_on_one_line(tree, kind):
    """A hostile sweep's: materials/glaze.toml/ made make end 0 with grep's and sha256sum's "Is a directory", baked the
    folder's own files without a word, and never settled; a dangling link printed their lines before atlasgen's."""
    path = tree / "materials" / "odd.toml"
    if kind == "folder":
        path.mkdir()
        (path / "inner.toml").write_text('type = "lambert"\n')
    else:
        path.symlink_to("nowhere.toml")
    result = _make(tree, "-n", "atlas", "render")
    assert result.returncode == 2 and result.stdout == "", result.stdout
    assert result.stderr.splitlines() == [f"Makefile:{_line_of(tree, '$(error $(NOT_FILES)')}: *** materials/odd.toml: a "
                                          "folder, a dangling link or another file that is no regular file, named as a "
                                          "material or scene file; expected a file (rename or remove it).  Stop."]  # fmt: skip
    path.unlink() if kind != "folder" else None
    (tree / "materials" / "odd.toml").unlink(missing_ok=True) if kind != "folder" else None


def _line_of(tree: Path, text: str) -> int:
    return next(i for i, line in enumerate((tree / "Makefile").read_text().splitlines(), 1) if text in line)


def test_a_file_a_material_names_re_bakes_that_material_alone(tree):
    """A measured BSDF's data (or a bitmap) changed: make saw nothing to do, and the atlas kept the old one. The
    cache entry's bake records the files the material names (--depfile), and make re-bakes it, and only it."""
    data = tree / "materials" / "data" / "clay.bsdf"
    data.parent.mkdir()
    data.write_text("data")
    write_depfile(
        tree / "build" / "cache" / "clay.d", "build/cache/clay.npz", ["materials/clay.toml", "materials/data/clay.bsdf"]
    )
    for path in (data, tree / "build" / "cache" / "clay.d"):
        os.utime(path, (T0, T0))
    assert _commands(tree, "atlas") == []
    _touch(data)
    assert [c for c in _commands(tree, "atlas") if "--cache-only" in c] == [
        ".venv/bin/atlasgen bake materials/clay.toml --cache build/cache --cache-only --depfile build/cache/clay.d "
        "--depfile-target build/cache/clay.npz -q"
    ]


def test_a_cache_entry_whose_depfile_is_gone_is_baked_again(tree):
    """Without build/cache/X.d make does not know the files the material names: it is baked again, which writes it."""
    (tree / "build" / "cache" / "snow.d").unlink()
    baked = [c for c in _commands(tree, "atlas") if "--cache-only" in c]
    assert len(baked) == 1 and "bake materials/snow.toml" in baked[0], baked


def test_a_deleted_library_manifest_re_bakes_every_scene_atlas_with_the_new_ids(tree):
    """The library's manifest keeps its IDs; deleted, the library is numbered afresh. The scene atlases, which wait
    for it only as order, kept their old IDs and ``make -q`` said 0: a material had two IDs in two atlases."""
    (tree / "build" / "atlas.json").unlink()
    assert _make(tree, "-q", "render").returncode == 1
    calls = _make_with_fake_atlasgen(tree, "render")
    bakes = [c for c in calls if c.startswith("bake")]
    assert "-o build/atlas.dds" in bakes[0], calls
    assert sorted(re.search(r"--scene (\S+)", c).group(1) for c in bakes[1:]) == [f"scenes/{s}.toml" for s in sorted(SCENES)]
    assert all("--ids-from build/atlas.json" in c for c in bakes[1:]), calls
    assert sorted(c.split()[1] for c in calls if c.startswith("render")) == [f"scenes/{s}.toml" for s in sorted(SCENES)]
    assert _make(tree, "-q", "render").returncode == 0


@pytest.mark.parametrize("atlas", ["atlas", "scenes/two"])
def test_a_deleted_side_car_of_a_separable_atlas_is_written_again(tree, atlas):
    """X.separable.bin is written only beside a manifest that names a separable material, so no rule names it:
    deleted, it was never written again and ``make -q`` said 0. Its set is baked again, and only its set."""
    manifest = tree / "build" / f"{atlas}.json"
    # The Makefile greps a manifest for the writer's own spelling: a golden manifest (format_manifest's bytes) has it.
    pattern = re.search(r"grep -l '([^']+)'", (ROOT / "Makefile").read_text()).group(1)
    assert pattern in (ROOT / "tests" / "resources" / "golden" / "array-srgb.json").read_text()
    manifest.write_text(f'{{"materials": [{{"name": "separable-gold", {pattern}}}]}}\n')
    sidecar = manifest.with_suffix(".separable.bin")
    sidecar.write_bytes(b"ASEP")
    for path in (manifest, sidecar):
        os.utime(path, (T_BUILT, T_BUILT))
    assert _make(tree, "-q", "atlas", "render").returncode == 0
    sidecar.unlink()
    assert _make(tree, "-q", "atlas", "render").returncode == 1
    bakes = [c for c in _make_with_fake_atlasgen(tree, "atlas", "render") if c.startswith("bake")]
    assert len(bakes) == 1 and f"-o build/{atlas}.dds" in bakes[0], bakes
    manifest.write_text('{"materials": [{"name": "clay", "type": "lambert"}]}\n')  # no separable material: no side-car
    os.utime(manifest, (T_BUILT, T_BUILT))  # the content alone changed, not what make compares
    assert _make(tree, "-q", "atlas", "render").returncode == 0
