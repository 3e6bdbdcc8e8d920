"""Issue 24, the fault families: every command's outputs change as one set.

Each command (``bake`` to DDS and to Zstandard KTX2, ``render``, ``validate --merge``,
``report separable --merge``, ``report library``) is driven through every rename of its commit
with ``strace`` fault injection (the real ``rename`` system call, in the real command line):

- **killed** there (``SIGKILL``, the rename not done): every file is whole, old or new, the
  primary (the file ``make`` targets) is still the old one, and once an atlasgen reader has
  looked at the folder the set is exactly the new generation, with nothing left beside it;
- **failing** there (``EIO``): exit 4 with one line, and every file is the old one;

and with each of its outputs in turn immutable (``chattr +i``, as root; skipped otherwise):
exit 4 with one line before any rename, every file the old one. Two bakes of one target run
at once end as one bake's generation.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from atlasgen.io.atlas import read_atlas
from atlasgen.io.atomic import recover_commits

pytestmark = [pytest.mark.slow, pytest.mark.skipif(shutil.which("strace") is None, reason="strace is not installed")]

ENV = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "ATLASGEN_DEBUG": "0"}
RENAMES = "rename,renameat,renameat2"
CLAY = 'type = "lambert"\ncolour = {colour}\n'
SCENE = ('[camera]\nposition = [0, 0, 3]\ntarget = [0, 0, 0]\nfov = 30\n[image]\nwidth = 24\nheight = 16\n'
         '[[lights]]\ntype = "directional"\ndirection = [0, 0, -1]\nintensity = {intensity}\n'
         '[[objects]]\nshape = "sphere"\nmaterial = "clay"\n')  # fmt: skip


def atlasgen(args, inject: str | None = None, trace: Path | None = None) -> subprocess.CompletedProcess:
    """``python -m atlasgen ARGS``, under strace when injecting a fault or logging renames."""
    command = [sys.executable, "-m", "atlasgen", *map(str, args)]
    if inject is not None or trace is not None:
        strace = ["strace", "-f", "-qq", "-o", str(trace or os.devnull), "-e", f"trace={RENAMES}"]
        command = strace + (["-e", f"inject={RENAMES}:{inject}"] if inject else []) + command
    return subprocess.run(command, env=ENV, capture_output=True, text=True, timeout=600)


def snapshot(folder: Path) -> dict:
    """Every file under ``folder`` (hidden ones too): relative path -> bytes."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def restore(folder: Path, files: dict) -> None:
    shutil.rmtree(folder, ignore_errors=True)
    for name, data in files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(data)


def commit_renames(log: Path, folder: Path) -> list[tuple[int, str]]:
    """``(n, target)`` of each rename (n counts from 1, as strace's ``when=``) onto a file under ``folder``."""
    renames = []
    calls = [line for line in log.read_text().splitlines() if re.search(r"\brename(at2?)?\(", line)]
    for n, line in enumerate(calls, 1):
        target = re.findall(r'"([^"]*)"', line)[-1]
        if Path(target).is_relative_to(folder):
            renames.append((n, Path(target).relative_to(folder).as_posix()))
    return renames


def chattr(path: Path, flag: str) -> bool:
    if os.geteuid() != 0 or shutil.which("chattr") is None:
        return False
    return subprocess.run(["chattr", flag, str(path)], capture_output=True).returncode == 0


def one_line(result: subprocess.CompletedProcess) -> str:
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    return lines[0]


def drive(args, folder: Path, primary: str, set_old, set_new, reader=None, immutable: bool = True) -> dict:
    """Drive one command through every fault (``immutable``: also each output made immutable in
    turn); return what was seen, for the summary asserts."""
    set_new()
    assert atlasgen(args).returncode == 0
    new = snapshot(folder)
    assert atlasgen(args).returncode == 0
    varying = {name for name, data in snapshot(folder).items() if new.get(name) != data}  # timings: measured seconds
    set_old()
    done = atlasgen(args)
    assert done.returncode == 0, done.stderr
    old = snapshot(folder)
    assert old[primary] != new[primary]
    assert not [name for name in {**old, **new} if ".atlasgen." in name]
    set_new()
    log = folder.parent / f"{folder.name}.renames.log"
    assert atlasgen(args, trace=log).returncode == 0
    renames = commit_renames(log, folder)
    assert renames[-1][1] == primary and {name for _, name in renames} == set(new), renames
    restore(folder, old)

    def whole(now: dict) -> None:
        for name in set(old) | set(new):
            if name in varying:
                json.loads(now[name]) if name.endswith(".json") else None
            else:
                assert now.get(name) in (old.get(name), new.get(name)), name

    for n, target in renames:
        killed = atlasgen(args, inject=f"error=EIO:signal=SIGKILL:when={n}")
        assert killed.returncode in (137, -9), (target, killed.returncode, killed.stderr)
        plain = {name: data for name, data in snapshot(folder).items() if ".atlasgen." not in name}
        whole(plain)
        assert plain[primary] == old[primary], target  # stale: make runs the command again
        (reader or recover_commits)(folder)
        after = snapshot(folder)
        assert set(after) == set(new), (target, sorted(set(after) ^ set(new)))  # the journal, backups and lock gone
        assert {k: v for k, v in after.items() if k not in varying} == {k: v for k, v in new.items() if k not in varying}
        restore(folder, old)
        failed = atlasgen(args, inject=f"error=EIO:when={n}")
        assert failed.returncode == 4, (target, failed.stderr)
        assert one_line(failed).endswith("cannot replace (Input/output error); every output was left as it was")
        assert snapshot(folder) == old, target
    frozen = []
    for name in sorted(old) if immutable else ():
        if not chattr(folder / name, "+i"):
            break
        try:
            refused = atlasgen(args)
        finally:
            chattr(folder / name, "-i")
        assert refused.returncode == 4, (name, refused.stderr)
        assert one_line(refused).endswith(f"{name}: cannot replace (Operation not permitted); nothing was replaced")
        assert snapshot(folder) == old, name
        frozen.append(name)
    return {"renames": [name for _, name in renames], "immutable": frozen}


@pytest.fixture
def library(tmp_path):
    folder = tmp_path / "materials"
    folder.mkdir()
    (folder / "snow.toml").write_text('type = "lambert"\nid = 9\n')

    def colour(rgb: str):
        return lambda: (folder / "clay.toml").write_text(CLAY.format(colour=rgb))

    return folder, colour("[0.2, 0.3, 0.4]"), colour("[0.7, 0.5, 0.3]")


@pytest.mark.parametrize("container", ["dds", "ktx2-zstd"])
def test_a_bake_changes_as_one_set_through_every_fault(tmp_path, library, container):
    folder, set_old, set_new = library
    build = tmp_path / "build"
    atlas = build / ("atlas.dds" if container == "dds" else "atlas.ktx2")
    args = ["bake", folder, "-o", atlas, "--preview", build / "atlas-preview.png", "-q"]
    args += ["--zstd"] if container != "dds" else []
    # The immutable outputs once: the KTX2 bake's commit is the same code.
    seen = drive(args, build, atlas.name, set_old, set_new, reader=lambda _: read_atlas(atlas), immutable=container == "dds")
    assert seen["renames"] == ["atlas.json", "atlas.wgsl", "atlas.glsl", "atlas.hlsl", "atlas.timings.json",
                               "atlas-preview.png", atlas.name]  # fmt: skip
    assert seen["immutable"] in ([], sorted(seen["renames"]) if container == "dds" else [])


def test_a_render_changes_as_one_set_through_every_fault(tmp_path, library):
    folder, _, set_colour = library
    set_colour()
    atlas = tmp_path / "atlas.dds"
    assert atlasgen(["bake", folder, "-o", atlas, "-q"]).returncode == 0
    scene = tmp_path / "scene.toml"
    out = tmp_path / "render"
    args = ["render", scene, "--atlas", atlas, "-o", out / "r.exr", "-q"]
    scene.write_text(SCENE.format(intensity=1.0))
    probe = atlasgen(args)
    if probe.returncode == 5:
        pytest.skip(probe.stderr.strip())
    seen = drive(args, out, "r.png", lambda: scene.write_text(SCENE.format(intensity=1.0)),
                 lambda: scene.write_text(SCENE.format(intensity=2.0)))  # fmt: skip
    assert seen["renames"] == ["r.exr", "r.png"]


def _validation_report(seconds: float) -> dict:
    ref = {"description": "closed form", "variant": "llvm_ad_rgb", "spp": 16, "seconds": seconds, "speed_ratio": 2.0,
           "rmse": 0.01, "psnr_db": 40.0, "flip": 0.1, "linear_rmse": 0.01, "linear_relative_rms": 0.02, "meets_goal": True,
           "images": {"reference": "images/r.png", "flip": "images/f.png"}}  # fmt: skip
    row = {"material": "clay", "type": "lambert", "scene": "front", "exposure": 1.0, "atlas_seconds": 0.5,
           "atlas_image": "images/a.png", "references": {"model": ref}, "notes": []}  # fmt: skip
    environment = {"gpu": "lavapipe", "mitsuba": "3.9.1", "atlas_timing": "wall", "mitsuba_timing": "wall"}
    return {"atlas": "atlas.dds", "settings": {"spp": 16, "physical_spp": 64, "goals": {"psnr_db": 30, "flip": 0.2}},
            "environment": environment, "total_seconds": seconds, "results": [row]}  # fmt: skip


def test_a_validation_merge_changes_as_one_set_through_every_fault(tmp_path):
    source = tmp_path / "materials" / "clay"
    source.mkdir(parents=True)
    out = tmp_path / "validation"

    def report(seconds):
        return lambda: (source / "report.json").write_text(json.dumps(_validation_report(seconds)))

    seen = drive(["validate", "--merge", source, "-o", out, "-q"], out, "report.json", report(1.0), report(2.0))
    assert seen["renames"] == ["speed_error.png", "index.html", "report.json"]


def test_a_separable_merge_changes_as_one_set_through_every_fault(tmp_path):
    """``report separable --merge`` of a real study; the new generation's source differs in one figure."""
    lobe = tmp_path / "lobe.toml"
    lobe.write_text('type = "separable"\nsource = "blinn_phong"\nexponent = 40.0\nterms = 2\n')
    source = tmp_path / "studies" / "lobe"
    assert atlasgen(["report", "separable", lobe, "--repeats", "1", "-o", source, "-q"]).returncode == 0
    study = json.loads((source / "report.json").read_text())
    merged = tmp_path / "separable"

    def measured(seconds):
        def put():
            study[0]["timings"]["sample_s"] = seconds
            (source / "report.json").write_text(json.dumps(study))

        return put

    seen = drive(["report", "separable", "--merge", source, "-o", merged, "-q"], merged, "index.md", measured(1.0), measured(2.0))
    assert seen["renames"][-1] == "index.md" and "lobe-terms.png" in seen["renames"]


def test_a_library_report_changes_as_one_set_through_every_fault(tmp_path, library):
    folder, set_old, set_new = library
    atlases = {}
    for name, set_inputs in (("old", set_old), ("new", set_new)):
        set_inputs()
        assert atlasgen(["bake", folder, "-o", tmp_path / name / "atlas.dds", "-q"]).returncode == 0
        atlases[name] = snapshot(tmp_path / name)
    atlas = tmp_path / "atlas" / "atlas.dds"

    def use(name):
        return lambda: restore(atlas.parent, atlases[name])

    page = tmp_path / "library"
    args = ["report", "library", "--atlas", atlas, "--validation", tmp_path / "none", "--separable", tmp_path / "none",
            "-o", page, "--no-physical", "-q"]  # fmt: skip
    seen = drive(args, page, "index.html", use("old"), use("new"))
    assert seen["renames"][-1] == "index.html" and "slices/clay-0.png" in seen["renames"]


def test_two_bakes_of_one_target_at_once_leave_one_generation(tmp_path):
    """The second waits on the first's lock (``make -j`` with two rules writing one atlas)."""
    builds = {}
    for name, colour in (("a", "[0.2, 0.3, 0.4]"), ("b", "[0.7, 0.5, 0.3]")):
        folder = tmp_path / name
        folder.mkdir()
        (folder / "clay.toml").write_text(CLAY.format(colour=colour))
        (folder / "snow.toml").write_text('type = "lambert"\nid = 9\n')
        reference = tmp_path / f"reference-{name}"
        assert atlasgen(["bake", folder, "-o", reference / "atlas.dds", "-q"]).returncode == 0
        builds[name] = (folder, snapshot(reference))
    out = tmp_path / "build" / "atlas.dds"
    stable = ("atlas.dds", "atlas.json", "atlas.wgsl", "atlas.glsl", "atlas.hlsl")
    for _ in range(3):
        runs = [subprocess.Popen([sys.executable, "-m", "atlasgen", "bake", str(folder), "-o", str(out), "-q"], env=ENV,
                                 stderr=subprocess.PIPE, text=True) for folder, _ in builds.values()]  # fmt: skip
        assert [run.wait(timeout=300) for run in runs] == [0, 0], [run.stderr.read() for run in runs]
        now = snapshot(out.parent)
        assert sorted(now) == sorted(builds["a"][1]), sorted(now)  # no journal, lock, temporary or backup left
        assert [n for n, (_, ref) in builds.items() if all(now[f] == ref[f] for f in stable)], "a mixed set"
        read_atlas(out)
