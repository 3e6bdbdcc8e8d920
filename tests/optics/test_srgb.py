"""The sRGB transfer function."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.optics.srgb import SRGB_DECODE_LUT, decode_srgb, encode_srgb


def test_known_points():
    # IEC 61966-2-1: the linear segment ends at 0.0031308 -> 0.04045; mid grey 0.5 -> 0.21404.
    assert encode_srgb(0.0031308) == np.float64(12.92 * 0.0031308)
    assert abs(decode_srgb(0.5) - 0.214041140) < 1e-9
    assert abs(encode_srgb(1.0) - 1.0) < 1e-15 and encode_srgb(0.0) == 0.0


@given(st.floats(0.0, 1.0))
def test_float_round_trip(x):
    assert abs(decode_srgb(encode_srgb(x)) - x) < 1e-12


def test_the_decode_table_is_the_decode_of_every_code():
    assert np.allclose(SRGB_DECODE_LUT, decode_srgb(np.arange(256) / 255))
