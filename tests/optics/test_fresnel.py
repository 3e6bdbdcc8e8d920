"""Fresnel: the exact dielectric reflectance against Fresnel's angle form, limits, TIR, Schlick, F0."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.integrate import quad

from atlasgen.optics.fresnel import fresnel_dielectric, fresnel_schlick, normal_reflectance
from atlasgen.optics.quadrature import hemispherical_average
from tests.fresnel_reference import fresnel_by_angles


@given(theta=st.floats(0.01, np.pi / 2 - 0.01), n=st.floats(1.01, 4.0))
@pytest.mark.slow
def test_exact_fresnel_matches_the_angle_form(theta, n):
    np.testing.assert_allclose(fresnel_dielectric(np.cos(theta), n), fresnel_by_angles(theta, n), rtol=1e-10)


def test_published_values_at_60_degrees():
    # facts.md: n = 1.5 at 60 degrees, Schlick 0.070 vs exact 0.089.
    assert fresnel_schlick(0.5, normal_reflectance(1.5)) == pytest.approx(0.070, abs=5e-4)
    assert fresnel_dielectric(0.5, 1.5) == pytest.approx(0.089, abs=5e-4)


@given(n=st.floats(0.2, 5.0))
def test_normal_incidence_is_the_squared_amplitude_ratio(n):
    expected = ((n - 1) / (n + 1)) ** 2
    assert fresnel_dielectric(1.0, n) == pytest.approx(expected, rel=1e-12, abs=1e-15)
    assert normal_reflectance(n) == pytest.approx(expected, rel=1e-12, abs=1e-15)
    assert fresnel_schlick(1.0, expected) == pytest.approx(expected, rel=1e-12, abs=1e-15)


def test_absorbing_normal_reflectance_is_that_of_the_complex_index():
    # |(1 - N) / (1 + N)|^2 with N = n + ik, e.g. gold near 600 nm (n 0.25, k 3.0) and iron.
    for n, k in ((0.25, 3.0), (2.9, 3.0), (1.5, 0.0)):
        m = complex(n, k)
        assert normal_reflectance(n, k) == pytest.approx(abs((1 - m) / (1 + m)) ** 2, rel=1e-12)


def test_grazing_incidence_reflects_everything():
    for n in (1.01, 1.5, 4.0):
        assert fresnel_dielectric(0.0, n) == pytest.approx(1.0, abs=1e-12)
    assert fresnel_schlick(0.0, 0.04) == 1.0
    # An RGB F0 broadcasts against the cosine's trailing axis.
    np.testing.assert_allclose(fresnel_schlick(np.array([[1.0], [0.0]]), (0.3, 0.5, 0.9)), [[0.3, 0.5, 0.9], [1, 1, 1]])


@given(theta=st.floats(0.01, 1.5), n=st.floats(1.01, 4.0))
@pytest.mark.slow
def test_reflectance_is_the_same_from_either_side(theta, n):
    # Stokes: light at theta_i onto index n reflects as much as light leaving the medium at
    # the refracted angle theta_t, with relative index 1/n.
    cos_t = np.sqrt(1 - np.sin(theta) ** 2 / n**2)
    np.testing.assert_allclose(fresnel_dielectric(cos_t, 1.0 / n), fresnel_dielectric(np.cos(theta), n), rtol=1e-9)


@given(n=st.floats(1.01, 4.0), past=st.floats(1e-6, 1.0))
@pytest.mark.slow
def test_total_internal_reflection_beyond_the_critical_angle(n, past):
    # Leaving a medium of index n: the critical angle has sin = 1/n; beyond it F = 1 exactly.
    critical = np.arcsin(1.0 / n)
    theta = critical + past * (np.pi / 2 - critical)
    assert fresnel_dielectric(np.cos(theta), 1.0 / n) == 1.0


def test_total_internal_reflection_is_continuous_at_the_critical_angle():
    n = 1.5
    critical = np.arcsin(1.0 / n)
    below = fresnel_dielectric(np.cos(critical - 1e-9), 1.0 / n)
    assert below == pytest.approx(1.0, abs=1e-3)
    assert fresnel_dielectric(np.cos(critical - 0.2), 1.0 / n) < below


def test_no_interface_reflects_nothing():
    c = np.linspace(0.01, 1.0, 50)
    np.testing.assert_allclose(fresnel_dielectric(c, 1.0), 0.0, atol=1e-15)
    assert np.isfinite(fresnel_dielectric(0.0, 1.0))


def test_reflectance_falls_monotonically_towards_normal_incidence():
    c = np.linspace(0.0, 1.0, 1001)
    for f in (fresnel_dielectric(c, 1.5), fresnel_schlick(c, normal_reflectance(1.5))):
        assert np.all(np.diff(f) < 0)


def test_hemispherical_average_matches_adaptive_quadrature():
    for n in (1.01, 1.33, 1.5, 2.4, 4.0):
        expected = quad(lambda c: 2 * c * fresnel_by_angles(np.arccos(c), n), 0, 1, epsabs=1e-14, limit=200)[0]
        assert hemispherical_average(lambda c: fresnel_dielectric(c, n)) == pytest.approx(expected, rel=1e-10)
    # n = 1.5: the albedo of a glass surface under uniform light is about 9.2%.
    assert hemispherical_average(lambda c: fresnel_dielectric(c, 1.5)) == pytest.approx(0.0918, abs=5e-4)
