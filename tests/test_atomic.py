"""All-or-nothing outputs: a process killed at any step of a commit leaves the primary file
stale, never a new primary beside old side files; the next run repairs everything and
removes the temporaries the killed one left."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from atlasgen.errors import InputError
from atlasgen.io import atomic
from atlasgen.io.atlas import RERUN
from atlasgen.io.atomic import TEMP_SUFFIX, remove_stale_temporaries, write_files_atomically
from atlasgen.render.atlas_texture import read_render_atlas

ROOT = Path(__file__).resolve().parents[1]
OUTPUTS = ("atlas.dds", "atlas.json", "atlas.wgsl", "atlas.glsl", "atlas.hlsl", "atlas.timings.json", "atlas-preview.png")
#: Outputs whose bytes depend only on the inputs (timings hold measured seconds).
DETERMINISTIC = ("atlas.dds", "atlas.json", "atlas.wgsl", "atlas.glsl", "atlas.hlsl", "atlas-preview.png")

#: Runs ``atlasgen`` with a commit hook that records each step and kills the process,
#: as SIGKILL would (no clean-up, no finally), at step ATLASGEN_TEST_KILL_AT.
KILLING_ATLASGEN = """\
import os, sys
kill_at = os.environ.get("ATLASGEN_TEST_KILL_AT")
if kill_at is not None and "--cache-only" not in sys.argv:
    from atlasgen.io import atomic
    steps = []
    def hook(step, path):
        steps.append((step, str(path)))
        if len(steps) - 1 == int(kill_at):
            os._exit(137)
    atomic.commit_hook = hook
from atlasgen.cli.main import main
main()
"""


@pytest.fixture
def record_steps(monkeypatch):
    steps = []
    monkeypatch.setattr(atomic, "commit_hook", lambda step, path: steps.append((step, Path(path).name)))
    return steps


def test_primary_is_renamed_last_after_every_write(tmp_path, record_steps):
    files = {tmp_path / name: name.encode() for name in ("a.dds", "a.json", "a.wgsl")}
    write_files_atomically(files, primary=tmp_path / "a.dds")
    assert record_steps == [("write", "a.json"), ("write", "a.wgsl"), ("write", "a.dds"),
                            ("rename", "a.json"), ("rename", "a.wgsl"), ("rename", "a.dds")]  # fmt: skip
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == {p.name: d for p, d in files.items()}


def test_default_primary_is_the_last_file_given(tmp_path, record_steps):
    write_files_atomically({tmp_path / "x": b"1", tmp_path / "y": b"2"})
    assert [name for step, name in record_steps if step == "rename"] == ["x", "y"]
    with pytest.raises(ValueError):
        write_files_atomically({tmp_path / "x": b"1"}, primary=tmp_path / "z")


def test_a_failed_write_leaves_every_output_and_no_temporary(tmp_path, monkeypatch):
    old = {tmp_path / "a": b"old a", tmp_path / "b": b"old b"}
    for path, data in old.items():
        path.write_bytes(data)

    def fail_on_second_write(step, path):
        if step == "write" and Path(path).name == "b":
            raise OSError("disk full")

    monkeypatch.setattr(atomic, "commit_hook", fail_on_second_write)
    with pytest.raises(OSError):
        write_files_atomically({tmp_path / "a": b"new a", tmp_path / "b": b"new b"})
    assert {p: p.read_bytes() for p in tmp_path.iterdir()} == old


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_stale_temporaries_of_dead_runs_are_removed_and_live_ones_kept(tmp_path):
    target = tmp_path / "atlas.dds"
    dead = tmp_path / f".atlas.dds.{_dead_pid()}.k2j3{TEMP_SUFFIX}"
    dead_folder = tmp_path / f".atlas.dds.{_dead_pid()}.q9x1{TEMP_SUFFIX}"
    live = tmp_path / f".atlas.dds.{os.getpid()}.a8b1{TEMP_SUFFIX}"
    other = tmp_path / f".atlas.json.{_dead_pid()}.zz11{TEMP_SUFFIX}"  # another output's
    foreign = tmp_path / ".atlas.dds.12.tmp"  # not ours: another tool's name
    for path in (dead, live, other, foreign):
        path.write_bytes(b"partial")
    dead_folder.mkdir()
    (dead_folder / "image.png").write_bytes(b"partial")
    write_files_atomically({target: b"new"})
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([target.name, live.name, other.name, foreign.name])
    assert remove_stale_temporaries(tmp_path / "atlas.json") == [other]


def _library(tmp_path: Path, colour: str) -> Path:
    folder = tmp_path / "materials"
    folder.mkdir(exist_ok=True)
    (folder / "clay.toml").write_text(f'type = "lambert"\ncolour = {colour}\n')
    (folder / "snow.toml").write_text('type = "lambert"\nid = 9\n')
    return folder


def _bake_command(library: Path, build: Path) -> list[str]:
    return [sys.executable, "-c", KILLING_ATLASGEN, "bake", str(library), "-o", str(build / "atlas.dds"),
            "--preview", str(build / "atlas-preview.png"), "-q"]  # fmt: skip


def _snapshot(build: Path) -> dict:
    return {name: (build / name).read_bytes() for name in OUTPUTS if (build / name).exists()}


def _temporaries(build: Path) -> list[str]:
    return sorted(p.name for p in build.iterdir() if p.name.endswith(TEMP_SUFFIX))


#: The files a reader uses together: texture, manifest, include.
PAIRED = ("atlas.dds", "atlas.json", "atlas.wgsl")


def _read_as_the_renderer(build: Path, old: dict, new: dict) -> str:
    """What a reader makes of ``build`` now: ``"ok"`` only for the texture, manifest and
    include of one bake; otherwise a one-line refusal that says to re-run the bake."""
    try:
        read_render_atlas(build / "atlas.dds")
    except InputError as exc:
        assert "\n" not in str(exc) and str(exc).endswith(RERUN), str(exc)
        return "refused"
    now = [(build / name).read_bytes() for name in PAIRED]
    assert now in ([old[n] for n in PAIRED], [new[n] for n in PAIRED]), "a mismatched generation was accepted"
    return "ok"


@pytest.mark.slow
def test_a_bake_killed_at_each_step_leaves_the_atlas_stale_and_the_next_run_repairs_it(tmp_path):
    library = _library(tmp_path, "[0.2, 0.3, 0.4]")
    build = tmp_path / "build"
    subprocess.run(_bake_command(library, build), check=True, env=os.environ)
    old = _snapshot(build)
    _library(tmp_path, "[0.7, 0.5, 0.3]")
    reference = tmp_path / "reference"
    subprocess.run(_bake_command(library, reference), check=True)
    new = _snapshot(reference)
    assert old["atlas.dds"] != new["atlas.dds"] and old["atlas.json"] != new["atlas.json"]
    # Five files: five writes, then five renames; the DDS last.
    steps = 2 * len(OUTPUTS)
    seen = []
    for k in range(steps):
        env = {**os.environ, "ATLASGEN_TEST_KILL_AT": str(k)}
        inodes = {name: (build / name).stat().st_ino for name in OUTPUTS}
        killed = subprocess.run(_bake_command(library, build), env=env, capture_output=True)
        assert killed.returncode == 137, (k, killed.stderr)
        now = _snapshot(build)
        # Every file is whole (old or new), and the DDS is still the old one: stale.
        assert all(now[name] in (old[name], new[name]) for name in DETERMINISTIC), k
        json.loads(now["atlas.timings.json"])
        assert now["atlas.dds"] == old["atlas.dds"], k
        # A reader sees the old generation, or refuses the mix (a new manifest beside the old DDS).
        seen.append(_read_as_the_renderer(build, old, new))
        renamed = sorted(name for name in OUTPUTS if (build / name).stat().st_ino != inodes[name])
        assert len(renamed) == max(0, k - len(OUTPUTS)), (k, renamed)
        n = len(OUTPUTS)
        assert len(_temporaries(build)) == min(k, n) - max(0, k - n), k  # written, not yet renamed
        subprocess.run(_bake_command(library, build), check=True)
        repaired = _snapshot(build)
        assert {n: repaired[n] for n in DETERMINISTIC} == {n: new[n] for n in DETERMINISTIC}, k
        assert _temporaries(build) == [], k
        # Back to the old state for the next step.
        for name, data in old.items():
            (build / name).write_bytes(data)
    killed = subprocess.run(_bake_command(library, build), env={**os.environ, "ATLASGEN_TEST_KILL_AT": str(steps)})
    assert killed.returncode == 0  # there is no step after the last rename
    # Before the manifest's rename the old pair is whole; from it until the DDS's, a mix, refused.
    renames = [name for name in OUTPUTS if name != "atlas.dds"] + ["atlas.dds"]
    first_refused = len(OUTPUTS) + renames.index("atlas.json") + 1
    assert seen == ["ok"] * first_refused + ["refused"] * (steps - first_refused), seen
    assert _read_as_the_renderer(build, old, new) == "ok"


MAKE_ATLASGEN = "#!{python}\n" + KILLING_ATLASGEN
T0 = 1_700_000_000


def _make(root: Path, *args: str, kill_at: int | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "MAKEFLAGS": "", "MAKELEVEL": ""}
    if kill_at is not None:
        env["ATLASGEN_TEST_KILL_AT"] = str(kill_at)
    return subprocess.run(["make", "--no-print-directory", *args], cwd=root, env=env, capture_output=True, text=True,
                          timeout=120)  # fmt: skip


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("make") is None, reason="GNU make is not installed")
def test_make_atlas_reruns_a_bake_killed_at_any_step(tmp_path):
    """The real Makefile: after a kill, ``make -q atlas`` says out of date, and ``make atlas``
    leaves the files a clean bake writes."""
    root = tmp_path / "tree"
    root.mkdir()
    shutil.copy(ROOT / "Makefile", root)
    shutil.copytree(ROOT / "atlasgen", root / "atlasgen", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    (root / "pyproject.toml").write_text("")
    venv_bin = root / ".venv" / "bin"
    venv_bin.mkdir(parents=True)
    (venv_bin / "atlasgen").write_text(MAKE_ATLASGEN.format(python=sys.executable))
    (venv_bin / "atlasgen").chmod(0o755)
    (root / ".venv" / ".stamp").write_text("")
    library = _library(root, "[0.2, 0.3, 0.4]")
    build = root / "build"
    assert _make(root, "atlas").returncode == 0
    old = _snapshot(build)
    # Sources, then outputs, in the past; then an edit of a material: make must re-bake
    # it and re-assemble the atlas.
    for path in root.rglob("*"):
        if path.is_file():
            os.utime(path, (T0, T0))
    for path in [*build.rglob("*"), root / ".venv" / ".stamp"]:
        os.utime(path, (T0 + 100, T0 + 100))
    (library / "clay.toml").write_text('type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n')
    for k in (0, len(OUTPUTS), 2 * len(OUTPUTS) - 1):  # first write, first rename, the DDS's rename
        failed = _make(root, "atlas", kill_at=k)
        assert failed.returncode != 0, k
        assert _snapshot(build)["atlas.dds"] == old["atlas.dds"], k
        assert _make(root, "-q", "atlas").returncode == 1, k  # out of date: make will bake again
    done = _make(root, "atlas")
    assert done.returncode == 0, done.stderr
    assert _make(root, "-q", "atlas").returncode == 0
    new = _snapshot(build)
    assert new["atlas.dds"] != old["atlas.dds"] and new["atlas.json"] != old["atlas.json"]
    assert _temporaries(build) == []
    manifest = (build / "atlas.json").read_text()
    assert '"colour": [0.7, 0.5, 0.3]' in manifest
