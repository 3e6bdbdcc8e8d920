"""Storage: the slice layout, per-factor scale and bias, and 8-bit round trips."""

import numpy as np
import pytest

from atlasgen.separable.approximate import approximate_brdf
from atlasgen.separable.factorize import Factors
from atlasgen.separable.rebuild import factors_from_slices
from atlasgen.separable.storage import encode_factor_slices, factors_to_slices, quantize_factors
from tests.separable.separable_helpers import analytic


def _factors(k=3, seed=0):
    rng = np.random.default_rng(seed)
    g = rng.normal(size=(k, 3, 32))
    h = rng.normal(size=(k, 3, 32, 32))
    g[0] = np.abs(g[0])
    h[0] = np.abs(h[0])
    return Factors(g, h, "half_diff", np.zeros((3, k)))


def test_layout_g_left_in_every_row_h_right_alpha_zero():
    f = _factors()
    s = factors_to_slices(f)
    assert s.shape == (3, 32, 64, 4)
    for k in range(3):
        for row in (0, 13, 31):
            np.testing.assert_array_equal(s[k, row, :32, :3], f.g[k].T)
        np.testing.assert_array_equal(s[k, :, 32:, :3], f.h[k].transpose(1, 2, 0))
    assert not s[..., 3].any()


def test_encoding_round_trips_and_uses_bias_only_for_signed_factors():
    f = _factors()
    values = factors_to_slices(f)
    stored, scale, bias, clamped = encode_factor_slices(values)
    assert stored.min() >= 0.0 and stored.max() <= 1.0 and clamped == 0.0
    assert np.all(bias[0] == 0.0)  # the non-negative first term keeps the full range
    assert np.all(bias[1:] < 0.0)
    back = factors_from_slices(stored, scale, bias, "half_diff")
    np.testing.assert_allclose(back.g, f.g, atol=1e-6 * np.abs(f.g).max())
    np.testing.assert_allclose(back.h, f.h, atol=1e-6 * np.abs(f.h).max())
    # Each (term, factor, channel) spans exactly [0, 1].
    half = [stored[:, :, :32, :3], stored[:, :, 32:, :3]]
    for factor in range(2):
        np.testing.assert_allclose(half[factor].max(axis=(1, 2)), 1.0, atol=1e-6)
        np.testing.assert_allclose(half[factor].min(axis=(1, 2))[1:], 0.0, atol=1e-6)


def test_zero_factors_give_a_zero_slice():
    f = Factors(np.zeros((2, 3, 32)), np.zeros((2, 3, 32, 32)), "half_diff", np.zeros((3, 2)))
    stored, scale, bias, clamped = encode_factor_slices(factors_to_slices(f))
    assert not stored.any() and np.all(scale == 1.0) and not bias.any() and clamped == 0.0


@pytest.mark.parametrize("srgb", [False, True])
def test_8bit_error_is_bounded_by_half_a_step(srgb):
    f = _factors()
    q = quantize_factors(f, srgb=srgb)
    _, scale, _, _ = encode_factor_slices(factors_to_slices(f))
    # Linear: half a code of the factor's span. sRGB: the coarsest step near 1 is
    # 1 - decode(254/255) ~ 0.0087 of the span.
    step = 0.5 / 255 if not srgb else 0.0045
    assert np.all(np.abs(q.g - f.g) <= step * scale[:, 0, :, None] + 1e-9)
    assert np.all(np.abs(q.h - f.h) <= step * scale[:, 1, :, None, None] + 1e-9)


@pytest.mark.slow
def test_8bit_adds_little_error_for_a_glossy_brdf():
    result = approximate_brdf(analytic("ggx", alpha=0.2), terms=4, target="f_cos")
    float_err = result.errors_by_terms["f_cos"][3]["relative_rms"]
    stored_err = result.errors_8bit_by_terms["f_cos"][3]["relative_rms"]
    assert float_err <= stored_err + 1e-3 and stored_err - float_err < 0.01
