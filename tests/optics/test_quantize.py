"""8-bit encoding: round to nearest, sRGB on RGB only, and the exact inverse for every code."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.optics.quantize import dequantize_rgba, quantize_rgba


def _iec_decode(code):
    # IEC 61966-2-1 eq. 4, written out independently of atlasgen.optics.srgb.
    c = code / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def test_every_8bit_code_round_trips():
    codes = np.arange(256, dtype=np.uint8)
    rgba = np.stack([codes, codes, codes, codes], axis=-1)
    for srgb in (False, True):
        assert np.array_equal(quantize_rgba(dequantize_rgba(rgba, srgb), srgb), rgba)


def test_decoding_is_code_over_255_or_the_srgb_curve_and_alpha_stays_linear():
    codes = np.arange(256, dtype=np.uint8)
    rgba = np.stack([codes, codes, codes, codes], axis=-1)
    linear = dequantize_rgba(rgba, srgb=False)
    np.testing.assert_array_equal(linear, np.broadcast_to((np.arange(256) / 255.0)[:, None], (256, 4)))
    srgb = dequantize_rgba(rgba, srgb=True)
    np.testing.assert_allclose(srgb[:, :3], np.broadcast_to(_iec_decode(np.arange(256.0))[:, None], (256, 3)), rtol=1e-14)
    np.testing.assert_array_equal(srgb[:, 3], linear[:, 3])


@given(code=st.integers(0, 255), offset=st.floats(-0.499, 0.499))
def test_encoding_rounds_to_the_nearest_code(code, offset):
    x = np.clip((code + offset) / 255.0, 0.0, 1.0)
    assert quantize_rgba(np.full(4, x), srgb=False).tolist() == [code] * 4


def test_out_of_range_values_clip_to_the_end_codes():
    got = quantize_rgba(np.array([[-0.5, 1.5, np.inf, -np.inf]]), srgb=True)
    assert got.tolist() == [[0, 255, 255, 0]]


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_rgb_and_rgba_encode_their_colour_alike(dtype):
    rng = np.random.default_rng(3)
    rgba = rng.random((5, 7, 4)).astype(dtype)
    for srgb in (False, True):
        np.testing.assert_array_equal(quantize_rgba(rgba[..., :3], srgb), quantize_rgba(rgba, srgb)[..., :3])
    # sRGB encodes the colour, never alpha: 0.5 is code 128 linear, 188 as sRGB.
    assert quantize_rgba(np.full(4, 0.5, dtype), srgb=True).tolist() == [188, 188, 188, 128]


@pytest.mark.parametrize("peak", [0.0678, 0.9, 1.0, 25.0, 1e-6, 0.1 + 1e-9])
def test_unorm_scale_is_the_smallest_float32_at_or_above_the_peak(peak):
    """The scale maps the peak to at most code 255 in f32 (what the include multiplies by), and no
    float32 below it would: every code is spent on the slice's own range, and nothing clamps."""
    from atlasgen.optics.quantize import unorm_scale

    scale = unorm_scale(peak)
    assert scale == float(np.float32(scale)) and scale >= peak
    assert float(np.nextafter(np.float32(scale), np.float32(0.0))) < peak
    assert quantize_rgba(np.array([peak / scale] * 4), srgb=False)[3] == 255


def test_unorm_scale_of_an_empty_slice_is_one():
    from atlasgen.optics.quantize import unorm_scale

    assert unorm_scale(0.0) == unorm_scale(-1.0) == unorm_scale(float("nan")) == 1.0
