"""All-or-nothing outputs: a process killed at any step of a commit leaves the primary file
stale, never a new primary beside old side files; any reader finishes a commit whose journal
was written, and the next run removes the temporaries the killed one left."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from atlasgen.errors import InputError, OutputError
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
def test_a_bake_killed_at_each_step_leaves_the_atlas_stale_and_any_reader_finishes_the_set(tmp_path):
    library = _library(tmp_path, "[0.2, 0.3, 0.4]")
    build = tmp_path / "build"
    subprocess.run(_bake_command(library, build), check=True, env=os.environ)
    old = _snapshot(build)
    _library(tmp_path, "[0.7, 0.5, 0.3]")
    reference = tmp_path / "reference"
    subprocess.run(_bake_command(library, reference), check=True)
    new = _snapshot(reference)
    assert old["atlas.dds"] != new["atlas.dds"] and old["atlas.json"] != new["atlas.json"]
    # Seven files: seven writes, then seven renames; the DDS last.
    n = len(OUTPUTS)
    steps = 2 * n
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
        renamed = sorted(name for name in OUTPUTS if (build / name).stat().st_ino != inodes[name])
        assert len(renamed) == max(0, k - n), (k, renamed)
        # The journal is written before the first rename: from then on the set is the new one's to finish.
        assert (build / ".atlas.atlasgen.journal").exists() == (k >= n), k
        # Any reader finishes (or never started) the commit: the plain files are then one generation.
        assert _read_as_the_renderer(build, old, new) == "ok", k
        expected = new if k >= n else old
        assert {name: (build / name).read_bytes() for name in DETERMINISTIC} == {n_: expected[n_] for n_ in DETERMINISTIC}, k
        assert len(_temporaries(build)) == (0 if k >= n else k), k  # a killed write's temporaries wait for the next write
        subprocess.run(_bake_command(library, build), check=True)
        repaired = _snapshot(build)
        assert {n_: repaired[n_] for n_ in DETERMINISTIC} == {n_: new[n_] for n_ in DETERMINISTIC}, k
        assert _temporaries(build) == [] and not list(build.glob(".*.atlasgen.*")), k
        # Back to the old state for the next step.
        for name, data in old.items():
            (build / name).write_bytes(data)
    killed = subprocess.run(_bake_command(library, build), env={**os.environ, "ATLASGEN_TEST_KILL_AT": str(steps)})
    assert killed.returncode == 0  # there is no step after the last rename
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
        # Back to the old outputs for the next step (the next bake would finish this one's commit first).
        for leftover in build.glob(".atlas*"):
            leftover.unlink()
        for name, data in old.items():
            (build / name).write_bytes(data)
            os.utime(build / name, (T0 + 100, T0 + 100))
    done = _make(root, "atlas")
    assert done.returncode == 0, done.stderr
    assert _make(root, "-q", "atlas").returncode == 0
    new = _snapshot(build)
    assert new["atlas.dds"] != old["atlas.dds"] and new["atlas.json"] != old["atlas.json"]
    assert _temporaries(build) == []
    manifest = (build / "atlas.json").read_text()
    assert '"colour": [0.7, 0.5, 0.3]' in manifest


# ---- the journaled commit: checked before the first rename, rolled back, recovered, locked ----


def _chattr(path: Path, flag: str) -> bool:
    """``chattr +i``/``-i`` (root only, and a file system that keeps the flag); False where it cannot."""
    if os.geteuid() != 0 or shutil.which("chattr") is None:
        return False
    return subprocess.run(["chattr", flag, str(path)], capture_output=True).returncode == 0


def _three(folder: Path, tag: str) -> dict:
    return {folder / name: f"{tag} {name}".encode() for name in ("a.json", "a.wgsl", "a.dds")}


@pytest.mark.parametrize("stuck", ["a.json", "a.wgsl", "a.dds"])
def test_an_immutable_target_refuses_the_commit_before_any_rename(tmp_path, stuck):
    old = _three(tmp_path, "old")
    for path, data in old.items():
        path.write_bytes(data)
    if not _chattr(tmp_path / stuck, "+i"):
        pytest.skip("chattr +i needs root and a file system with the immutable flag")
    try:
        with pytest.raises(OutputError, match=rf"{stuck}: cannot replace \(Operation not permitted\); nothing was replaced"):
            write_files_atomically(_three(tmp_path, "new"), primary=tmp_path / "a.dds")
    finally:
        _chattr(tmp_path / stuck, "-i")
    assert {p: p.read_bytes() for p in tmp_path.iterdir()} == old  # no temporary, backup, journal or lock left


@pytest.mark.parametrize("failing", [0, 1, 2])
def test_a_rename_that_fails_rolls_back_every_rename_before_it(tmp_path, monkeypatch, failing):
    old = _three(tmp_path, "old")
    for path, data in old.items():
        path.write_bytes(data)
    new = {**_three(tmp_path, "new"), tmp_path / "a.glsl": b"new a.glsl"}  # one target that did not exist
    calls = []
    real_replace = os.replace

    def replace(src, dst):
        calls.append(Path(dst).name)
        if len(calls) == failing + 2:  # after the new file's rename (and `failing` more)
            raise OSError(5, "Input/output error")
        real_replace(src, dst)

    monkeypatch.setattr(atomic.os, "replace", replace)
    with pytest.raises(OutputError, match="cannot replace .*every output was left as it was"):
        write_files_atomically(new, primary=tmp_path / "a.dds", remove=[tmp_path / "stale.bin"])
    assert {p: p.read_bytes() for p in tmp_path.iterdir()} == old


def _journal_case(tmp_path: Path, kill_after: int, rollback: bool = False) -> tuple[dict, dict]:
    """A commit of three files (one removal) stopped, as a kill would, after ``kill_after`` renames."""
    old = _three(tmp_path, "old")
    for path, data in old.items():
        path.write_bytes(data)
    (tmp_path / "a.separable.bin").write_bytes(b"stale")
    old[tmp_path / "a.separable.bin"] = b"stale"
    new = _three(tmp_path, "new")

    class Killed(BaseException):
        pass

    renames = []

    def hook(step, path):
        if step == "rename":
            renames.append(path)
            if len(renames) > kill_after:
                raise Killed

    atomic.commit_hook = hook
    real_unlink = atomic._unlink
    try:
        # A kill leaves every file as it is: no clean-up may run.
        atomic._unlink = lambda path: None  # type: ignore[assignment]
        with pytest.raises(Killed):
            write_files_atomically(new, primary=tmp_path / "a.dds", remove=[tmp_path / "a.separable.bin"])
    finally:
        atomic.commit_hook = None
        atomic._unlink = real_unlink  # type: ignore[assignment]
    if rollback:
        (tmp_path / ".a.atlasgen.rollback").touch()
    return old, new


def _outputs(folder: Path) -> dict:
    return {p: p.read_bytes() for p in folder.iterdir()}


@pytest.mark.parametrize("kill_after", [0, 1, 2, 3])
def test_a_reader_rolls_a_killed_commit_forward(tmp_path, kill_after):
    _, new = _journal_case(tmp_path, kill_after)
    assert (tmp_path / ".a.atlasgen.journal").exists()
    assert atomic.recover_commits(tmp_path) == [tmp_path / ".a.atlasgen.journal"]
    assert _outputs(tmp_path) == new  # the side-car removed, every temporary and backup gone


@pytest.mark.parametrize("kill_after", [0, 1, 2, 3])
def test_a_killed_rollback_is_rolled_back(tmp_path, kill_after):
    old, _ = _journal_case(tmp_path, kill_after, rollback=True)
    atomic.recover_commits(tmp_path)
    assert _outputs(tmp_path) == old


def test_a_half_written_journal_is_discarded_with_nothing_renamed(tmp_path):
    (tmp_path / "a.dds").write_bytes(b"old")
    (tmp_path / ".a.atlasgen.journal").write_text('{"version": 1, "entries": [{"target": ')
    write_files_atomically({tmp_path / "a.dds": b"new"})
    assert _outputs(tmp_path) == {tmp_path / "a.dds": b"new"}


def test_a_second_writer_waits_for_the_lock_then_refuses_with_one_line(tmp_path):
    with atomic.output_lock(tmp_path, "a") as lock:
        assert lock == tmp_path / ".a.atlasgen.lock" and lock.exists()
        with pytest.raises(OutputError) as refused:
            with atomic.output_lock(tmp_path, "a", timeout=0.2):
                pass
        assert str(refused.value) == (f"{lock.as_posix()}: another atlasgen process is writing this output set "
                                      "(waited 0.2 s); expected one writer at a time")  # fmt: skip
        with atomic.output_lock(tmp_path, "b", timeout=0):  # another set's lock is free
            pass
    assert not lock.exists()
    with atomic.output_lock(tmp_path, "a", timeout=0):
        pass


def test_removed_siblings_go_in_the_same_commit(tmp_path):
    for name in ("a.dds", "a.glsl", "a.ktx2"):
        (tmp_path / name).write_bytes(b"old")
    write_files_atomically({tmp_path / "a.dds": b"new"}, remove=[tmp_path / "a.glsl", tmp_path / "a.ktx2", tmp_path / "gone"])
    assert _outputs(tmp_path) == {tmp_path / "a.dds": b"new"}


def test_a_killed_commit_whose_target_became_immutable_is_rolled_back(tmp_path):
    old, _ = _journal_case(tmp_path, 1)  # a.json renamed, a.wgsl and a.dds not yet
    if not _chattr(tmp_path / "a.dds", "+i"):
        pytest.skip("chattr +i needs root and a file system with the immutable flag")
    try:
        atomic.recover_commits(tmp_path)
        left = _outputs(tmp_path)
    finally:
        _chattr(tmp_path / "a.dds", "-i")
    # Every output as it was; the immutable file's backup (a link to it) cannot be removed, and stays hidden.
    assert {p: d for p, d in left.items() if not p.name.startswith(".")} == old
    assert [(p.name.startswith(".a.dds."), d) for p, d in left.items() if p.name.startswith(".")] == [(True, b"old a.dds")]
