"""The renderer's specular lobe in NumPy: its exponent, its Beckmann twin, and the shading equation."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.optics.microfacet import beckmann_distribution
from atlasgen.optics.specular import (
    blinn_phong_alpha,
    renderer_f_cos,
    specular_exponent,
    specular_f_cos,
    specular_normalisation,
)


def test_exponent_spans_2_to_8192_log_uniformly():
    np.testing.assert_allclose(specular_exponent([0.0, 0.5, 1.0]), [2.0, 128.0, 8192.0], rtol=1e-15)


@given(st.floats(0.0, 0.9))
def test_blinn_phong_alpha_gives_beckmann_the_normalised_blinn_phong_peak(gloss):
    """Walter et al. 2007, section 5.2: D_Blinn = (s + 2) / (2 pi) cos^s matches Beckmann with
    alpha^2 = 2 / (s + 2); at the peak (cos = 1) both equal (s + 2) / (2 pi) exactly."""
    s = float(specular_exponent(gloss))
    alpha = blinn_phong_alpha(gloss)
    assert beckmann_distribution(1.0, alpha) == pytest.approx((s + 2.0) / (2.0 * np.pi), rel=1e-12)


def test_the_lobe_integrates_to_one_at_normal_view():
    n = 600
    t = (np.arange(n) + 0.5) * (0.5 * np.pi / n)
    w = 2.0 * np.pi * np.sin(t) * (0.5 * np.pi / n)  # the lobe is symmetric about v = n
    for gloss in (0.0, 0.25, 0.5):
        f = specular_f_cos(gloss, np.cos(t), np.cos(0.5 * t))  # with v = n, h lies halfway to l
        assert (f * w).sum() == pytest.approx(1.0, rel=2e-3)
    assert specular_normalisation(2.0) < 10 / (8 * np.pi)  # the (s + 8) / (8 pi) rule overshoots


def test_renderer_equation_splits_into_diffuse_over_pi_and_the_scaled_lobe():
    nl = np.array([-0.5, 0.3, 0.8, 0.8])
    nh = np.array([0.9, 0.95, 0.99, 0.99])
    rgba = np.array([[0.2, 0.4, 0.6, 0.5]] * 4)
    degenerate = np.array([False, False, False, True])
    got = renderer_f_cos(rgba, (1.0, 0.5, 0.25), 0.4, nl, nh, degenerate)
    s = float(specular_exponent(0.4))
    lobe = specular_normalisation(s) * nh**s * np.maximum(nl, 0.0) * (nl > 0) * ~degenerate
    expected = np.array([0.2, 0.2, 0.15]) / np.pi + 0.5 * lobe[:, None]
    np.testing.assert_allclose(got, expected, rtol=1e-13)
    assert np.all(got[0] == np.array([0.2, 0.2, 0.15]) / np.pi)  # no lobe below the horizon
