"""Materials baked in worker processes: the same bytes as in process, the cache filled once, the
first failing material's own error, the progress in order, and typed errors across processes."""

from __future__ import annotations

import os
import pickle
import shutil
import signal
import subprocess
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from click.testing import CliRunner

from atlasgen.bake import cache as bake_cache
from atlasgen.bake import workers
from atlasgen.bake.cache import cache_path
from atlasgen.bake.pipeline import bake_atlas
from atlasgen.bake.workers import fill_cache, load_or_bake_all
from atlasgen.cli.main import app
from atlasgen.errors import FieldError, ManifestError, MaterialError, SceneError
from atlasgen.io.manifest import format_manifest
from atlasgen.materials.material import read_materials
from tests.terminal import as_in_a_terminal

SHOWCASE = Path(__file__).resolve().parents[2] / "materials" / "materialx-showcase.mtlx"
LIBRARY = {
    "clay": 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n',
    "shell": 'type = "iridescent"\nthickness = 420.0\n',
    "rim": 'type = "backlit"\n',
    "band": 'type = "toon"\nthresholds = [0.05, 0.55]\n',
}


@pytest.fixture
def library(write_material):
    return read_materials([write_material(name, body) for name, body in LIBRARY.items()])


@pytest.mark.slow
def test_two_jobs_bake_the_bytes_of_one_and_fill_the_cache_once(tmp_path, library, monkeypatch):
    serial = bake_atlas(library, jobs=1)
    monkeypatch.setattr(workers, "POOL_AFTER_S", 0.0)  # workers from the first material on
    pools = []
    start = workers.worker_pool
    monkeypatch.setattr(workers, "worker_pool", lambda jobs: pools.append(jobs) or start(jobs))
    seen = []
    parallel = bake_atlas(library, jobs=2, cache_dir=tmp_path / "cache", progress=seen.append)
    assert all(np.array_equal(a, b) for a, b in zip(serial.levels, parallel.levels, strict=True))
    assert format_manifest(serial.manifest) == format_manifest(parallel.manifest)
    assert serial.include == parallel.include
    assert seen == [m.name for m in library] and pools == [2]
    assert parallel.timings["cache"]["baked"] == [m.name for m in library]
    assert all(parallel.timings["materials"][m.name]["bake_s"] > 0 for m in library)
    # Every entry was written by this process, once: a second bake loads them all.
    again = bake_atlas(library, jobs=2, cache_dir=tmp_path / "cache")
    assert again.timings["cache"]["hits"] == [m.name for m in library]
    assert all(np.array_equal(a, b) for a, b in zip(serial.levels, again.levels, strict=True))


@pytest.mark.slow
def test_the_first_failing_material_s_own_error_is_raised_and_the_bakes_before_it_are_cached(tmp_path, library, monkeypatch):
    monkeypatch.setattr(workers, "POOL_AFTER_S", 0.0)
    broken = replace(library[1], params={**library[1].params, "thickness": "thick"})
    materials = [library[0], broken, *library[2:]]
    with pytest.raises(ValueError, match="'thick'"):
        load_or_bake_all(tmp_path, materials, jobs=2)
    assert cache_path(tmp_path, library[0]).is_file()
    assert not cache_path(tmp_path, broken).exists()


def test_one_job_or_one_material_to_bake_stays_in_process(tmp_path, library, monkeypatch):
    def no_pool(*args, **kwargs):
        raise AssertionError("a process pool was started")

    monkeypatch.setattr(workers, "worker_pool", no_pool)
    monkeypatch.setattr(workers, "POOL_AFTER_S", 0.0)  # so only the job and material counts keep the pool away
    fill_cache(tmp_path, library[:1], jobs=4)
    assert fill_cache(tmp_path, library, jobs=1)["hits"] == [library[0].name]
    assert all(cache_path(tmp_path, m).is_file() for m in library)


@pytest.mark.slow
def test_workers_start_once_baking_here_has_taken_pool_after_s(library, monkeypatch):
    """A quick bake never pays for a worker's start-up: the first materials bake here, and the pool,
    of no more workers than materials left, takes the rest once POOL_AFTER_S has passed."""
    ticks = iter(range(100))
    monkeypatch.setattr(workers, "time", SimpleNamespace(perf_counter=lambda: 1.5 * next(ticks)))
    pools = []
    start = workers.worker_pool
    monkeypatch.setattr(workers, "worker_pool", lambda jobs: pools.append(jobs) or start(jobs))
    mixed = load_or_bake_all(None, library, jobs=4)
    assert pools == [3]  # material 0 here (1.5 s < 2 s), then 3 s: the other three in three workers
    serial = load_or_bake_all(None, library, jobs=1)
    assert all(np.array_equal(a.values, b.values) for (a, _), (b, _) in zip(mixed, serial, strict=True))
    assert pools == [3]


def test_slices_given_to_the_bake_are_used_not_baked_again(library, monkeypatch):
    """A preview's completed drafts reach the atlas as they are (``bake_atlas(baked=...)``)."""
    first = bake_atlas(library[:1])
    slices = bake_cache.load_or_bake(None, library[0])[0]

    def refuse(material):
        raise AssertionError(f"{material.name} baked again")

    monkeypatch.setattr(bake_cache, "bake_material", refuse)
    given = bake_atlas(library[:1], baked={library[0].name: slices})
    assert all(np.array_equal(a, b) for a, b in zip(first.levels, given.levels, strict=True))


@pytest.mark.parametrize("kind", [FieldError, MaterialError, SceneError, ManifestError])
def test_typed_errors_cross_a_process_boundary_whole(kind):
    error = kind("materials/gold.toml", "ior", "expected a finite number >= 1, got nan")
    back = pickle.loads(pickle.dumps(error))
    assert type(back) is kind and str(back) == str(error) and back.exit_code == error.exit_code
    assert (back.path, back.field, back.expected) == (error.path, error.field, error.expected)


def test_jobs_must_be_a_positive_count(tmp_path, write_material):
    clay = write_material("clay", LIBRARY["clay"])
    res = CliRunner().invoke(app, ["bake", str(clay), "-o", str(tmp_path / "a.dds"), "-j", "0"])
    assert res.exit_code == 2 and "'-j' / '--jobs'" in res.stderr


def _worker_state(_=None):
    """In a bake worker: whether it ignores SIGINT, and the action of its first warning filter."""
    return signal.getsignal(signal.SIGINT) == signal.SIG_IGN, [entry[0] for entry in warnings.filters[:1]]


def test_workers_leave_ctrl_c_to_the_caller_and_take_its_warning_filters():
    """The CLI shows warnings only as its own lines, and one line for Ctrl-C: a worker printing either
    itself (a RuntimeWarning, a KeyboardInterrupt traceback) would break both."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with workers.worker_pool(1) as pool:
            state = next(pool.map(_worker_state, [None]))
    assert state == (True, ["ignore"])


def _workers_of(pid: int) -> list[int]:
    """The live bake workers (spawned multiprocessing children) of process ``pid``, from /proc."""
    found = []
    for task in Path(f"/proc/{pid}/task").glob("*/children"):
        for child in task.read_text().split():
            try:
                command = Path(f"/proc/{child}/cmdline").read_bytes()
            except OSError:
                continue
            if b"spawn_main" in command:
                found.append(int(child))
    return found


#: How a command with workers is stopped, and the status and stderr it then ends with: Ctrl-C (a terminal
#: signals the whole process group), and ``kill`` of the command alone (a CI job's time-out, an IDE's stop button).
STOPS = {
    "Ctrl-C": (signal.SIGINT, True, 130, "atlasgen: interrupted\n"),
    "SIGTERM": (signal.SIGTERM, False, 143, "atlasgen: terminated\n"),
    "SIGKILL": (signal.SIGKILL, False, -signal.SIGKILL, None),
}


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="reads the process tree from /proc")
@pytest.mark.parametrize("stop", list(STOPS))
def test_a_stopped_bake_ends_its_workers_and_leaves_the_old_atlas(tmp_path, write_material, stop):
    """Ctrl-C is one line and 130, SIGTERM one line and 143, each output set whole (docs/cli.md): so with
    workers too. A ``kill`` used to leave the workers running: each finished its bake, then blocked for ever
    writing the result to a pipe nobody read, holding a few hundred MB. Even a SIGKILL, which runs no
    clean-up, now ends them (each worker watches its parent, atlasgen.bake.workers._end_with_parent), and
    they remove the pool's folder of results, which every SIGKILL used to leave in the temporary directory."""
    pytest.importorskip("MaterialX")
    pytest.importorskip("moderngl")
    signum, whole_group, status, line = STOPS[stop]
    out = tmp_path / "build" / "atlas.dds"
    clay = write_material("clay", LIBRARY["clay"])
    assert CliRunner().invoke(app, ["bake", str(clay), "-o", str(out), "-q"]).exit_code == 0
    old = out.read_bytes()
    doc = tmp_path / "showcase.mtlx"
    shutil.copy(SHOWCASE, doc)
    command = [sys.executable, "-m", "atlasgen", "bake", str(doc), "-o", str(out), "-j", "2", "-q"]
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    child = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, start_new_session=True,
                             preexec_fn=as_in_a_terminal, env={**os.environ, "TMPDIR": str(temporary)})  # fmt: skip
    workers_seen = []
    try:
        deadline = time.monotonic() + 120
        while len(_workers_of(child.pid)) < 2 and time.monotonic() < deadline and child.poll() is None:
            time.sleep(0.05)
        workers_seen = _workers_of(child.pid)
        assert len(workers_seen) == 2, "no workers started"
        time.sleep(1.0)  # inside the materials' bakes
        if whole_group:
            os.killpg(child.pid, signum)
        else:
            child.send_signal(signum)
        _, stderr = child.communicate(timeout=60)
        deadline = time.monotonic() + 30  # a SIGKILL's workers notice a moment later
        while [pid for pid in workers_seen if _alive(pid)] and time.monotonic() < deadline:
            time.sleep(0.1)
    finally:
        child.kill()
        for pid in workers_seen:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
    if signum == signal.SIGKILL:
        # No handler runs: only multiprocessing's resource tracker (its own process) may warn of the pool's
        # semaphores, which it then removes.
        assert child.returncode == status and "atlasgen" not in stderr and "Traceback" not in stderr, stderr
    else:
        assert (child.returncode, stderr) == (status, line), stderr
    assert not [pid for pid in workers_seen if _alive(pid)], "a worker outlived the command"
    assert out.read_bytes() == old
    assert not list(temporary.glob("atlasgen-workers-*")), "the pool's folder of results was left behind"


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, ended but not yet reaped by init, counts as ended)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _sleep_or_fail(task):
    """A worker's task: ``("sleep", s)`` sleeps s seconds; ``("fail", s)`` raises ValueError after s."""
    what, seconds = task
    time.sleep(seconds)
    if what == "fail":
        raise ValueError("the first task's own error")
    return seconds


def _on_alarm(signum, frame):
    raise KeyboardInterrupt


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="reads the process tree from /proc")
@pytest.mark.parametrize("leaving", ["an error", "an interrupt"])
def test_leaving_the_pool_early_ends_the_running_workers_at_once(leaving, monkeypatch):
    """A Ctrl-C, a SIGTERM or an error used to wait for every task already running: a ``-j 2`` bake
    took up to 30 s (skin's fit) to answer a ``kill``. Results now come back through files, so the
    workers can be ended at any instant without cutting a message in the executor's pipe."""
    tasks = [("fail", 1.0), ("sleep", 300.0)] if leaving == "an error" else [("sleep", 300.0), ("sleep", 300.0)]
    expected = ValueError if leaving == "an error" else KeyboardInterrupt
    if leaving == "an interrupt":
        previous = signal.signal(signal.SIGALRM, _on_alarm)
        signal.setitimer(signal.ITIMER_REAL, 8.0)  # the workers spawned and inside their tasks
    started = time.monotonic()
    seen = []
    try:
        with pytest.raises(expected) as raised:
            with workers.worker_pool(2) as pool:
                for value in pool.map(_sleep_or_fail, tasks):
                    seen.append(value)
    finally:
        if leaving == "an interrupt":
            signal.setitimer(signal.ITIMER_REAL, 0.0)
            signal.signal(signal.SIGALRM, previous)
    assert time.monotonic() - started < 60.0, "the pool waited for a task still running"
    assert seen == [] and not _workers_of(os.getpid()), "a worker outlived the pool"
    if leaving == "an error":
        # The worker's own traceback stays with the error, for --debug.
        assert isinstance(raised.value.__cause__, workers.WorkerTraceback)
        assert "_sleep_or_fail" in str(raised.value.__cause__)


@pytest.mark.slow
def test_a_ctrl_c_while_the_workers_start_ends_the_pool_cleanly(monkeypatch):
    """A SIGTERM as the pool started ended in "internal error (RuntimeError: cannot join thread before it is
    started)", exit 1, and a worker's traceback: the signal is held until every worker has started."""
    from concurrent.futures import process

    start = process._ExecutorManagerThread.start

    def interrupted_start(self):
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C between making the executor's thread and starting it
        return start(self)

    monkeypatch.setattr(process._ExecutorManagerThread, "start", interrupted_start)
    before = set(Path(workers.tempfile.gettempdir()).glob("atlasgen-workers-*"))
    with pytest.raises(KeyboardInterrupt):
        with workers.worker_pool(2) as pool:
            list(pool.map(_sleep_or_fail, [("sleep", 300.0), ("sleep", 300.0)]))
    assert not _workers_of(os.getpid()), "a worker outlived the pool"
    assert set(Path(workers.tempfile.gettempdir()).glob("atlasgen-workers-*")) == before, "its folder was left"
