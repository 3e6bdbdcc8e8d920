"""Reading a ``.npz`` archive that atlasgen wrote (a cache entry), refusing a damaged or hand-made one before
NumPy allocates what its headers declare.

``numpy.load`` trusts each ``.npy`` header: a header edited to declare a (100000, 100000, 3) image asked for
112 GiB, a truncated archive raised ``zipfile.BadZipFile`` (no ``ValueError``), and a named pipe in the
entry's place blocked the reader for ever. Here every member's header is read first and its data must be
there in full, within a bound on the whole.
"""

from __future__ import annotations

import math
import zipfile
import zlib
from pathlib import Path

import numpy as np

__all__ = ["read_npy_header", "read_npz_arrays"]

#: The .npy header readers by format version (NumPy writes 1.0, or 2.0 for a header over 64 kB).
_NPY_HEADERS = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}


def read_npy_header(member) -> tuple:
    """``(shape, fortran_order, dtype)`` of the ``.npy`` array that the open file ``member`` starts with, its data
    unread; ValueError for an unknown format version or a malformed header."""
    read_header = _NPY_HEADERS.get(np.lib.format.read_magic(member))
    if read_header is None:
        raise ValueError("an unknown .npy format version")
    return read_header(member)


def read_npz_arrays(path, max_bytes: int) -> dict[str, np.ndarray]:
    """Every array of the archive ``path`` by name (the member's name without ``.npy``).

    Raises
    ------
    ValueError
        Not a regular file, not a zip archive, a member that is no ``.npy`` array of plain values, data
        shorter than its header declares, or arrays of more than ``max_bytes`` in all.
    OSError
        The file cannot be read.
    """
    path = Path(path)
    if not path.is_file():  # a pipe would block the reader; a folder is no archive
        raise ValueError("not a regular file")
    arrays, total = {}, 0
    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                if not info.filename.endswith(".npy"):
                    raise ValueError(f"a member {info.filename!r} that is no .npy array")
                with archive.open(info) as member:
                    shape, fortran, dtype = read_npy_header(member)
                    if dtype.hasobject:
                        raise ValueError("an array of Python objects")
                    size = math.prod(shape) * dtype.itemsize
                    total += size
                    if total > max_bytes:
                        raise ValueError(f"arrays of more than {max_bytes} bytes")
                    data = member.read(size)
                if len(data) != size:
                    raise ValueError(f"{info.filename}: {len(data)} bytes of the {size} its header declares")
                array = np.frombuffer(data, dtype=dtype).reshape(shape, order="F" if fortran else "C")
                arrays[info.filename[: -len(".npy")]] = array.copy()
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, zlib.error, NotImplementedError) as exc:
        raise ValueError(f"not a readable .npz archive ({exc})") from None
    return arrays
