"""Analytic BRDFs: lobe integrals, reciprocity, finite grazing values (their D, G, F terms: tests/optics)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.separable.analytic import blinn_phong_brdf, evaluate_analytic, lambert_brdf, microfacet_brdf, ward_brdf
from tests.separable.separable_helpers import ANALYTIC_DEFAULTS


def _hemisphere_integral(fn, n=4000):
    """Integral over the hemisphere of fn(cos theta) d omega (midpoint rule in cos)."""
    mu = (np.arange(n) + 0.5) / n
    return 2.0 * np.pi * np.sum(fn(mu)) / n


def test_lambert_is_colour_over_pi():
    l = np.array([[0.3, 0.1, 0.9]]) / np.linalg.norm([0.3, 0.1, 0.9])
    v = np.array([[0.0, 0.6, 0.8]])
    np.testing.assert_allclose(lambert_brdf(l, v, (0.2, 0.4, 0.6))[0], np.array([0.2, 0.4, 0.6]) / np.pi)
    assert not lambert_brdf(-l, v).any()


def test_blinn_phong_lobe_integral():
    """With h = n fixed, integral of (m+8)/(8 pi) cos^m cos d omega = (m+8) / (4 (m+2))."""
    m = 40.0
    lobe = lambda mu: (m + 8) / (8 * np.pi) * mu**m * mu  # noqa: E731
    assert _hemisphere_integral(lobe, 100_000) == pytest.approx((m + 8) / (4 * (m + 2)), rel=1e-4)
    # and the function uses that lobe at h = n
    l = v = np.array([[0.0, 0.0, 1.0]])
    assert blinn_phong_brdf(l, v, m)[0, 0] == pytest.approx((m + 8) / (8 * np.pi))


def _unit(rng, k):
    d = rng.normal(size=(k, 3))
    d[:, 2] = np.abs(d[:, 2])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@pytest.mark.parametrize("source", ["ggx", "beckmann", "blinn_phong", "ward", "lambert"])
def test_reciprocity(source):
    rng = np.random.default_rng(1)
    l, v = _unit(rng, 500), _unit(rng, 500)
    params = {**ANALYTIC_DEFAULTS, "source": source, "fresnel": "exact", "diffuse": (0.1, 0.2, 0.3)}
    np.testing.assert_allclose(evaluate_analytic(params, l, v), evaluate_analytic(params, v, l), rtol=1e-10)


@given(
    alpha=st.sampled_from([0.005, 0.05, 0.5, 1.0, 2.0]),
    source=st.sampled_from(["ggx", "beckmann", "ward"]),
    cos_o=st.sampled_from([0.0, 1e-300, 1e-12, 1e-6, 0.01]),
    cos_i=st.floats(0.0, 1.0),
)
@settings(max_examples=150, deadline=None)
@pytest.mark.slow
def test_grazing_values_are_finite(alpha, source, cos_o, cos_i):
    """1 / (4 N.L N.V) blows up at grazing; the BRDFs still return finite values."""
    l = np.array([[np.sqrt(1 - cos_i**2), 0.0, cos_i]])
    v = np.array([[-np.sqrt(1 - cos_o**2), 0.0, cos_o]])
    params = {**ANALYTIC_DEFAULTS, "source": source, "alpha": alpha}
    for a, b in ((l, v), (v, l)):
        f = evaluate_analytic(params, a, b)
        assert np.all(np.isfinite(f)) and np.all(f >= 0)


def test_microfacet_is_zero_below_the_horizon():
    l = np.array([[0.6, 0.0, -0.8]])
    v = np.array([[0.0, 0.6, 0.8]])
    assert not microfacet_brdf(l, v).any()
    assert not ward_brdf(v, l).any()
