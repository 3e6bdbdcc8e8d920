"""The range window and the spot cone against their closed forms."""

from __future__ import annotations

import doctest
import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.optics import falloff
from atlasgen.optics.falloff import range_window, spot_factor, windowed_irradiance

distances = st.floats(0.0, 1e4, allow_nan=False)
ranges = st.floats(1e-3, 1e3, allow_nan=False)


@given(distances, ranges)
def test_window_is_the_closed_form_inside_and_exactly_zero_at_and_beyond_the_range(d, r):
    w = float(range_window(d, r))
    if d >= r:
        assert w == 0.0
    else:
        assert math.isclose(w, max(1.0 - (d / r) ** 4, 0.0) ** 2, rel_tol=1e-12, abs_tol=1e-300)
    assert float(range_window(r, r)) == 0.0 and float(range_window(r * 1.000001, r)) == 0.0


@given(ranges)
def test_window_falls_smoothly_to_zero(r):
    d = np.linspace(0.0, r, 2001)
    w = range_window(d, r)
    assert w[0] == 1.0 and w[-1] == 0.0 and (np.diff(w) <= 0).all()
    # Zero slope at the range: W ~ 16 (1 - d/r)^2 just inside it.
    eps = 1e-3
    assert math.isclose(float(range_window(r * (1 - eps), r)), (1 - (1 - eps) ** 4) ** 2, rel_tol=1e-9)
    assert float(range_window(r * (1 - eps), r)) < 17 * eps**2


def test_without_a_range_the_falloff_is_inverse_square():
    d = np.array([0.5, 1.0, 2.0, 100.0])
    np.testing.assert_array_equal(windowed_irradiance(3.0, d, math.inf), 3.0 / d**2)
    np.testing.assert_allclose(windowed_irradiance(3.0, d, 1e9), 3.0 / d**2, rtol=1e-12)


@given(st.floats(0.0, 89.0), st.floats(0.5, 60.0), st.floats(0.0, 180.0))
def test_spot_is_one_inside_linear_in_angle_between_and_zero_outside(inner, width, theta):
    outer = min(inner + width, 90.0)
    s = float(spot_factor(math.cos(math.radians(theta)), inner, outer))
    if theta <= inner - 1e-9:
        assert s == 1.0
    elif theta >= outer + 1e-9:
        assert s == 0.0
    else:
        assert math.isclose(s, min(max((outer - theta) / (outer - inner), 0.0), 1.0), abs_tol=1e-6)


def test_doctests():
    assert doctest.testmod(falloff).failed == 0


def test_a_scene_a_millionth_the_size_keeps_its_irradiance():
    """The whole scene scaled by k (distances and ranges times k, intensity times k^2) keeps E: 1/d^2 is floored at
    float32's least normal number only, where a floor of 1e-12 dimmed every light of a scene smaller than 1e-6."""
    d = np.array([0.2, 0.5, 1.0, 1.9])
    for k in (1e-3, 1e-7, 1e-12, 1e-17):
        np.testing.assert_allclose(windowed_irradiance(3.0 * k * k, d * k, 2.0 * k), windowed_irradiance(3.0, d, 2.0),
                                   rtol=1e-12)  # fmt: skip
