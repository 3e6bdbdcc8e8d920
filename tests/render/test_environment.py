"""The renderer's environment data kept across processes: what is loaded is what would be built."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.materials.environment import Environment
from atlasgen.optics.sky import SkyParameters
from atlasgen.render.environment import EnvironmentData, cached_environment


@pytest.mark.slow
def test_a_cached_environment_is_the_one_built_and_is_built_again_when_damaged(tmp_path, monkeypatch):
    sky = Environment("sky", intensity=0.6, sky=SkyParameters())
    built = EnvironmentData.of(sky)
    first = cached_environment(sky, tmp_path)
    (entry,) = tmp_path.glob("environment-*.npz")
    monkeypatch.setattr(EnvironmentData, "of", classmethod(lambda cls, env: pytest.fail("built, not loaded")))
    loaded = cached_environment(sky, tmp_path)
    for got in (first, loaded):
        np.testing.assert_array_equal(got.image, built.image)
        np.testing.assert_array_equal(got.sh, built.sh)
        assert len(got.levels) == len(built.levels)
        for a, b in zip(got.levels, built.levels):
            np.testing.assert_array_equal(a, b)
    monkeypatch.undo()
    # Another intensity is another entry; a damaged entry is built again and replaced.
    cached_environment(Environment("sky", intensity=0.7, sky=SkyParameters()), tmp_path)
    assert len(list(tmp_path.glob("environment-*.npz"))) == 2
    entry.write_bytes(b"damaged")
    np.testing.assert_array_equal(cached_environment(sky, tmp_path).sh, built.sh)
    assert entry.read_bytes()[:2] == b"PK"


def test_a_file_environment_is_never_cached(tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(EnvironmentData, "of", classmethod(lambda cls, env: calls.append(env) or "built"))
    env = Environment("file", file=tmp_path / "sky.exr")
    assert cached_environment(env, tmp_path) == cached_environment(env, tmp_path) == "built"
    assert len(calls) == 2 and not list(tmp_path.iterdir())


def _rewritten(arrays: dict) -> bytes:
    import io

    out = io.BytesIO()
    np.savez(out, **arrays)
    return out.getvalue()


def _huge_header(entry) -> bytes:
    """The entry with its image's .npy header declaring a (100000, 100000, 3) image (112 GiB)."""
    import io
    import zipfile

    out = io.BytesIO()
    with zipfile.ZipFile(entry) as source, zipfile.ZipFile(out, "w") as target:
        for info in source.infolist():
            data = source.read(info)
            if info.filename == "image.npy":
                header = np.lib.format.header_data_from_array_1_0(np.zeros((1, 1, 3), np.float32))
                body = io.BytesIO()
                np.lib.format.write_array_header_1_0(body, {**header, "shape": (100000, 100000, 3)})
                data = body.getvalue() + data[-64:]
            target.writestr(info, data)
    return out.getvalue()


def _forged(arrays: dict, image=None, sh=None, levels=None) -> bytes:
    """The entry's arrays changed and given a digest of their own, as a hand-made entry would be."""
    from atlasgen.render.environment import _environment_digest

    count = int(arrays["count"])
    image = arrays["image"] if image is None else image
    sh = arrays["sh"] if sh is None else sh
    levels = [arrays[f"level_{k}"] for k in range(count)] if levels is None else levels
    digest = _environment_digest(EnvironmentData(image, sh, levels))
    return _rewritten({"image": image, "sh": sh, "count": np.array(len(levels)), "digest": np.array(digest),
                       **{f"level_{k}": v for k, v in enumerate(levels)}})  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("damage", ["truncated", "empty", "fifo", "huge header", "count -3", "nan", "one texel",
                                    "forged ten levels", "forged harmonics", "forged nan"])  # fmt: skip
def test_a_damaged_environment_entry_is_built_again_not_loaded(tmp_path, damage):
    """Hostile sweeps': a truncated or empty entry and a huge header ended in an internal error, a pipe in the
    entry's place hung preview, and NaN images, an image of one texel or a level count of -3 loaded as the sky; so
    did entries forged with a digest of their own."""
    import os

    sky = Environment("sky", intensity=0.6, sky=SkyParameters())
    built = cached_environment(sky, tmp_path)
    (entry,) = tmp_path.glob("environment-*.npz")
    good = entry.read_bytes()
    with np.load(entry) as z:
        arrays = dict(z)
    damaged = {"truncated": lambda: good[:5000], "empty": lambda: b"", "huge header": lambda: _huge_header(entry),
               "count -3": lambda: _rewritten({**arrays, "count": np.array(-3)}),
               "nan": lambda: _rewritten({**arrays, "image": np.full_like(arrays["image"], np.nan)}),
               "one texel": lambda: _rewritten({**arrays, "image": np.zeros((1, 1, 1)), "sh": np.zeros(1)}),
               # A digest of their own: ten levels failed the texture's creation, other harmonics their packing (internal
               # errors), and NaN drew the ball black.
               "forged ten levels": lambda: _forged(arrays, levels=[arrays["level_0"]] * 10),
               "forged harmonics": lambda: _forged(arrays, sh=np.zeros((2, 2))),
               "forged nan": lambda: _forged(arrays, image=arrays["image"] * np.nan)}  # fmt: skip
    data = None if damage == "fifo" else damaged[damage]()
    entry.unlink()
    if data is None:
        os.mkfifo(entry)
    else:
        entry.write_bytes(data)
    again = cached_environment(sky, tmp_path)
    np.testing.assert_array_equal(again.image, built.image)
    np.testing.assert_array_equal(again.sh, built.sh)
    assert entry.is_file() and entry.read_bytes() == good  # replaced by the entry built again
