"""Materials the bake cache lacks, baked side by side in worker processes.

A material's bake is independent of every other's and, on this project's machines, CPU-bound
Python and NumPy (the fits, the factorizations, a MaterialX oracle on llvmpipe), so a document of
many slow materials bakes in nearly 1/N of the time on N cores. Baking starts in the calling
process, and only what is left once it has taken :data:`POOL_AFTER_S` goes to workers, so a quick
bake pays for no worker's start-up. Each material is baked whole in one process, by the same code
(:func:`atlasgen.bake.adaptive.bake_material`), so the slices are the same bytes whatever the number
of jobs; the cache is read and written here, in the calling process only.
"""

from __future__ import annotations

import contextlib
import functools
import multiprocessing
import os
import pickle
import shutil
import signal
import tempfile
import threading
import time
import traceback
import warnings
from concurrent.futures import ProcessPoolExecutor

from atlasgen.backend_messages import apply_requested_backend_level
from atlasgen.bake.cache import bake_timed, cache_path, load_timed, store_cached
from atlasgen.bake.quality import check_nonfinite
from atlasgen.interrupts import deferred_interrupts
from atlasgen.models.base import SliceSet

__all__ = ["available_cpus", "load_or_bake_all", "fill_cache", "worker_pool", "Workers", "WorkerTraceback"]


def available_cpus() -> int:
    """The CPUs this process may run on (its affinity mask where the platform has one)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


def _start_worker(filters, folder: str) -> None:
    """A worker's set-up: the caller's warning filters (the CLI shows warnings only as its own lines),
    Ctrl-C left to the caller, which drops the work not started (a worker's own KeyboardInterrupt would
    print a traceback), and an end with the caller's (:func:`_end_with_parent`), which removes the
    pool's ``folder`` of results. Dr.Jit's level is the caller's too (:mod:`atlasgen.backend_messages`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    apply_requested_backend_level()
    warnings.filters[:] = filters
    _end_with_parent(folder)


def _end_with_parent(folder: str) -> None:
    """End this worker as soon as the process that started it has ended, however it ended.

    A caller killed (``kill``, a CI job's time-out, an IDE's stop button: SIGTERM or SIGKILL to it
    alone) runs no clean-up, and its workers would otherwise finish their bake, then block for ever
    writing the result to a pipe nobody reads, each holding its few hundred MB. The parent's sentinel
    (a pipe whose other end only the parent holds) becomes readable when it ends, whatever the cause.
    A parent that ran its clean-up has removed the pool's ``folder`` already; one killed outright has
    not, and every SIGKILL left an empty ``atlasgen-workers-*`` folder in the temporary directory, so
    the workers remove it (each, in case the other is writing its last result into it).
    """
    parent = multiprocessing.parent_process()
    if parent is None:
        return

    def watch() -> None:
        parent.join()
        shutil.rmtree(folder, ignore_errors=True)
        os._exit(1)

    threading.Thread(target=watch, name="atlasgen-end-with-parent", daemon=True).start()


def _picklable_filters() -> list:
    """The warning filters a spawned worker can be given: the caller's, less any that do not pickle."""
    keep = []
    for entry in warnings.filters:
        try:
            pickle.dumps(entry)
        except Exception:  # noqa: BLE001 - a filter on a class defined where a worker cannot import it
            continue
        keep.append(entry)
    return keep


class WorkerTraceback(Exception):
    """The traceback a worker's error was raised with, as text: the ``__cause__`` of that error
    when it is raised again in the calling process (shown by ``--debug``)."""


def _outcome_to_file(function, folder: str, item) -> str:
    """In a worker: ``function(item)``, or the error it raised, pickled to a new file in ``folder``;
    the file's name.

    Only the name crosses the executor's pipe. A message shorter than PIPE_BUF is written in one
    piece, so a worker ended at any instant cannot leave half a result in the pipe, which the
    executor would wait for the rest of for ever; that is what lets :func:`worker_pool` end its
    workers at once instead of letting their tasks finish.
    """
    try:
        outcome = (True, function(item), None)
    except Exception as exc:  # noqa: BLE001 - raised again in the caller, as it was raised here
        outcome = (False, exc, traceback.format_exc())
    handle, path = tempfile.mkstemp(dir=folder, suffix=".pickle")
    with os.fdopen(handle, "wb") as file:
        pickle.dump(outcome, file, protocol=pickle.HIGHEST_PROTOCOL)
    return os.path.basename(path)


class Workers:
    """A pool of worker processes whose results come back through files (:func:`_outcome_to_file`)."""

    def __init__(self, executor: ProcessPoolExecutor, folder: str):
        self._executor = executor
        self._folder = folder

    def map(self, function, items):
        """``function(item)`` for each of ``items``, in their order, computed in the workers (as
        :meth:`concurrent.futures.Executor.map`); the first error raised is raised here."""
        # The submissions start the workers and the executor's manager thread. A Ctrl-C or SIGTERM in the middle
        # left a thread made but not started, whose join in shutdown() raised "cannot join thread before it is
        # started" (an internal error, exit 1), and a worker reading its start-up data from a closed pipe printed
        # its traceback: the signal is held until every worker is started, then raised.
        with deferred_interrupts():
            names = self._executor.map(functools.partial(_outcome_to_file, function, self._folder), items)
        for name in names:
            path = os.path.join(self._folder, name)
            with open(path, "rb") as file:
                ok, value, remote = pickle.load(file)
            os.unlink(path)
            if not ok:
                raise value from WorkerTraceback(remote)
            yield value

    def end(self) -> None:
        """End every worker now, whatever it is running (safe: see :func:`_outcome_to_file`)."""
        for process in list((getattr(self._executor, "_processes", None) or {}).values()):
            with contextlib.suppress(OSError, ValueError):
                process.kill()


@contextlib.contextmanager
def worker_pool(jobs: int):
    """``jobs`` worker processes (the bake's, the reports' measurements) as :class:`Workers`, set up by
    :func:`_start_worker`; spawned: a forked Mitsuba/LLVM runtime or EGL context is not safe to reuse.

    concurrent.futures rather than multiprocessing.Pool: a Pool's terminate() can deadlock
    (python/cpython#73945, #96995; a CI run here hung in it). Leaving the block normally waits for
    the workers to exit. Leaving it on an error, a Ctrl-C, a SIGTERM or a closed generator drops what
    has not started and ends the workers at once: a Ctrl-C or ``kill`` is answered in a moment, not
    once the longest bake running (skin's fit: about 30 s) has finished.
    """
    context = multiprocessing.get_context("spawn")
    folder = tempfile.mkdtemp(prefix="atlasgen-workers-")
    executor = ProcessPoolExecutor(jobs, mp_context=context, initializer=_start_worker, initargs=(_picklable_filters(), folder))
    workers = Workers(executor, folder)
    try:
        yield workers
    except BaseException:
        workers.end()
        raise
    finally:
        executor.shutdown(wait=True, cancel_futures=True)
        shutil.rmtree(folder, ignore_errors=True)


def load_or_bake_all(cache_dir, materials, jobs: int = 1, cache_warnings=None, progress=None) -> list[tuple[SliceSet, bool]]:
    """:func:`~atlasgen.bake.cache.load_or_bake` for each of ``materials``, in their order: ``(slices, hit)``.

    The materials the cache lacks (all of them without a ``cache_dir``) are baked here, one after
    another, until baking has taken :data:`POOL_AFTER_S`; those still to bake are then baked in up
    to ``jobs`` worker processes, one material to a process at a time (:func:`_baked_in_order`).
    Each is stored in the cache as it returns, in order. The first material in order whose bake
    raises stops the pool: its error is raised here as the worker raised it, and the bakes still
    running are ended. So does Ctrl-C, which the workers leave to this process. ``progress`` is
    called with each material's name, in order, once its slices are here.
    """
    results: list = [None] * len(materials)
    todo = []
    for i, material in enumerate(materials):
        slices = load_timed(cache_dir, material, cache_warnings)
        if slices is None:
            todo.append(i)
        else:
            results[i] = (slices, True)
    baked = _baked_in_order([materials[i] for i in todo], jobs)
    try:
        for i, material in enumerate(materials):
            if results[i] is None:
                slices = next(baked)
                if cache_dir is not None:
                    store_cached(cache_dir, material, slices, slices.timings["bake_s"])
                results[i] = (slices, False)
            # A material the assembly will refuse is not reported as baked first (a second line on stderr).
            check_nonfinite(material, results[i][0].extra)
            if progress is not None:
                progress(material.name)
    finally:
        baked.close()  # the workers, if any, end (:func:`_baked_in_order`)
    return results


#: Seconds of baking in process after which the materials still to bake go to worker processes. Starting
#: one costs about a second of CPU (a fresh interpreter importing NumPy and the models), more than a whole
#: bake of most closed-form materials, so a quick bake never starts one.
POOL_AFTER_S = 2.0


def _baked_in_order(materials: list, jobs: int):
    """Each material's :func:`~atlasgen.bake.cache.bake_timed` slices, in order: here until baking has
    taken :data:`POOL_AFTER_S` with two or more left and ``jobs`` > 1, then from a pool of workers."""
    started = time.perf_counter()
    for k, material in enumerate(materials):
        left = len(materials) - k
        if jobs > 1 and left >= 2 and time.perf_counter() - started >= POOL_AFTER_S:
            break
        yield bake_timed(material)
    else:
        return
    with worker_pool(min(jobs, left)) as pool:
        yield from pool.map(bake_timed, materials[k:])


def fill_cache(cache_dir, materials, jobs: int = 1) -> dict:
    """Bake into the cache each material whose entry is missing or stale, in up to ``jobs``
    processes (:func:`load_or_bake_all`); leave the rest.

    An up-to-date entry has its time stamp refreshed, so that ``make``, which asked for
    it because the material file is newer, does not ask again. Returns
    ``{"baked": [names], "hits": [names], "warnings": [lines]}``, the warnings naming
    unreadable entries that were baked again.
    """
    lines: list = []
    results = load_or_bake_all(cache_dir, materials, jobs, lines)
    baked, hits = [], []
    for material, (_, hit) in zip(materials, results, strict=True):
        if hit:
            os.utime(cache_path(cache_dir, material))
        (hits if hit else baked).append(material.name)
    return {"baked": baked, "hits": hits, "warnings": lines}
