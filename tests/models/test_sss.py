"""Pre-integrated skin: Penner's ring integral against adaptive quadrature, and its limits."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from atlasgen.contract import texel_grid
from atlasgen.errors import MaterialError
from atlasgen.io.fields import validate_params
from atlasgen.models import get_model
from atlasgen.models.sss import SKIN_VARIANCES, SKIN_WEIGHTS, preintegrate_ring

MODEL = get_model("sss")
DEFAULTS = validate_params(MODEL.params, {}, "test")


def ring_integral_by_quad(theta, radius, variances, weights, channel):
    """D(theta, r) straight from Penner's definition, with scipy's adaptive quadrature."""
    v = np.asarray(variances)
    w = np.asarray(weights)[:, channel]

    def profile(d):
        return np.sum(w * np.exp(-d * d / (2 * v)) / (2 * np.pi * v))

    kinks = [x for x in (np.pi / 2 - theta, -np.pi / 2 - theta, 1.5 * np.pi - theta, 0.0) if -np.pi < x < np.pi]

    def lit(x):
        return max(np.cos(theta + x), 0.0) * profile(2 * radius * np.sin(x / 2))

    def weight(x):
        return profile(2 * radius * np.sin(x / 2))

    numerator = quad(lit, -np.pi, np.pi, points=kinks, limit=400, epsabs=1e-13)[0]
    denominator = quad(weight, -np.pi, np.pi, points=[0.0], limit=400, epsabs=1e-13)[0]
    return numerator / denominator


@pytest.mark.parametrize("radius", [0.05, 0.5, 3.0, 10.0, 40.0])
@pytest.mark.parametrize("theta", [0.0, 0.6, 1.45, 1.6, 1.75, 2.4, 3.1])
def test_matches_adaptive_quadrature_of_the_definition(theta, radius):
    got = preintegrate_ring(np.cos(theta), radius)
    expected = [ring_integral_by_quad(theta, radius, SKIN_VARIANCES, SKIN_WEIGHTS, c) for c in range(3)]
    np.testing.assert_allclose(got, expected, rtol=1e-4, atol=1e-7)


def test_large_radius_tends_to_clamped_cosine():
    cos_theta = np.linspace(-1.0, 1.0, 201)
    d = preintegrate_ring(cos_theta, 1.0e4)
    np.testing.assert_allclose(d, np.repeat(np.maximum(cos_theta, 0.0)[:, None], 3, axis=1), atol=1e-4)


def test_small_radius_tends_to_one_over_pi_everywhere():
    # facts.md's limit holds for the full-ring integral (x over [-pi, pi]): the profile is
    # flat over the ring, so D is the mean of cos+ over a circle, 2 / (2 pi), at every theta.
    cos_theta = np.linspace(-1.0, 1.0, 201)
    far = np.abs(preintegrate_ring(cos_theta, 1e-2) - 1 / np.pi).max()
    near = np.abs(preintegrate_ring(cos_theta, 1e-3) - 1 / np.pi).max()
    assert near < 1e-4
    # ... and it converges like r^2 (the kernel's width in kappa = r^2 / v).
    assert far / near == pytest.approx(100.0, rel=0.05)


@pytest.mark.parametrize("radius", [0.2, 2.0, 20.0])
def test_ring_convolution_preserves_the_integral(radius):
    # D is a normalised convolution of cos+ on the circle and even in theta, so
    # int_0^pi D dtheta = (1/2) int_-pi^pi cos+ = 1, whatever the radius.
    theta = np.linspace(0.0, np.pi, 4001)
    d = preintegrate_ring(np.cos(theta), radius)
    integral = np.sum((d[1:] + d[:-1]) * 0.5 * np.diff(theta)[:, None], axis=0)
    np.testing.assert_allclose(integral, 1.0, atol=2e-6)


def test_red_light_wraps_furthest_past_the_terminator():
    d = preintegrate_ring(np.cos(np.radians(100.0)), 10.0)
    assert d[0] > 10 * d[1] > 10 * d[2] > 0.0


def test_custom_single_gaussian_profile():
    weights = [(1.0, 0.5, 0.25)]  # channels differ only in scale, which D normalises away
    d = preintegrate_ring(np.cos([0.3, 1.7]), 1.5, [0.5], weights)
    assert np.ptp(d, axis=1).max() < 1e-15
    expected = [ring_integral_by_quad(t, 1.5, [0.5], weights, 0) for t in (0.3, 1.7)]
    np.testing.assert_allclose(d[:, 0], expected, rtol=1e-6)


def test_model_is_tinted_falloff_with_constant_alpha():
    nl, nv = texel_grid()
    params = {**DEFAULTS, "colour": (0.9, 0.7, 0.6), "specular": 0.4, "radius": 5.0}
    out = MODEL.evaluate(params, nl, nv)
    np.testing.assert_allclose(out[..., :3], preintegrate_ring(nl, 5.0) * (0.9, 0.7, 0.6), rtol=1e-15)
    assert (out[..., 3] == 0.4).all()


def test_profile_cross_checks():
    with pytest.raises(MaterialError, match="field 'weights': expected one RGB weight per variance \\(6\\), got 2"):
        MODEL.check({**DEFAULTS, "weights": ((1, 1, 1), (1, 1, 1))}, "skin.toml")
    with pytest.raises(MaterialError, match="field 'weights': expected a positive total weight in every channel, B sums to 0"):
        MODEL.check({**DEFAULTS, "variances": (1.0,), "weights": ((1.0, 1.0, 0.0),)}, "skin.toml")


@st.composite
def params_strategy(draw):
    count = draw(st.integers(1, 6))
    weights = draw(st.lists(st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3), min_size=count, max_size=count))
    weights[0] = [max(c, 0.01) for c in weights[0]]  # every channel needs some weight
    return {
        "colour": draw(st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3)),
        "radius": draw(st.floats(0.01, 10000.0)),
        "variances": draw(st.lists(st.floats(1e-4, 1e4), min_size=count, max_size=count)),
        "weights": weights,
        "specular": draw(st.floats(0.0, 16.0)),
    }


@given(raw=params_strategy())
@settings(max_examples=50, deadline=None)
@pytest.mark.slow
def test_random_valid_parameters_give_finite_non_negative_slices(raw, valid_slice):
    params = validate_params(MODEL.params, raw, "hypothesis")
    MODEL.check(params, "hypothesis")
    values = valid_slice(MODEL, params)
    # A normalised average of cos+ never exceeds 1.
    assert values[..., :3].max() <= 1.0 + 1e-12


@pytest.mark.parametrize(
    "body, field, expected",
    [
        ("radius = 0", "radius", "expected a finite number >= 0.01 and <= 10000, got 0"),
        ("radius = nan", "radius", "got nan"),
        ("variances = [0.1, -1.0]", "variances[1]", "> 0"),
        ("variances = [0.1]", "weights", "expected one RGB weight per variance (1), got 6"),
        ("weights = [[1, 1, 1], [2, 0, 0]]", "weights[1]", "in [0, 1]"),
        ("radious = 3", "radious", "did you mean 'radius'?"),
    ],
)
def test_bad_parameters_are_rejected(expect_rejected, body, field, expected):
    expect_rejected("sss", body, field, expected)
