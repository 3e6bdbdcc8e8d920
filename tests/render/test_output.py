"""Render output: the EXR and its display PNG beside it, and g-buffer layers, read back independently."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.errors import OutputError
from atlasgen.optics.srgb import encode_srgb
from atlasgen.render.output import write_aov, write_render


def read(path):
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(path))
    return buf.get_pixels(oiio.FLOAT if str(path).endswith(".exr") else oiio.UINT8), buf.spec()


def test_the_png_beside_a_render_is_aces_then_srgb(tmp_path):
    values = np.array([[[0.0, 0.18, 1.0], [4.0, 100.0, -1.0]]], dtype=np.float32)
    exr, png = write_render(tmp_path / "a.exr", values, exposure=2.0)
    pixels, _ = read(png)
    x = np.maximum(values.astype(np.float64) * 2.0, 0)
    aces = np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0, 1)
    np.testing.assert_array_equal(pixels, np.rint(encode_srgb(aces) * 255).astype(np.uint8))
    assert pixels[0, 0, 0] == 0 and pixels[0, 1, 1] == 255
    np.testing.assert_array_equal(read(exr)[0], values)


@pytest.mark.parametrize("name, channels", [("normal", 3), ("albedo", 3), ("depth", 1), ("id", 1)])
def test_aov_exr(tmp_path, name, channels):
    value = np.arange(12, dtype=np.float32).reshape(2, 2, 3) if channels == 3 else np.array([[1.0, np.inf], [3.0, 4.0]])
    write_aov(tmp_path / f"{name}.exr", name, value)
    pixels, spec = read(tmp_path / f"{name}.exr")
    assert spec.nchannels == channels
    np.testing.assert_array_equal(pixels.reshape(value.shape), value)


def test_write_render_writes_both_or_neither(tmp_path):
    radiance = np.full((3, 4, 3), 0.5, dtype=np.float32)
    paths = write_render(tmp_path / "out" / "frame.exr", radiance, exposure=1.0)
    assert [p.name for p in paths] == ["frame.exr", "frame.png"]
    np.testing.assert_array_equal(read(paths[0])[0], radiance)
    assert read(paths[1])[0].shape == (3, 4, 3)
    # A folder that cannot be made (a file is in the way): an OutputError, nothing written.
    (tmp_path / "blocker").write_text("")
    with pytest.raises(OutputError):
        write_render(tmp_path / "blocker" / "frame.exr", radiance)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blocker", "out"]


def test_written_radiance_is_finite_and_the_exr_carries_no_time_stamp(tmp_path):
    from atlasgen.render.output import HDR_MAX

    radiance = np.array([[[np.nan, np.inf, -np.inf], [1e30, 2.0, 0.0]]], dtype=np.float32)
    write_render(tmp_path / "a.exr", radiance)
    pixels, spec = read(tmp_path / "a.exr")
    np.testing.assert_array_equal(pixels, [[[0.0, HDR_MAX, -HDR_MAX], [HDR_MAX, 2.0, 0.0]]])
    # OpenImageIO stamps the time unless told not to: the same render would differ by the clock.
    assert spec.getattribute("DateTime") is None and b"DateTime" not in (tmp_path / "a.exr").read_bytes()


def test_the_exr_and_png_are_one_set_committed_by_one_swap(tmp_path, monkeypatch):
    """Both are links into ``.a.atlasgen/current``; the commit is one swap, named by the PNG the
    Makefile's render rule targets."""
    import os

    from atlasgen.io import atomic

    steps = []
    monkeypatch.setattr(atomic, "commit_hook", lambda step, path: steps.append((step, path.name)))
    write_render(tmp_path / "a.exr", np.zeros((2, 2, 3), np.float32))
    assert [step for step in steps if step[0] != "write"] == [("link", "a.exr"), ("link", "a.png"), ("swap", "a.png")]
    assert [os.readlink(tmp_path / name) for name in ("a.exr", "a.png")] == [
        ".a.atlasgen/current/a.exr",
        ".a.atlasgen/current/a.png",
    ]


def _formula_codes(radiance, exposure):
    from atlasgen.optics.display import display_aces
    from atlasgen.optics.quantize import quantize_rgba
    from atlasgen.render.output import finite_radiance

    return quantize_rgba(display_aces(finite_radiance(radiance), exposure), srgb=False)


@pytest.mark.parametrize("exposure", [1.0, 0.35])
def test_display_codes_of_half_float_radiance_are_the_formulas(exposure):
    from atlasgen.render.output import display_codes

    rng = np.random.default_rng(5)
    radiance = (rng.standard_exponential((200, 300, 3)) * rng.choice([1e-3, 0.5, 30.0], (200, 300, 3))).astype(np.float16)
    radiance = radiance.astype(np.float32)  # as the renderer reads its rgba16float target back
    radiance[0, :6, 0] = [np.nan, np.inf, -np.inf, -2.0, 0.0, 65504.0]
    np.testing.assert_array_equal(display_codes(radiance, exposure), _formula_codes(radiance, exposure))


def test_display_codes_of_other_radiance_are_the_formulas_too():
    from atlasgen.render.output import display_codes

    # float32 values between halves, where the nearest half's code differs from the value's own.
    values = np.linspace(0.05, 0.4, 200 * 300 * 3, dtype=np.float32).reshape(200, 300, 3)
    own = _formula_codes(values, 1.0)
    assert (own != _formula_codes(values.astype(np.float16).astype(np.float32), 1.0)).any()
    np.testing.assert_array_equal(display_codes(values, 1.0), own)
    np.testing.assert_array_equal(display_codes(values.astype(np.float64), 1.0), own)
