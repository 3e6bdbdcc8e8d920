"""The reference cache on disk: an entry is used only where it holds a render of the size asked for, as stored."""

from __future__ import annotations

import json

import numpy as np
import pytest

from atlasgen.io.digest import array_digest
from atlasgen.validate.reference_cache import ReferenceCache

KEY = "ab" * 32
SIZE = (6, 8)


def _render(second=True, mask=True) -> dict:
    rng = np.random.default_rng(1)
    image = rng.uniform(0.0, 1.0, size=(*SIZE, 3)).astype(np.float32)
    return {"kind": "physical", "description": "Mitsuba diffuse", "image": image, "seconds": 0.25, "spp": 16,
            "variant": "llvm_ad_rgb", "second_image": (image * np.float32(0.9)) if second else None,
            "mask": np.eye(*SIZE, dtype=bool) if mask else None, "masked": "cast shadows" if mask else None}  # fmt: skip


def _stored(tmp_path, fields=None):
    ReferenceCache(tmp_path).put(KEY, fields or _render())
    return tmp_path / f"{KEY}.npz"


def _rewrite(path, arrays=None, record=None):
    """Rewrite an entry's arrays (``{name: array or None}``, None removes one) and record fields (``{key: value}``,
    a value of ``...`` removes the key), leaving the rest as stored."""
    with np.load(path) as data:
        stored = dict(data)
    rec = json.loads(str(stored.pop("record")))
    for k, v in (arrays or {}).items():
        if v is None:
            stored.pop(k, None)
        else:
            stored[k] = v
    for k, v in (record or {}).items():
        if v is ...:
            rec.pop(k, None)
        else:
            rec[k] = v
    np.savez(path, record=np.array(json.dumps(rec)), **stored)


def test_a_stored_render_is_read_back_as_it_was_and_its_record_holds_the_digests(tmp_path):
    path = _stored(tmp_path)
    with np.load(path) as data:
        record = json.loads(str(data["record"]))
        assert record["digests"] == {k: array_digest(data[k]) for k in ("image", "second_image", "mask")}
    cache = ReferenceCache(tmp_path)
    assert cache.get("cd" * 32, SIZE) is None and cache.rejected == []  # no such entry: a quiet miss
    got = cache.get(KEY, SIZE)
    want = _render()
    assert got is not None and cache.rejected == [] and cache.loaded == 1
    assert set(got) == set(want) and "digests" not in got
    for k, v in want.items():
        assert np.array_equal(got[k], v) if isinstance(v, np.ndarray) else got[k] == v
    bare = _render(second=False, mask=False)
    ReferenceCache(tmp_path / "bare").put(KEY, bare)
    assert ReferenceCache(tmp_path / "bare").get(KEY, SIZE)["second_image"] is None


def _nan_image(image):
    image = image.copy()
    image[2, 3, 1] = np.nan
    return image


@pytest.mark.parametrize(
    "arrays, record, why",
    [
        ({"image": lambda a: np.full_like(a, np.nan)}, {}, "image has 144 values that are not finite"),
        ({"image": _nan_image}, {}, "image has 1 values that are not finite"),
        ({"second_image": lambda a: np.full_like(a, np.inf)}, {}, "second_image has 144 values that are not finite"),
        ({"image": lambda a: np.ones((3, 3, 3), np.float32)}, {}, "image is float32 3x3x3; expected float32 6x8x3"),
        ({"image": lambda a: a.astype(np.float64)}, {}, "image is float64 6x8x3; expected float32 6x8x3"),
        ({"image": lambda a: a[..., 0]}, {}, "image is float32 6x8; expected float32 6x8x3"),
        ({"mask": lambda a: a.astype(np.uint8)}, {}, "mask is uint8 6x8; expected bool 6x8"),
        ({"image": lambda a: a * np.float32(0.5)}, {}, "image does not match its record's digest (changed since it was stored)"),
        ({"mask": lambda a: ~a}, {}, "mask does not match its record's digest (changed since it was stored)"),
        ({"second_image": lambda a: None}, {}, "its arrays are not the ones its record's digests name"),
        ({"image": lambda a: None}, {}, "no image"),
        ({}, {"digests": ...}, "its record has no digests of its images (an entry of another atlasgen)"),
        ({}, {"spp": "16"}, "its record's 'spp' is str; expected int"),
        ({}, {"spp": True}, "its record's 'spp' is bool; expected int"),
        ({}, {"spp": 0}, "its record's sample count or seconds are not a render's"),
        ({}, {"seconds": -1.0}, "its record's sample count or seconds are not a render's"),
        (
            {},
            {"extra": 1},
            "its record has fields ['description', 'extra', 'kind', 'masked', 'seconds', 'spp', 'variant']; "
            "expected ['description', 'kind', 'masked', 'seconds', 'spp', 'variant']",
        ),
        ({}, {"key": "cd" * 32}, "its record is not this entry's (another key)"),
    ],
)
def test_an_entry_that_is_not_a_render_of_the_size_asked_for_is_a_miss_and_said(tmp_path, arrays, record, why):
    path = _stored(tmp_path)
    with np.load(path) as data:
        stored = dict(data)
    _rewrite(path, {k: f(stored[k]) for k, f in arrays.items()}, record)
    cache = ReferenceCache(tmp_path)
    assert cache.get(KEY, SIZE) is None
    assert cache.rejected == [f"{path.as_posix()}: {why}; rendered again"]
    assert cache.hits == 0 and cache.loaded == 0
    # The render made again replaces the entry, and is found next time.
    cache.put(KEY, _render())
    again = ReferenceCache(tmp_path)
    assert again.get(KEY, SIZE) is not None and again.rejected == []


def test_an_entry_of_another_frame_size_is_a_miss(tmp_path):
    _stored(tmp_path)
    cache = ReferenceCache(tmp_path)
    assert cache.get(KEY, (8, 6)) is None
    assert cache.rejected == [f"{(tmp_path / f'{KEY}.npz').as_posix()}: image is float32 6x8x3; expected float32 8x6x3; "
                              "rendered again"]  # fmt: skip


@pytest.mark.parametrize("content", [b"", b"PK\x03\x04garbage", b"not a zip at all"])
def test_an_unreadable_entry_is_a_miss_and_said(tmp_path, content):
    path = _stored(tmp_path)
    path.write_bytes(content)
    cache = ReferenceCache(tmp_path)
    assert cache.get(KEY, SIZE) is None
    assert len(cache.rejected) == 1 and cache.rejected[0].startswith(f"{path.as_posix()}: unreadable (")
    assert cache.rejected[0].endswith("); rendered again")


def test_a_record_time_beyond_a_double_is_a_miss_and_said(tmp_path):
    """A hostile sweep's: seconds = 10**400 (valid JSON, no float) failed math.isfinite: an internal error, exit 1,
    on every later run until the entry was removed by hand."""
    path = _stored(tmp_path)
    _rewrite(path, record={"seconds": 10**400})
    cache = ReferenceCache(tmp_path)
    assert cache.get(KEY, SIZE) is None
    assert cache.rejected == [f"{path.as_posix()}: its record's sample count or seconds are not a render's; rendered again"]


def test_an_entry_inflating_beyond_a_render_of_its_size_is_a_miss_read_from_its_headers(tmp_path):
    """A hostile sweep's: a 0.78 MB compressed entry inflated to 805 MB in np.load before its shape was checked."""
    path = _stored(tmp_path)
    with np.load(path) as data:
        stored = dict(data)
    np.savez_compressed(path, **{**stored, "image": np.zeros((1024, 1024, 3), np.float32)})  # 12.6 MB inflated
    assert path.stat().st_size < 100_000
    cache = ReferenceCache(tmp_path)
    assert cache.get(KEY, SIZE) is None
    assert len(cache.rejected) == 1 and cache.rejected[0].startswith(f"{path.as_posix()}: unreadable (arrays of more than ")
