"""Reading atlasgen's own .npz archives: every array back as written, anything else a ValueError before allocation."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

from atlasgen.io.npz import read_npz_arrays


def _archive(path, **arrays):
    np.savez(path, **arrays)
    return path


def test_the_arrays_come_back_as_written(tmp_path):
    written = {"image": np.arange(24, dtype=np.float32).reshape(2, 4, 3), "count": np.array(3), "digest": np.array("ab"),
               "fortran": np.asfortranarray(np.arange(6.0).reshape(2, 3))}  # fmt: skip
    got = read_npz_arrays(_archive(tmp_path / "a.npz", **written), 1 << 20)
    assert sorted(got) == sorted(written)
    for name, array in written.items():
        np.testing.assert_array_equal(got[name], array)
        assert got[name].dtype == array.dtype and got[name].shape == array.shape


def _with_member(path, name: str, data: bytes):
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr(name, data)
    return path


def _written(path, data: bytes):
    path.write_bytes(data)
    return path


def _npy(array, shape=None) -> bytes:
    out = io.BytesIO()
    header = np.lib.format.header_data_from_array_1_0(array)
    np.lib.format.write_array_header_1_0(out, {**header, "shape": shape or array.shape})
    return out.getvalue() + array.tobytes()


@pytest.mark.parametrize(("make", "expected"), [
    (lambda p: _written(p, b""), "not a readable .npz archive"),
    (lambda p: _written(p, _archive(p, a=np.zeros(100)).read_bytes()[:300]), "not a readable .npz archive"),
    (lambda p: _with_member(p, "a.npy", _npy(np.zeros(3), (100000, 100000, 3))), "arrays of more than 4096 bytes"),
    (lambda p: _with_member(p, "a.npy", _npy(np.zeros(3), (4,))), "a.npy: 24 bytes of the 32 its header declares"),
    (lambda p: _with_member(p, "a.txt", b"text"), "a member 'a.txt' that is no .npy array"),
    (lambda p: _archive(p, a=np.array([{"x": 1}], dtype=object)), "an array of Python objects"),
    (lambda p: p.mkdir() or p, "not a regular file"),
])  # fmt: skip
def test_a_damaged_or_foreign_archive_is_a_value_error(tmp_path, make, expected):
    path = make(tmp_path / "a.npz")
    with pytest.raises(ValueError, match=expected):
        read_npz_arrays(path, 4096)
