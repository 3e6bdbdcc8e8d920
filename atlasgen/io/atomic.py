"""All-or-nothing output sets: a journaled commit under a lock.

A command's outputs (a bake's ``X.dds``, ``X.json``, includes, side-car and timings; a
render's EXR and PNG; a report's pages) change together or not at all, as seen by any
atlasgen reader and, once any atlasgen command has touched the folder after a crash, by a
plain file reader too. The files at the documented paths stay plain files. The commit:

1. **Lock.** ``fcntl.flock`` on ``.<key>.atlasgen.lock`` beside the primary output (``key``:
   the primary's name up to its first dot), waiting up to :data:`LOCK_TIMEOUT_S` for another
   writer of the same set, then refusing with one line. A leftover journal of a killed
   writer is recovered first (step 6).
2. **Stage.** Every new file is written to a temporary beside its target and fsynced.
3. **Check.** Every existing target (and every file the commit removes) gets a hard-linked
   backup: this fails, before any rename, for a target that cannot be replaced (immutable,
   append-only, a read-only file system), so nothing is replaced.
4. **Journal.** ``.<key>.atlasgen.journal`` names, for every target, its new temporary and
   its backup; it is fsynced (and its folder) before the first rename.
5. **Rename** each temporary over its target (removals unlink), the primary last, then fsync
   the folders, delete the journal, and then the backups. A rename that still fails rolls
   every renamed target back from its backup before the error is raised: nothing changed.
6. **Recover.** A journal left by a killed writer is rolled *forward* (the rest of its
   temporaries renamed, its removals done) by the next writer of the set or by any atlasgen
   reader of the folder (:func:`recover_commits`); a killed rollback (marked by
   ``.<key>.atlasgen.rollback``) is rolled back. A journal that is not complete (the writer
   died writing it, before any rename) is deleted.

Ctrl-C is held during steps 4-5 (:func:`atlasgen.interrupts.deferred_interrupts`) and acted
on once the set is whole. Because the primary (the file a ``make`` rule targets) is renamed
last, a run killed mid-commit also leaves it stale, so ``make`` runs the command again.

Temporaries and backups are named ``.<name>.<pid>.<random>.atlasgen.tmp`` beside their
target; the next write of the same target removes those whose process is gone (never those
of a live process: it may be a parallel job).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import re
import shutil
import tempfile
import time
from pathlib import Path

from atlasgen.errors import OutputError
from atlasgen.interrupts import deferred_interrupts

__all__ = [
    "write_files_atomically",
    "write_file_atomically",
    "staged_folder",
    "scratch_folder",
    "remove_stale_temporaries",
    "recover_commits",
    "output_lock",
    "set_key",
    "TEMP_SUFFIX",
    "LOCK_SUFFIX",
    "JOURNAL_SUFFIX",
    "LOCK_TIMEOUT_S",
]

#: Every temporary file or folder this module creates ends with this.
TEMP_SUFFIX = ".atlasgen.tmp"
#: ``.<key>.atlasgen.lock``: the lock file of an output set, present only while a writer holds it.
LOCK_SUFFIX = ".atlasgen.lock"
#: ``.<key>.atlasgen.journal``: present only while a commit renames, or after one was killed.
JOURNAL_SUFFIX = ".atlasgen.journal"
#: ``.<key>.atlasgen.rollback``: present only while a failed commit rolls back.
ROLLBACK_SUFFIX = ".atlasgen.rollback"
#: Seconds a writer waits for another writer of the same output set (``ATLASGEN_LOCK_TIMEOUT_S``
#: overrides it) before it refuses with one line.
LOCK_TIMEOUT_S = 120.0
JOURNAL_VERSION = 1

#: Test hook: when set, called as ``hook(step, path)`` before each step of a commit,
#: ``step`` being ``"write"`` (a temporary for ``path``) or ``"rename"`` (onto ``path``, or
#: its removal). Tests set it to kill the process at every step in turn; it is None otherwise.
commit_hook = None


def _step(step: str, path: Path) -> None:
    if commit_hook is not None:
        commit_hook(step, path)


def _temp_prefix(name: str) -> str:
    return f".{name}.{os.getpid()}."


def _folder(path: Path) -> Path:
    return path.parent if str(path.parent) else Path(".")


def set_key(primary) -> str:
    """The name an output set's lock and journal are called by: the primary's name up to its first dot.

    >>> set_key("build/atlas.dds"), set_key("out/report.json"), set_key(".hidden")
    ('atlas', 'report', '.hidden')
    """
    name = Path(primary).name
    return name.split(".", 1)[0] or name


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    return True


def remove_stale_temporaries(path) -> list[Path]:
    """Remove the temporaries of ``path`` left by runs that died; return what was removed.

    Only names this module makes (``.<name>.<pid>.<random>.atlasgen.tmp``) whose pid is no
    longer running are touched; files and folders alike.
    """
    path = Path(path)
    folder = _folder(path)
    pattern = re.compile(re.escape(f".{path.name}.") + r"(\d+)\.[^.]+" + re.escape(TEMP_SUFFIX) + "$")
    removed: list[Path] = []
    try:
        candidates = list(folder.iterdir())
    except OSError:
        return removed
    for candidate in candidates:
        match = pattern.match(candidate.name)
        if match is None or _pid_alive(int(match.group(1))):
            continue
        try:
            if candidate.is_dir() and not candidate.is_symlink():
                shutil.rmtree(candidate)
            else:
                candidate.unlink()
            removed.append(candidate)
        except OSError:
            pass
    return removed


def _fsync_folder(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _unlink(path) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)


def _lock_timeout() -> float:
    try:
        return float(os.environ.get("ATLASGEN_LOCK_TIMEOUT_S", LOCK_TIMEOUT_S))
    except ValueError:
        return LOCK_TIMEOUT_S


@contextlib.contextmanager
def output_lock(folder, key: str, timeout: float | None = None):
    """Hold ``folder/.<key>.atlasgen.lock`` (``fcntl.flock``, exclusive) for the block.

    Waits up to ``timeout`` seconds (default :data:`LOCK_TIMEOUT_S`, or
    ``ATLASGEN_LOCK_TIMEOUT_S``) for another process holding it.

    Raises
    ------
    OutputError
        The lock file cannot be opened, or another writer held it for the whole timeout.
    """
    folder = Path(folder)
    lock_path = folder / f".{key}{LOCK_SUFFIX}"
    timeout = _lock_timeout() if timeout is None else timeout
    deadline = time.monotonic() + timeout
    while True:
        try:
            fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise OutputError(f"{lock_path.as_posix()}: cannot open the output set's lock file ({exc.strerror})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            if time.monotonic() >= deadline:
                raise OutputError(f"{lock_path.as_posix()}: another atlasgen process is writing this output set "
                                  f"(waited {timeout:g} s); expected one writer at a time") from None  # fmt: skip
            time.sleep(0.05)
            continue
        try:
            current = os.stat(lock_path).st_ino
        except FileNotFoundError:
            current = None
        if current == os.fstat(fd).st_ino:
            break
        os.close(fd)  # the holder before us removed the file we locked: lock the new one
    try:
        yield lock_path
    finally:
        # Removed while still held, so no lock file is left beside the outputs; a waiter
        # that locked the removed file notices above and locks afresh.
        _unlink(lock_path)
        os.close(fd)


def _read_journal(journal: Path) -> list | None:
    """The entries of a complete journal, or None for one a killed writer left half-written."""
    try:
        data = json.loads(journal.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("version") != JOURNAL_VERSION or data.get("complete") is not True:
        return None
    entries = data.get("entries")
    ok = isinstance(entries, list) and all(
        isinstance(e, dict)
        and isinstance(e.get("target"), str)
        and all(isinstance(e.get(k), (str, type(None))) for k in ("new", "old"))
        for e in entries
    )
    return entries if ok else None


def _roll_back(entries: list) -> None:
    """Undo a commit's renames: every target as its backup had it (or absent, if it had none)."""
    for entry in reversed(entries):
        target, new, old = entry["target"], entry["new"], entry["old"]
        if new is not None and os.path.lexists(new):
            _discard(new)  # never renamed: the target is still the old file
            if old is not None:
                _discard(old)
            continue
        if old is not None:
            if os.path.lexists(old):
                os.replace(old, target)  # a no-op when both are links of one file ...
                _discard(old)  # ... which leaves the backup to remove
        elif new is not None:
            _unlink(target)  # the target did not exist before this commit


def _roll_forward(entries: list) -> None:
    """Finish a commit whose journal is complete: the remaining renames and removals, then the backups."""
    for entry in entries:
        target, new = entry["target"], entry["new"]
        if new is None:
            _unlink(target)
        elif os.path.lexists(new):
            os.replace(new, target)
    for folder in dict.fromkeys(os.path.dirname(e["target"]) or "." for e in entries):
        _fsync_folder(Path(folder))


def _remove_backups(entries: list) -> None:
    for entry in entries:
        if entry["old"] is not None:
            _discard(entry["old"])


def _discard(path) -> None:
    """Remove a temporary or a backup if it can be: a backup of an immutable file cannot be, and
    stays (under a temporary's name) without harm."""
    with contextlib.suppress(OSError):
        os.unlink(path)


def _recover(journal: Path) -> None:
    """Roll a leftover journal forward, or back when a rollback was under way; the caller holds the lock."""
    marker = journal.with_name(journal.name[: -len(JOURNAL_SUFFIX)] + ROLLBACK_SUFFIX)
    entries = _read_journal(journal) if journal.exists() else None
    if entries is not None:
        if marker.exists():
            _roll_back(entries)
        else:
            try:
                _roll_forward(entries)
            except OSError:  # a target that can no longer be replaced: back to the old set
                _mark_rollback(marker)
                _roll_back(entries)
            _remove_backups(entries)
    _unlink(journal)
    _fsync_folder(_folder(journal))
    _unlink(marker)


def _mark_rollback(marker: Path) -> None:
    """Create the rollback marker (flushed), so that a roll-back killed half-way is finished as one."""
    with contextlib.suppress(OSError):
        os.close(os.open(marker, os.O_WRONLY | os.O_CREAT, 0o644))
        _fsync_folder(_folder(marker))


def _journal_path(folder: Path, key: str) -> Path:
    return folder / f".{key}{JOURNAL_SUFFIX}"


def recover_commits(folder, wait: bool = True) -> list[Path]:
    """Recover every commit a killed writer left half-done in ``folder``; return their journals.

    Each journal is rolled forward (or a killed rollback back) under its set's lock, so a
    live writer's commit is waited for, never touched. Readers call this before they read;
    it does nothing (one ``listdir``) when no journal is there. Errors are left to the
    reader's own checks (a read-only folder cannot be repaired; the hashes still refuse a mix).
    """
    folder = Path(folder) if str(folder) else Path(".")
    try:
        journals = sorted(p for p in folder.iterdir() if p.name.startswith(".") and p.name.endswith(JOURNAL_SUFFIX))
    except OSError:
        return []
    done = []
    for journal in journals:
        key = journal.name[1 : -len(JOURNAL_SUFFIX)]
        try:
            with output_lock(folder, key, None if wait else 0.0):
                if journal.exists():
                    _recover(journal)
                    done.append(journal)
        except (OSError, OutputError):
            continue
    return done


def _backup(path: Path) -> str | None:
    """A hard link to the current ``path`` (None if there is none), kept until the commit is done.

    Linking fails, as the rename would, for an immutable or append-only file or on a
    read-only file system: the commit stops before its first rename.
    """
    if not os.path.lexists(path):
        return None
    backup = tempfile.mktemp(prefix=_temp_prefix(path.name), suffix=TEMP_SUFFIX, dir=_folder(path))
    try:
        os.link(path, backup, follow_symlinks=False)
    except OSError as exc:
        raise OutputError(f"{path.as_posix()}: cannot replace ({exc.strerror}); nothing was replaced") from None
    return backup


def _write_journal(journal: Path, entries: list, primary: Path) -> None:
    data = json.dumps({"version": JOURNAL_VERSION, "pid": os.getpid(), "entries": entries, "complete": True}, indent=1)
    try:
        fd = os.open(journal, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(data + "\n")
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as exc:
        _unlink(journal)
        raise OutputError(f"{primary.as_posix()}: cannot write ({exc.strerror}, writing the commit journal {journal.name}); "
                          "nothing was replaced") from None  # fmt: skip
    _fsync_folder(_folder(journal))


def _commit(journal: Path, entries: list, primary: Path) -> None:
    """Steps 4-5 of the module's commit: journal, renames (rolled back on failure), clean-up."""
    _write_journal(journal, entries, primary)
    done = []
    for entry in entries:
        target = Path(entry["target"])
        _step("rename", target)
        try:
            if entry["new"] is None:
                _unlink(target)
            else:
                os.replace(entry["new"], target)
        except OSError as exc:
            marker = journal.with_name(journal.name[: -len(JOURNAL_SUFFIX)] + ROLLBACK_SUFFIX)
            _mark_rollback(marker)
            _roll_back(entries)
            _unlink(journal)
            _unlink(marker)
            raise OutputError(f"{target.as_posix()}: cannot replace ({exc.strerror}); every output was left as it was") from None
        done.append(entry)
    for folder in dict.fromkeys(_folder(Path(e["target"])) for e in entries):
        _fsync_folder(folder)
    _unlink(journal)
    _fsync_folder(_folder(journal))
    _remove_backups(entries)


def write_files_atomically(contents: dict, primary=None, remove=()) -> None:
    """Write ``{path: bytes}`` and remove the files ``remove`` names as one set: all or nothing.

    The journaled commit of this module's docstring, under the set's lock: temporaries
    written beside their targets and fsynced, every target checked replaceable (a
    hard-linked backup), a journal, the renames (in the order given, the removals after
    them and ``primary`` last), the journal deleted. Any failure, before or
    during the renames, leaves every existing output as it was; a process killed during
    the renames leaves a journal the next writer or reader rolls forward, and ``primary``
    stale until then, so a build rule that targets it runs again.

    Parameters
    ----------
    contents
        ``{path: bytes}``.
    primary
        The path a build rule targets (a key of ``contents``); default: the last key. Its
        folder holds the set's lock and journal.
    remove
        Paths that must not survive the commit (stale siblings); those absent are skipped.

    Raises
    ------
    OutputError
        A folder cannot be created, a temporary cannot be written, a target cannot be
        replaced, or another writer holds the set's lock past the timeout.
    """
    items = [(Path(p), data) for p, data in contents.items()]
    if not items:
        return
    if primary is not None:
        primary = Path(primary)
        if primary not in {p for p, _ in items}:
            raise ValueError(f"primary {primary} is not one of the files written")
        items = [item for item in items if item[0] != primary] + [item for item in items if item[0] == primary]
    primary = items[-1][0]
    written = {os.path.abspath(p) for p, _ in items}
    removals = [Path(p) for p in dict.fromkeys(os.path.abspath(p) for p in remove) if p not in written]
    home = _folder(primary)
    try:
        home.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{home.as_posix()}: cannot write output folder ({exc.strerror})") from None
    key = set_key(primary)
    journal = _journal_path(home, key)
    with output_lock(home, key):
        if journal.exists():
            try:
                _recover(journal)
            except OSError as exc:
                raise OutputError(f"{primary.as_posix()}: cannot finish the commit a killed run left in {journal.name} "
                                  f"({exc.strerror}); expected its outputs to be replaceable") from None  # fmt: skip
        staged: list[tuple[str, Path]] = []
        entries: list[dict[str, str | None]] = []
        committed = False
        try:
            for path, data in items:
                folder = _folder(path)
                _step("write", path)
                try:
                    folder.mkdir(parents=True, exist_ok=True)
                    remove_stale_temporaries(path)
                    fd, tmp = tempfile.mkstemp(prefix=_temp_prefix(path.name), suffix=TEMP_SUFFIX, dir=folder)
                except OSError as exc:
                    raise OutputError(f"{folder.as_posix()}: cannot write output folder ({exc.strerror})") from None
                staged.append((tmp, path))
                try:
                    with os.fdopen(fd, "wb") as fh:
                        fh.write(data)
                        fh.flush()
                        os.fsync(fh.fileno())
                except OSError as exc:
                    raise OutputError(f"{path.as_posix()}: cannot write ({exc.strerror})") from None
                os.chmod(tmp, 0o644)
            # Removals go before the primary, so that a killed commit still leaves the primary stale.
            order: list[tuple[str | None, Path]] = [(tmp, path) for tmp, path in staged[:-1]]
            order += [(None, p) for p in removals if os.path.lexists(p)]
            order += [(tmp, path) for tmp, path in staged[-1:]]
            for new, path in order:
                entry: dict[str, str | None] = {"target": os.path.abspath(path), "new": new and os.path.abspath(new), "old": None}
                entries.append(entry)
                entry["old"] = _backup(path)
            with deferred_interrupts():
                _commit(journal, entries, primary)
            committed = True
        finally:
            # A journal still there means renames began and neither finished nor rolled back: its
            # temporaries and backups are what recovery needs, so they stay.
            if not committed and not journal.exists():
                for tmp, _ in staged:
                    _unlink(tmp)
                _remove_backups(entries)


def write_file_atomically(path, data: bytes) -> None:
    """Atomically replace one file; see :func:`write_files_atomically`."""
    write_files_atomically({path: data})


@contextlib.contextmanager
def staged_folder(folder, primary=None):
    """A fresh temporary folder beside ``folder``, for a writer that is not atomic itself.

    On a clean exit every file written under it replaces its counterpart under
    ``folder`` in one all-or-nothing step (:func:`write_files_atomically`), ``primary``
    (a path relative to ``folder``, the file a build rule targets) renamed last; on an
    exception nothing under ``folder`` changes. The temporary folder is removed either
    way. Files already in ``folder`` that the writer did not produce are left alone.

    Raises
    ------
    OutputError
        The temporary folder (beside ``folder``) or the outputs cannot be written.
    """
    folder = Path(folder)
    parent = folder.parent if str(folder.parent) else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        remove_stale_temporaries(folder)
        staging = Path(tempfile.mkdtemp(prefix=_temp_prefix(folder.name), suffix=TEMP_SUFFIX, dir=parent))
    except OSError as exc:
        raise OutputError(f"{parent.as_posix()}: cannot write output folder ({exc.strerror})") from None
    try:
        yield staging
        files = {folder / p.relative_to(staging): p.read_bytes() for p in sorted(staging.rglob("*")) if p.is_file()}
        target = folder / primary if primary is not None and (folder / primary) in files else None
        write_files_atomically(files, primary=target)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


@contextlib.contextmanager
def scratch_folder(path):
    """A private folder beside ``path``, named as one of its temporaries, removed on exit.

    For encoders that can only write to a file of their own choosing (OpenImageIO picks
    the format from the extension): a run killed inside leaves a folder the next write of
    ``path`` recognises as stale and removes.

    Raises
    ------
    OutputError
        The folder cannot be created.
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        scratch = Path(tempfile.mkdtemp(prefix=_temp_prefix(path.name), suffix=TEMP_SUFFIX, dir=parent))
    except OSError as exc:
        raise OutputError(f"{parent.as_posix()}: cannot write output folder ({exc.strerror})") from None
    try:
        yield scratch
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
