"""All-or-nothing file output: write beside the target, then rename over it."""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

from atlasgen.errors import OutputError

__all__ = ["write_files_atomically", "write_file_atomically", "staged_folder"]


def write_files_atomically(contents: dict) -> None:
    """Write ``{path: bytes}`` so that either every file is replaced or none is.

    Each file is first written to a temporary file in its own folder (so the final
    ``os.replace`` is an atomic rename on the same file system). Only when all
    temporaries are complete are they renamed; any failure before that removes
    them and leaves the existing outputs untouched.
    """
    staged: list[tuple[str, Path]] = []
    try:
        for path, data in contents.items():
            path = Path(path)
            folder = path.parent if str(path.parent) else Path(".")
            try:
                folder.mkdir(parents=True, exist_ok=True)
                fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
            except OSError as exc:
                raise OutputError(f"{folder.as_posix()}: cannot write output folder ({exc.strerror})") from None
            staged.append((tmp, path))
            try:
                with os.fdopen(fd, "wb") as fh:
                    fh.write(data)
            except OSError as exc:
                raise OutputError(f"{path.as_posix()}: cannot write ({exc.strerror})") from None
            os.chmod(tmp, 0o644)
        for tmp, path in staged:
            os.replace(tmp, path)
        staged.clear()
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
def staged_folder(folder):
    """A fresh temporary folder beside ``folder``, for a writer that is not atomic itself.

    On a clean exit every file written under it replaces its counterpart under
    ``folder`` in one all-or-nothing step (:func:`write_files_atomically`); on an
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
        staging = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".tmp", dir=parent))
    except OSError as exc:
        raise OutputError(f"{parent.as_posix()}: cannot write output folder ({exc.strerror})") from None
    try:
        yield staging
        files = {folder / p.relative_to(staging): p.read_bytes() for p in sorted(staging.rglob("*")) if p.is_file()}
        write_files_atomically(files)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
