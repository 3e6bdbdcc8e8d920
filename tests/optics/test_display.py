"""Display transforms: Narkowicz's ACES fit and the plain clip, both ending in the sRGB curve."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.optics.display import display_aces, display_clip


def _oetf(x):
    # IEC 61966-2-1 eq. 5, written out independently of atlasgen.optics.srgb.
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def test_aces_is_narkowicz_then_srgb():
    values = np.array([[[0.0, 0.18, 1.0], [4.0, 100.0, -1.0]]])
    x = np.maximum(values * 2.0, 0)
    aces = np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0, 1)
    np.testing.assert_allclose(display_aces(values, exposure=2.0), _oetf(aces), atol=1e-12)
    # Narkowicz's curve: black stays black, 0.18 grey at exposure 1 maps to about 0.267 before sRGB.
    assert display_aces(0.0) == 0.0
    assert display_aces(100.0) == pytest.approx(1.0, abs=1e-15)
    assert _oetf(0.2670) == pytest.approx(display_aces(0.18), abs=1e-3)


def test_aces_is_monotone_and_never_nan():
    ramp = display_aces(np.linspace(0, 50, 2000))
    assert np.all(np.diff(ramp) >= 0)
    np.testing.assert_allclose(display_aces(np.array([np.nan, np.inf, -np.inf])), [0.0, 1.0, 0.0], atol=1e-15)


def test_clip_is_the_srgb_oetf_of_the_clipped_exposed_value():
    linear = np.array([0.0, 0.001, 0.0031308, 0.18, 0.5, 1.0, 4.0, np.nan])
    got = display_clip(linear, exposure=2.0)
    x = np.clip(np.nan_to_num(linear * 2.0), 0.0, 1.0)
    np.testing.assert_allclose(got, _oetf(x), atol=1e-12)
    np.testing.assert_allclose(display_clip(np.array([np.inf, -np.inf])), [1.0, 0.0], atol=1e-15)


@given(x=st.floats(0.0, 0.99), exposure=st.floats(0.1, 1.0))
def test_clip_keeps_what_a_display_can_show_and_aces_compresses_it(x, exposure):
    # Below white the clip transform is the sRGB curve alone; ACES darkens highlights relative to it.
    assert display_clip(x, exposure) == pytest.approx(_oetf(x * exposure), abs=1e-12)
    if x * exposure > 0.9:
        assert display_aces(x, exposure) < display_clip(x, exposure)
