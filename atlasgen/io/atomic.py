"""All-or-nothing file output: write beside the target, then rename over it.

A set of files cannot be replaced in one atomic step, so the commit is ordered for the
build system: every temporary is written and flushed to disk first, then the side files
are renamed into place, and the *primary* file (the one a ``make`` rule names as its
target: the DDS of a bake) last. A run killed anywhere leaves the primary file stale
(older than its prerequisites, or missing), so ``make`` runs the command again, and the
re-run replaces every file.

Temporaries are named ``.<name>.<pid>.<random>.atlasgen.tmp`` beside their target. A run
killed before its renames leaves them behind; the next write of the same target removes
those whose process is gone (never those of a live process: it may be a parallel job).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import tempfile
from pathlib import Path

from atlasgen.errors import OutputError

__all__ = [
    "write_files_atomically",
    "write_file_atomically",
    "staged_folder",
    "scratch_folder",
    "remove_stale_temporaries",
    "TEMP_SUFFIX",
]

#: Every temporary file or folder this module creates ends with this.
TEMP_SUFFIX = ".atlasgen.tmp"

#: Test hook: when set, called as ``hook(step, path)`` before each step of a commit,
#: ``step`` being ``"write"`` (a temporary for ``path``) or ``"rename"`` (onto ``path``).
#: Tests set it to kill the process at every step in turn; it is None otherwise.
commit_hook = None


def _step(step: str, path: Path) -> None:
    if commit_hook is not None:
        commit_hook(step, path)


def _temp_prefix(name: str) -> str:
    return f".{name}.{os.getpid()}."


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
    folder = path.parent if str(path.parent) else Path(".")
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


def write_files_atomically(contents: dict, primary=None) -> None:
    """Write ``{path: bytes}`` so that either every file is replaced or none is.

    Each file is first written to a temporary file in its own folder (so the final
    ``os.replace`` is an atomic rename on the same file system) and flushed to disk.
    Only when all temporaries are complete are they renamed: the others in the order
    given, ``primary`` last. Any failure before the renames removes the temporaries and
    leaves the existing outputs untouched; a process killed during the renames leaves
    ``primary`` as it was, so a build rule that targets it runs again.

    Parameters
    ----------
    contents
        ``{path: bytes}``.
    primary
        The path a build rule targets (a key of ``contents``); default: the last key.

    Raises
    ------
    OutputError
        A folder cannot be created or a temporary cannot be written.
    """
    items = [(Path(p), data) for p, data in contents.items()]
    if not items:
        return
    if primary is not None:
        primary = Path(primary)
        if primary not in {p for p, _ in items}:
            raise ValueError(f"primary {primary} is not one of the files written")
        items = [item for item in items if item[0] != primary] + [item for item in items if item[0] == primary]
    staged: list[tuple[str, Path]] = []
    try:
        for path, data in items:
            folder = path.parent if str(path.parent) else Path(".")
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
        for tmp, path in list(staged):
            _step("rename", path)
            try:
                os.replace(tmp, path)
            except OSError as exc:
                raise OutputError(f"{path.as_posix()}: cannot replace ({exc.strerror})") from None
            staged.remove((tmp, path))
        for folder in dict.fromkeys(path.parent for path, _ in items):
            _fsync_folder(folder if str(folder) else Path("."))
    finally:
        for tmp, _ in staged:
            try:
                os.unlink(tmp)
            except OSError:
                pass


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
