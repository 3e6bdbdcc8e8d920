"""The renderer's specular lobe in NumPy: its roughness mapping, its directional albedo and
energy, the cosine A's Fresnel is taken at, and the shading equation."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.contract import SPECULAR_ALPHA_MIN, SPECULAR_LOBE
from atlasgen.optics.microfacet import ggx_distribution
from atlasgen.optics.specular import half_vector_cosine, renderer_f_cos, specular_alpha, specular_f_cos, specular_fresnel_cosine

#: Glosses of the albedo tests, and what specular_alpha gives them: alpha 1, 0.49, 0.25, 0.09, 0.01, the floor.
GLOSSES = (0.0, 0.3, 0.5, 0.7, 0.9, 1.0)


def test_roughness_is_one_minus_gloss_squared_with_a_floor():
    np.testing.assert_allclose(specular_alpha([0.0, 0.5, 0.8, 1.0, 1.5, -1.0]), [1.0, 0.25, 0.04, SPECULAR_ALPHA_MIN, SPECULAR_ALPHA_MIN, 1.0],
                               rtol=1e-12)  # fmt: skip
    assert str(SPECULAR_ALPHA_MIN) in SPECULAR_LOBE["roughness"]


def _view(cos_v):
    return np.array([np.sqrt(1.0 - cos_v * cos_v), 0.0, cos_v])


def _albedo_over_light(gloss, cos_v, n=800):
    """int f_s cos d omega_l by the midpoint rule over the light's (theta, phi): brute force."""
    t = (np.arange(n) + 0.5) * (0.5 * np.pi / n)
    p = (np.arange(2 * n) + 0.5) * (np.pi / n)
    tt, pp = np.meshgrid(t, p, indexing="ij")
    l = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1)
    h = l + _view(cos_v)
    nh = h[..., 2] / np.linalg.norm(h, axis=-1)
    f = specular_f_cos(gloss, l[..., 2], cos_v, nh)
    return (f * np.sin(tt)).sum() * (0.5 * np.pi / n) * (np.pi / n)


def _albedo_over_normals(gloss, cos_v, n=600):
    """The same integral over microfacet normals h, stratified in D(h) cos theta_h (exact for any alpha).

    l = reflect(v, h), d omega_l = 4 (v.h) d omega_h (Walter et al. 2007, eq. 14), and
    cos^2 theta_h = (1 - xi) / (xi (alpha^2 - 1) + 1) maps xi uniform to D cos theta_h
    (eq. 35): int f_s cos d omega_l = E[f_s cos 4 (v.h) / (D cos theta_h)].
    """
    alpha = float(specular_alpha(gloss))
    xi = (np.arange(n) + 0.5) / n
    phi = (np.arange(2 * n) + 0.5) * (np.pi / n)
    xx, pp = np.meshgrid(xi, phi, indexing="ij")
    c = np.sqrt((1.0 - xx) / (xx * (alpha * alpha - 1.0) + 1.0))
    s = np.sqrt(1.0 - c * c)
    h = np.stack([s * np.cos(pp), s * np.sin(pp), c], -1)
    v = _view(cos_v)
    vh = h @ v
    l = 2.0 * vh[..., None] * h - v
    f = specular_f_cos(gloss, l[..., 2], cos_v, c)
    weight = np.where(vh > 0.0, 4.0 * vh / (ggx_distribution(c, alpha) * c), 0.0)
    return (f * weight).mean()


def _albedo_from_lambda(gloss, cos_v, n=600):
    """The albedo from the textbook G2 = 1 / (1 + Lambda(v) + Lambda(l)), Lambda = (sqrt(1 + alpha^2 tan^2) - 1) / 2
    (Heitz 2014, eqs. 72 and 99): f_s cos 4 (v.h) / (D cos theta_h) = G2 (v.h) / (N.V cos theta_h),
    written without the library's V."""
    alpha = float(specular_alpha(gloss))
    xi = (np.arange(n) + 0.5) / n
    phi = (np.arange(2 * n) + 0.5) * (np.pi / n)
    xx, pp = np.meshgrid(xi, phi, indexing="ij")
    c = np.sqrt((1.0 - xx) / (xx * (alpha * alpha - 1.0) + 1.0))
    s = np.sqrt(1.0 - c * c)
    h = np.stack([s * np.cos(pp), s * np.sin(pp), c], -1)
    v = _view(cos_v)
    vh = h @ v
    nl = 2.0 * vh * c - cos_v

    def lam(mu):
        mu = np.clip(mu, 1e-12, 1.0)
        return 0.5 * (np.sqrt(1.0 + alpha * alpha * (1.0 - mu * mu) / (mu * mu)) - 1.0)

    g2 = 1.0 / (1.0 + lam(cos_v) + lam(nl))
    return np.where((vh > 0) & (nl > 0), g2 * vh / (cos_v * c), 0.0).mean()


@pytest.mark.parametrize("gloss", [0.0, 0.3, 0.5])
@pytest.mark.parametrize("cos_v", [1.0, 0.7, 0.3])
@pytest.mark.slow
def test_directional_albedo_agrees_with_brute_force_integration_over_the_light(gloss, cos_v):
    """Rough enough for the midpoint rule over l to resolve the lobe (alpha >= 0.25)."""
    assert _albedo_over_light(gloss, cos_v) == pytest.approx(_albedo_over_normals(gloss, cos_v), rel=2e-3)


@pytest.mark.parametrize("gloss", GLOSSES)
@pytest.mark.parametrize("cos_v", [1.0, 0.8, 0.5, 0.2, 0.05])
@pytest.mark.slow
def test_directional_albedo_agrees_with_the_textbook_masking_function(gloss, cos_v):
    assert _albedo_over_normals(gloss, cos_v) == pytest.approx(_albedo_from_lambda(gloss, cos_v), rel=1e-9)


@pytest.mark.parametrize("gloss", GLOSSES)
@pytest.mark.slow
def test_white_furnace_the_lobe_never_creates_energy(gloss):
    """int D V N.L d omega <= 1 for every roughness and view, with two closed forms: a near-mirror
    keeps everything at normal view, and at alpha = 1 (D = 1 / pi, V = 0.5 / (N.L + 1) at
    v = n) the albedo at normal view is 2 int_0^1 mu / (1 + mu) / 2 dmu = 1 - ln 2."""
    albedos = np.array([_albedo_over_normals(gloss, c) for c in (1.0, 0.8, 0.5, 0.2, 0.05, 0.01)])
    assert np.all(albedos <= 1.0 + 1e-9), albedos
    assert np.all(albedos > 0.0)
    alpha = float(specular_alpha(gloss))
    if alpha <= 0.01:
        assert albedos[0] == pytest.approx(1.0, abs=1e-3)  # a near-mirror reflects everything at normal view
    if alpha == 1.0:
        assert albedos[0] == pytest.approx(1.0 - np.log(2.0), rel=1e-5)


@given(cos_l=st.floats(0.0, 1.0), cos_v=st.floats(0.0, 1.0))
def test_fresnel_cosine_is_l_dot_h_where_the_lobe_peaks(cos_l, cos_v):
    """With l and v opposite in azimuth, h is nearest N; the cosine is L.H there, symmetric in l and v."""
    l = np.array([-np.sqrt(1.0 - cos_l * cos_l), 0.0, cos_l])
    v = np.array([np.sqrt(1.0 - cos_v * cos_v), 0.0, cos_v])
    h = l + v
    norm = np.linalg.norm(h)
    if norm > 1e-6:
        assert float(specular_fresnel_cosine(cos_l, cos_v)) == pytest.approx(float(l @ h / norm), abs=1e-9)
    assert float(specular_fresnel_cosine(cos_l, cos_v)) == pytest.approx(float(specular_fresnel_cosine(cos_v, cos_l)), abs=1e-15)
    assert float(specular_fresnel_cosine(cos_v, cos_v)) == pytest.approx(cos_v, abs=1e-9)  # the mirror: N.V


def test_renderer_equation_splits_into_diffuse_over_pi_and_the_scaled_lobe():
    nl = np.array([-0.5, 0.3, 0.8, 0.8, 0.6])
    nv = np.array([0.7, 0.6, 0.9, 0.9, 0.0])
    nh = np.array([0.9, 0.95, 0.99, 0.99, 0.8])
    rgba = np.array([[0.2, 0.4, 0.6, 0.5]] * 5)
    degenerate = np.array([False, False, False, True, False])
    got = renderer_f_cos(rgba, (1.0, 0.5, 0.25), 0.4, nl, nv, nh, degenerate)
    a2 = 0.6**4  # alpha = (1 - 0.4)^2
    d = a2 / (np.pi * (nh * nh * (a2 - 1.0) + 1.0) ** 2)
    lit = np.maximum(nl, 0.0)
    vis = 0.5 / (lit * np.sqrt(nv * nv * (1 - a2) + a2) + nv * np.sqrt(lit * lit * (1 - a2) + a2))
    lobe = np.where((nl > 0) & ~degenerate, d * vis * lit, 0.0)
    expected = np.array([0.2, 0.2, 0.15]) / np.pi + 0.5 * lobe[:, None]
    np.testing.assert_allclose(got, expected, rtol=1e-13)
    assert np.all(got[0] == np.array([0.2, 0.2, 0.15]) / np.pi)  # no lobe below the horizon
    assert np.isfinite(got[4]).all() and got[4, 0] > got[0, 0]  # finite at N.V = 0 (V = 0.5 / (N.L alpha))


def test_the_lobe_is_zero_where_both_cosines_are_zero_without_a_warning():
    """N.L = N.V = 0 makes V infinite, times N.L = 0: the lobe is 0 there, as in the shader, and the
    masked 0 * inf is no RuntimeWarning for a caller of the library (the CLI hides warnings; a script
    does not)."""
    import warnings

    nl = np.array([0.0, 0.0, -0.2])
    nv = np.array([0.0, 0.5, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = specular_f_cos(0.5, nl, nv, np.array([0.7, 0.7, 0.7]))
    assert got.tolist() == [0.0, 0.0, 0.0]


def test_half_vector_cosine_closed_forms():
    """N.H = cos of the half angle: l at 60 degrees and v at 0 in one plane give cos 30 degrees;
    l = v gives N.L; l = -v has no half vector (0, flagged); a per-pair normal is honoured."""
    l = np.array([[np.sin(np.pi / 3), 0.0, np.cos(np.pi / 3)], [0.6, 0.0, 0.8], [0.6, 0.0, 0.8]])
    v = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [-0.6, 0.0, -0.8]])
    nh, degenerate = half_vector_cosine(l, v)
    np.testing.assert_allclose(nh, [np.cos(np.pi / 6), 0.8, 0.0], atol=1e-12)
    assert degenerate.tolist() == [False, False, True]
    n = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(half_vector_cosine(l, v, n)[0], [np.cos(np.pi / 6), 0.6, 0.0], atol=1e-12)
