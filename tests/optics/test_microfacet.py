"""Microfacet terms: normalisation of D, Smith G1's limits and closed forms, the separable G2."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.integrate import quad

from atlasgen.optics.microfacet import (
    beckmann_distribution,
    ggx_distribution,
    smith_g1_beckmann,
    smith_g1_ggx,
    smith_g1_over_cos_beckmann,
    smith_g1_over_cos_ggx,
    smith_g2_separable_over_cos,
)

DISTRIBUTIONS = {"ggx": ggx_distribution, "beckmann": beckmann_distribution}
G1 = {"ggx": smith_g1_ggx, "beckmann": smith_g1_beckmann}
G1_OVER_COS = {"ggx": smith_g1_over_cos_ggx, "beckmann": smith_g1_over_cos_beckmann}


@pytest.mark.parametrize("alpha", [0.02, 0.1, 0.3, 0.7, 1.0, 2.0])
@pytest.mark.parametrize("name", sorted(DISTRIBUTIONS))
def test_distributions_are_normalised(name, alpha):
    """Projected microfacet area is the macro-surface: int D(h) (n.h) d omega_h = 2 pi int_0^1 D(mu) mu dmu = 1.

    Walter et al. 2007, eq. 4.
    """
    d = DISTRIBUTIONS[name]
    # The lobe's width in mu = cos theta_h is about alpha^2: split there for the adaptive rule.
    breaks = [1.0 - min(0.5, k * alpha * alpha) for k in (1, 4, 16)]
    total = quad(lambda mu: 2 * np.pi * float(d(mu, alpha)) * mu, 0.0, 1.0, points=breaks, epsabs=1e-13, limit=500)[0]
    assert total == pytest.approx(1.0, rel=1e-7)


@given(alpha=st.floats(0.01, 4.0))
def test_peak_is_one_over_pi_alpha_squared_and_nothing_faces_away(alpha):
    for d in DISTRIBUTIONS.values():
        assert d(1.0, alpha) == pytest.approx(1.0 / (np.pi * alpha * alpha), rel=1e-12)
        assert not np.any(d(np.array([0.0, -0.3, -1.0]), alpha))


@given(cos_t=st.floats(1e-3, 1.0), alpha=st.floats(0.01, 4.0))
def test_ggx_g1_is_its_tangent_form(cos_t, alpha):
    # Walter et al. 2007, eq. 34: G1 = 2 / (1 + sqrt(1 + alpha^2 tan^2 theta)).
    tan2 = (1.0 - cos_t * cos_t) / (cos_t * cos_t)
    assert smith_g1_ggx(cos_t, alpha) == pytest.approx(2.0 / (1.0 + math.sqrt(1.0 + alpha * alpha * tan2)), rel=1e-12)


@pytest.mark.parametrize("alpha", [0.05, 0.3, 1.0])
def test_beckmann_g1_fit_follows_the_exact_smith_function(alpha):
    # The exact Smith G1 for Beckmann: 1 / (1 + Lambda), Lambda = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)),
    # a = 1 / (alpha tan theta) (Walter et al. 2007, eq. 27's left side). The rational fit is off by
    # at most 0.0031, just below the switch to 1 at a = 1.6.
    for cos_t in np.linspace(0.02, 0.999, 60):
        a = cos_t / (alpha * math.sqrt(1.0 - cos_t * cos_t))
        exact = 1.0 / (1.0 + 0.5 * (math.erf(a) - 1.0) + math.exp(-a * a) / (2.0 * a * math.sqrt(math.pi)))
        assert smith_g1_beckmann(cos_t, alpha) == pytest.approx(exact, abs=3.2e-3)


@given(alpha=st.floats(0.01, 4.0))
@pytest.mark.slow
def test_g1_is_one_facing_and_zero_at_grazing(alpha):
    for name, g1 in G1.items():
        assert g1(1.0, alpha) == pytest.approx(1.0, rel=1e-12), name
        assert g1(0.0, alpha) == 0.0, name
        assert np.isfinite(G1_OVER_COS[name](0.0, alpha)), name


@given(cos_t=st.floats(0.0, 1.0))
def test_g1_tends_to_one_for_a_smooth_surface(cos_t):
    if cos_t > 1e-3:
        assert smith_g1_ggx(cos_t, 1e-5) == pytest.approx(1.0, rel=1e-4)
        assert smith_g1_beckmann(cos_t, 1e-5) == pytest.approx(1.0, rel=1e-12)


@given(cos_t=st.floats(1e-6, 1.0), alpha=st.floats(0.01, 4.0))
def test_over_cos_forms_are_g1_divided_by_the_cosine(cos_t, alpha):
    for name, g1 in G1.items():
        assert G1_OVER_COS[name](cos_t, alpha) * cos_t == pytest.approx(g1(cos_t, alpha), rel=1e-12), name


@given(cos_i=st.floats(1e-4, 1.0), cos_o=st.floats(1e-4, 1.0), alpha=st.floats(0.01, 4.0))
def test_separable_g2_is_the_product_of_the_g1s(cos_i, cos_o, alpha):
    for name, g1 in G1.items():
        product = g1(cos_i, alpha) * g1(cos_o, alpha) / (cos_i * cos_o)
        assert smith_g2_separable_over_cos(cos_i, cos_o, alpha, name) == pytest.approx(product, rel=1e-12)
    with pytest.raises(ValueError, match="unknown microfacet distribution"):
        smith_g2_separable_over_cos(0.5, 0.5, 0.3, "phong")


@pytest.mark.parametrize("alpha", [0.1, 0.5, 1.0])
@pytest.mark.parametrize("cos_o", [1.0, 0.6, 0.2])
def test_ggx_d_and_g1_project_to_the_visible_area(alpha, cos_o):
    """int G1(o) max(o.h, 0) D(h) d omega_h = cos_o: D and the Smith G1 are consistent (Heitz 2014, eq. 9)."""
    o = np.array([math.sqrt(1.0 - cos_o * cos_o), 0.0, cos_o])
    # Midpoint rule in (mu = cos theta_h, phi); the lobe is resolved with mu spaced as alpha^2 near 1.
    t = (np.arange(4000) + 0.5) / 4000
    mu = 1.0 - t**3  # dense near the peak
    dmu = 3 * t**2 / 4000
    phi = (np.arange(720) + 0.5) / 720 * 2 * np.pi
    s = np.sqrt(1.0 - mu * mu)
    h = np.stack([s[:, None] * np.cos(phi), s[:, None] * np.sin(phi), np.broadcast_to(mu[:, None], (mu.size, phi.size))], -1)
    integrand = np.maximum(h @ o, 0.0) * ggx_distribution(mu, alpha)[:, None]
    total = smith_g1_ggx(cos_o, alpha) * np.sum(integrand * dmu[:, None]) * (2 * np.pi / phi.size)
    assert total == pytest.approx(cos_o, rel=2e-3)
