"""Issue 24, the fault families: every command's outputs change as one set, for a plain reader.

Each command (``bake`` to DDS and to Zstandard KTX2, ``render``, full ``validate`` and
``validate --merge``, ``report separable`` and its ``--merge``, ``report library``) is driven
through every ``rename``, ``unlink`` and ``symlink`` system call its commit makes in the output
folder, with ``strace`` fault injection in the real command line:

- **killed** there (``SIGKILL``, the call not made): a plain reader (the bytes at the
  documented paths, no hashes checked, no atlasgen code run) sees the old generation or the new
  one, never a mix, and the primary (the file ``make`` targets) is old unless the whole set is new;
- **failing** there (``EIO``): exit 4 with one line and the old generation, or, for a call
  after the commit (tidying), exit 0 and the new one;

and with outputs made immutable in turn (``chattr +i``, as root; skipped otherwise): exit 4
with one line before anything changes. Two bakes of one target at once end as one bake's set.

The old state is saved once and restored (links and all) before each run; only the faulted
runs start an interpreter.
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
from atlasgen.io.atomic import STORE_SUFFIX, TEMP_SUFFIX
from tests.plain_reader import read_plainly

pytestmark = [pytest.mark.slow, pytest.mark.skipif(shutil.which("strace") is None, reason="strace is not installed")]

ENV = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "ATLASGEN_DEBUG": "0"}
CALLS = ("rename", "renameat", "renameat2", "unlink", "unlinkat", "symlink", "symlinkat")
CLAY = 'type = "lambert"\ncolour = {colour}\n'
SCENE = ('[camera]\nposition = [0, 0, 3]\ntarget = [0, 0, 0]\nfov = 30\n[image]\nwidth = 24\nheight = 16\n'
         '[[lights]]\ntype = "directional"\ndirection = [0, 0, -1]\nintensity = {intensity}\n'
         '[[objects]]\nshape = "sphere"\nmaterial = "clay"\n')  # fmt: skip


def atlasgen(args, inject: str | None = None, trace: Path | None = None) -> subprocess.CompletedProcess:
    """``python -m atlasgen ARGS``, under strace when injecting a fault or logging the calls."""
    command = [sys.executable, "-m", "atlasgen", *map(str, args)]
    if inject is not None or trace is not None:
        strace = ["strace", "-f", "-qq", "-y", "-o", str(trace or os.devnull), "-e", f"trace={','.join(CALLS)}"]
        if inject is None or "signal=" not in inject:
            # Only the traced calls stop the process: a third less CPU. strace 6.1 then injects
            # errors but no signals, so the kills run without it.
            strace.insert(1, "--seccomp-bpf")
        command = strace + (["-e", f"inject={inject}"] if inject else []) + command
    return subprocess.run(command, env=ENV, capture_output=True, text=True, timeout=600)


def outputs(folder: Path) -> set:
    """The documented paths under ``folder``: everything but the stores and temporaries."""
    return {p.relative_to(folder).as_posix() for p in folder.rglob("*")
            if not p.relative_to(folder).parts[0].endswith(STORE_SUFFIX) and not p.name.endswith(TEMP_SUFFIX)
            and not (p.is_dir() and not p.is_symlink())}  # fmt: skip


def save(folder: Path, to: Path) -> None:
    shutil.rmtree(to, ignore_errors=True)
    shutil.copytree(folder, to, symlinks=True)


def commit_calls(log: Path, folder: Path) -> list[tuple[str, int, str]]:
    """``(syscall, n, line)`` of each traced call that names a path under ``folder``; ``n`` counts
    that syscall's calls in its process from 1, as strace's ``when=`` does."""
    counts: dict = {}
    found = []
    inside = str(folder) + "/"
    for line in log.read_text().splitlines():
        match = re.match(r"(\d+)\s+(\w+)\(", line)
        if match is None or match.group(2) not in CALLS or "resumed>" in line:
            continue
        key = (match.group(1), match.group(2))
        counts[key] = counts.get(key, 0) + 1
        if inside in line:
            found.append((match.group(2), counts[key], line))
    return found


def chattr(path: Path, flag: str) -> bool:
    """``chattr`` the file a reader of ``path`` opens (a link itself cannot be flagged)."""
    if os.geteuid() != 0 or shutil.which("chattr") is None:
        return False
    return subprocess.run(["chattr", flag, os.path.realpath(path)], capture_output=True).returncode == 0


def one_line(result: subprocess.CompletedProcess) -> str:
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    return lines[0]


def drive(args, folder: Path, primary: str, set_old, set_new, immutable=(), before: str = "links", tidy: bool = False) -> dict:
    """Drive one command through every fault; return what was seen, for :func:`check_seen`.

    ``immutable``: outputs to make immutable in turn; ``tidy``: run once more after the last
    fault (what that leaves is tidied, as tests/test_atomic.py checks in-process). ``before``:
    the old set as one run left it (``links``), as two runs did (``collected``: the commit
    first removes the previous generation), or as plain files (``plain``: an older atlasgen's,
    migrated by the commit). The new generation is the traced run's."""
    shutil.rmtree(folder, ignore_errors=True)
    set_old()
    for _ in range(2 if before == "collected" else 1):
        done = atlasgen(args)
        if done.returncode == 5:  # no Vulkan device, no Mitsuba
            pytest.skip(done.stderr.strip())
        assert done.returncode == 0, done.stderr
    if before == "plain":
        files = {name: (folder / name).read_bytes() for name in outputs(folder)}
        shutil.rmtree(folder)
        for name, data in files.items():
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            (folder / name).write_bytes(data)
    saved = folder.parent / f"{folder.name}.saved"
    save(folder, saved)
    old_names = outputs(folder)
    set_new()
    log = folder.parent / f"{folder.name}.calls.log"
    assert atlasgen(args, trace=log).returncode == 0
    calls = commit_calls(log, folder)
    names = old_names | outputs(folder)
    new = read_plainly(folder, names)
    old = read_plainly(saved, names)
    assert old[primary] != new[primary]
    changed = [name for name in names if old[name] != new[name]]

    def generation(now: dict) -> str:
        """Which generation ``now`` is wholly: ``old``, or ``new`` (every file that differs between
        the two differs from the old one, and is present where the new one has it: measured
        figures, such as timings, differ from run to run)."""
        if now == old:
            return "old"
        assert [n for n in changed if now[n] == old[n] or (now[n] is None) != (new[n] is None)] == [], "a mixed set"
        assert {n: now[n] for n in names if n not in changed} == {n: old[n] for n in names if n not in changed}
        return "new"

    seen = []
    for syscall, n, line in calls:
        save(saved, folder)
        killed = atlasgen(args, inject=f"{syscall}:error=EIO:signal=SIGKILL:when={n}")
        assert killed.returncode in (137, -9), (line, killed.returncode, killed.stderr)
        gen = generation(read_plainly(folder, names))
        save(saved, folder)
        failed = atlasgen(args, inject=f"{syscall}:error=EIO:when={n}")
        if failed.returncode == 4:
            assert re.search(r"cannot (replace|write) \(Input/output error\)", one_line(failed)), (line, failed.stderr)
            assert read_plainly(folder, names) == old, line
        else:
            assert failed.returncode == 0, (line, failed.stderr)  # a call after the commit: tidying
            assert generation(read_plainly(folder, names)) == "new", line
        seen.append((syscall, gen, failed.returncode))
    if tidy:  # after the last kill, the next run finds what it left, tidies it and commits
        assert atlasgen(args).returncode == 0
        assert generation(read_plainly(folder, names)) == "new"
        assert not [p for p in folder.rglob("*") if p.name.endswith(TEMP_SUFFIX)]
    frozen = []
    for name in immutable:
        save(saved, folder)
        if not chattr(folder / name, "+i"):
            break
        try:
            refused = atlasgen(args)
        finally:
            chattr(folder / name, "-i")
        assert refused.returncode == 4, (name, refused.stderr)
        assert one_line(refused).endswith(f"{name}: cannot replace (Operation not permitted); nothing was replaced")
        assert read_plainly(folder, names) == old, name
        frozen.append(name)
    return {"calls": seen, "immutable": frozen}


def check_seen(seen: dict) -> None:
    """The commit is the last rename (``current`` swapped): a kill up to it leaves the old set,
    after it the new one; a failing rename or symlink up to it exits 4, a failing unlink before it
    (collecting an old generation) or any call after it (tidying) is harmless."""
    calls = seen["calls"]
    swap = max(i for i, (syscall, _, _) in enumerate(calls) if syscall.startswith("rename"))
    assert [gen for _, gen, _ in calls] == ["old"] * (swap + 1) + ["new"] * (len(calls) - swap - 1), calls
    expected = [4 if i <= swap and not syscall.startswith("unlink") else 0 for i, (syscall, _, _) in enumerate(calls)]
    assert [rc for _, _, rc in calls] == expected, calls


@pytest.fixture
def library(tmp_path):
    folder = tmp_path / "materials"
    folder.mkdir()
    (folder / "snow.toml").write_text('type = "lambert"\nid = 9\n')

    def colour(rgb: str):
        return lambda: (folder / "clay.toml").write_text(CLAY.format(colour=rgb))

    return folder, colour("[0.2, 0.3, 0.4]"), colour("[0.7, 0.5, 0.3]")


@pytest.mark.parametrize("container", ["dds", "dds over plain files", "ktx2-zstd"])
def test_a_bake_changes_as_one_set_through_every_fault(tmp_path, library, container):
    folder, set_old, set_new = library
    build = tmp_path / "build"
    atlas = build / ("atlas.ktx2" if container == "ktx2-zstd" else "atlas.dds")
    args = ["bake", folder, "-o", atlas, "-q"]
    if container == "ktx2-zstd":
        args += ["--preview", build / "atlas-preview.png", "--zstd"]
        immutable = [atlas.name, "atlas.hlsl", "atlas-preview.png"]
    else:  # four outputs: each call of the commit costs two faulted runs
        args += ["--include", "wgsl"]
        immutable = [atlas.name]
    before = {"dds": "collected", "dds over plain files": "plain"}.get(container, "links")
    seen = drive(args, build, atlas.name, set_old, set_new, immutable, before=before, tidy=True)
    check_seen(seen)
    calls = [syscall for syscall, _, _ in seen["calls"]]
    if before == "plain":  # the holding swap, a link renamed over each file, the swap
        assert calls == ["symlink", "rename"] * (1 + 4 + 1), calls
    elif before == "collected":  # the previous generation's files and record of writers collected, then the swap
        assert calls == ["unlinkat"] * 4 + ["unlink", "symlink", "rename"], calls
    else:
        assert calls == ["symlink", "rename"], calls
    assert seen["immutable"] in ([], immutable)
    read_atlas(atlas)


def test_a_render_changes_as_one_set_through_every_fault(tmp_path, library):
    folder, _, set_colour = library
    set_colour()
    atlas = tmp_path / "atlas.dds"
    assert atlasgen(["bake", folder, "-o", atlas, "-q"]).returncode == 0
    scene = tmp_path / "scene.toml"
    out = tmp_path / "render"
    args = ["render", scene, "--atlas", atlas, "-o", out / "r.exr", "-q"]
    seen = drive(args, out, "r.png", lambda: scene.write_text(SCENE.format(intensity=1.0)),
                 lambda: scene.write_text(SCENE.format(intensity=2.0)), immutable=["r.exr", "r.png"])  # fmt: skip
    check_seen(seen)
    assert seen["immutable"] in ([], ["r.exr", "r.png"])


def _bake_pair(tmp_path: Path, library) -> tuple:
    """Old and new bakes of one atlas path, saved; and a setter for each."""
    folder, set_old, set_new = library
    atlas = tmp_path / "atlas" / "atlas.dds"
    for name, set_inputs in (("old", set_old), ("new", set_new)):
        set_inputs()
        assert atlasgen(["bake", folder, "-o", atlas, "-q"]).returncode == 0
        save(atlas.parent, tmp_path / f"atlas-{name}")

    def use(name):
        return lambda: save(tmp_path / f"atlas-{name}", atlas.parent)

    return atlas, use("old"), use("new")


def test_a_full_validation_changes_as_one_set_through_every_fault(tmp_path, library):
    atlas, use_old, use_new = _bake_pair(tmp_path, library)
    out = tmp_path / "validation"
    args = ["validate", "clay", "--atlas", atlas, "--scene", "front", "--resolution", "24x18", "--no-physical",
            "--cache", tmp_path / "no-cache", "--reference-cache", tmp_path / "references", "-o", out, "-q"]  # fmt: skip
    # The new atlas's references rendered once first: the traced run must make the calls each
    # faulted run makes, and a reference-cache miss adds renames (of the cache's files).
    warm = atlasgen([*args[:-2], tmp_path / "warm", "-q"])  # -o warm
    if warm.returncode == 5:  # no Vulkan device, no Mitsuba
        pytest.skip(warm.stderr.strip())
    seen = drive(args, out, "report.json", use_old, use_new, immutable=["images/clay.front.atlas.png"])
    check_seen(seen)


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
    (source / "images").mkdir(parents=True)
    for name in ("a", "r", "f"):  # the images the report names: a merge links only images that are there
        (source / "images" / f"{name}.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    out = tmp_path / "validation"

    def report(seconds):
        return lambda: (source / "report.json").write_text(json.dumps(_validation_report(seconds)))

    seen = drive(["validate", "--merge", source, "-o", out, "-q"], out, "report.json", report(1.0), report(2.0),
                 immutable=["report.json"])  # fmt: skip
    check_seen(seen)
    assert seen["immutable"] in ([], ["report.json"])


LOBE = 'type = "separable"\nsource = "blinn_phong"\nexponent = {exponent}\nterms = 2\n'


def test_a_separable_study_and_its_merge_change_as_one_set_through_every_fault(tmp_path):
    """``report separable`` (its pages staged, then committed as one set), then ``--merge`` of
    the study it left; the merge's new generation's source differs in one figure."""
    lobe = tmp_path / "lobe.toml"
    study = tmp_path / "studies" / "lobe"
    args = ["report", "separable", lobe, "--repeats", "1", "-o", study, "-q"]
    seen = drive(args, study, "report.json", lambda: lobe.write_text(LOBE.format(exponent=40.0)),
                 lambda: lobe.write_text(LOBE.format(exponent=20.0)))  # fmt: skip
    check_seen(seen)
    figures = json.loads((study / "report.json").read_text())  # the old study or the new, whole
    merged = tmp_path / "separable"

    def measured(seconds):
        def put():
            figures[0]["timings"]["sample_s"] = seconds
            (study / "report.json").unlink()  # a plain file in place of the link: the merge's input
            (study / "report.json").write_text(json.dumps(figures))

        return put

    args = ["report", "separable", "--merge", study, "-o", merged, "-q"]
    seen = drive(args, merged, "index.md", measured(1.0), measured(2.0), immutable=["index.md"])
    check_seen(seen)


def test_a_library_report_changes_as_one_set_through_every_fault(tmp_path, library):
    atlas, use_old, use_new = _bake_pair(tmp_path, library)
    page = tmp_path / "library"
    # Named report folders must hold their reports (and the defaults would read the working folder's build/).
    (tmp_path / "v").mkdir()
    (tmp_path / "v" / "report.json").write_text('{"results": []}')
    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "index.html").write_text("<html></html>")
    (tmp_path / "s" / "report.json").write_text('[{"name": "clay"}]')  # a separable report's, as --separable requires
    args = ["report", "library", "--atlas", atlas, "--validation", tmp_path / "v", "--separable", tmp_path / "s",
            "-o", page, "--no-physical", "-q"]  # fmt: skip
    seen = drive(args, page, "index.html", use_old, use_new, immutable=["slices/clay-0.png"])
    check_seen(seen)


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
        builds[name] = (folder, read_plainly(reference, outputs(reference)))
    out = tmp_path / "build" / "atlas.dds"
    stable = ("atlas.dds", "atlas.json", "atlas.wgsl", "atlas.glsl", "atlas.hlsl")
    for _ in range(2):
        runs = [subprocess.Popen([sys.executable, "-m", "atlasgen", "bake", str(folder), "-o", str(out), "-q"], env=ENV,
                                 stderr=subprocess.PIPE, text=True) for folder, _ in builds.values()]  # fmt: skip
        assert [run.wait(timeout=300) for run in runs] == [0, 0], [run.stderr.read() for run in runs]
        now = read_plainly(out.parent, outputs(out.parent))
        assert sorted(now) == sorted(builds["a"][1]), sorted(now)  # no temporary left
        assert [n for n, (_, ref) in builds.items() if all(now[f] == ref[f] for f in stable)], "a mixed set"
        # lock, current, two generations and their records of writers
        assert len(os.listdir(out.parent / f".atlas{STORE_SUFFIX}")) <= 6
        read_atlas(out)
