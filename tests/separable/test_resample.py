"""Carrying factors between sampling grids: interpolation up, least squares down."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.optics.interpolation import interpolate_1d
from atlasgen.separable.factorize import Factors
from atlasgen.separable.resample import interpolation_matrix, resample_factors, resampling_matrix

grids = st.integers(min_value=2, max_value=80)


@given(grids)
def test_the_same_grid_is_the_identity(n):
    np.testing.assert_allclose(interpolation_matrix(n, n), np.eye(n), atol=1e-12)


@given(grids, grids)
def test_interpolation_is_the_gpu_filter_at_the_target_texels(source, target):
    table = np.random.default_rng(source * 100 + target).normal(size=source)
    x = np.arange(target) * (source - 1) / (target - 1)  # the target texels in source texel units
    np.testing.assert_allclose(interpolation_matrix(source, target) @ table, interpolate_1d(table, x), atol=1e-12)


@settings(deadline=None)  # the first call of a pair computes a pseudo-inverse: no timed assertions
@pytest.mark.slow
@given(grids, grids, st.floats(-3, 3), st.floats(-3, 3))
def test_a_linear_ramp_survives_any_resampling(source, target, a, b):
    ramp = a + b * np.linspace(0.0, 1.0, source)
    np.testing.assert_allclose(resampling_matrix(source, target) @ ramp, a + b * np.linspace(0.0, 1.0, target), atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(st.integers(min_value=33, max_value=96))
def test_downsampling_recovers_a_stored_factor_exactly(fine):
    # A factor that is already a linear reconstruction of 32 texels is fitted with no loss.
    stored = np.random.default_rng(fine).normal(size=32)
    on_fine = interpolation_matrix(32, fine) @ stored
    np.testing.assert_allclose(resampling_matrix(fine, 32) @ on_fine, stored, atol=1e-9)


def test_least_squares_beats_point_sampling_for_a_sharp_peak():
    fine = 48
    t = np.linspace(0.0, 1.0, fine)
    peak = np.exp(-(((t - 0.503) / 0.02) ** 2))
    back = interpolation_matrix(32, fine)
    fitted = back @ (resampling_matrix(fine, 32) @ peak)
    pointwise = back @ np.interp(np.linspace(0.0, 1.0, 32), t, peak)
    assert np.linalg.norm(fitted - peak) < 0.9 * np.linalg.norm(pointwise - peak)


def test_factors_are_resampled_along_every_axis():
    rng = np.random.default_rng(3)
    f = Factors(rng.normal(size=(2, 3, 16)), rng.normal(size=(2, 3, 16, 16)), "half_diff", np.ones((3, 2)), "f_proxy")
    out = resample_factors(f, 32)
    r = interpolation_matrix(16, 32)
    assert out.g.shape == (2, 3, 32) and out.h.shape == (2, 3, 32, 32)
    np.testing.assert_allclose(out.g[1, 2], r @ f.g[1, 2])
    np.testing.assert_allclose(out.h[0, 1], r @ f.h[0, 1] @ r.T)
    assert (out.parametrization, out.target) == ("half_diff", "f_proxy")
    assert resample_factors(f, 16) is f


def test_a_grid_needs_two_samples():
    with pytest.raises(ValueError, match="at least 2"):
        interpolation_matrix(1, 32)
