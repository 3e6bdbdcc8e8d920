"""Real spherical harmonics: orthonormality, the textbook polynomials, projection round trips,
Funk-Hecke's zonal coefficients against closed forms, and the figures behind SH_ORDER."""

import doctest
import re

import numpy as np
import pytest

from atlasgen.optics import spherical_harmonics
from atlasgen.optics.equirect import texel_directions
from atlasgen.optics.spherical_harmonics import (
    SH_ORDER,
    evaluate_sh,
    project_directions,
    project_equirect,
    sh_basis,
    sh_count,
    zonal_coefficients,
)

RNG = np.random.default_rng(11)


def _sphere_rule(n=24):
    """Gauss-Legendre in z times 2n equally spaced azimuths: exact for polynomials of degree < 2n on the sphere."""
    z, wz = np.polynomial.legendre.leggauss(n)
    phi = (np.arange(2 * n) + 0.5) * np.pi / n
    s = np.sqrt(1.0 - z * z)
    d = np.stack(np.broadcast_arrays(s[:, None] * np.cos(phi), s[:, None] * np.sin(phi), z[:, None]), -1).reshape(-1, 3)
    return d, (wz[:, None] * np.full(2 * n, np.pi / n)).ravel()


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_the_basis_is_orthonormal():
    d, w = _sphere_rule(16)
    for order in (2, SH_ORDER, 6):
        y = sh_basis(d, order)
        np.testing.assert_allclose(y.T @ (w[:, None] * y), np.eye(sh_count(order)), atol=1e-13)


def test_the_basis_is_ramamoorthi_and_hanrahans():
    # Ramamoorthi & Hanrahan 2001, eq. 12 (no Condon-Shortley phase), index l*l + l + m.
    x, y, z = _unit(RNG.normal(size=(50, 3))).T
    expected = np.stack([np.full_like(x, 0.282095), 0.488603 * y, 0.488603 * z, 0.488603 * x, 1.092548 * x * y,
                         1.092548 * y * z, 0.315392 * (3 * z * z - 1), 1.092548 * x * z, 0.546274 * (x * x - y * y)], -1)  # fmt: skip
    np.testing.assert_allclose(sh_basis(np.stack([x, y, z], -1), 2), expected, atol=2e-6)


def test_projection_then_evaluation_round_trips_a_band_limited_function():
    coefficients = RNG.normal(size=(sh_count(SH_ORDER), 3))
    d, w = _sphere_rule()
    np.testing.assert_allclose(project_directions(evaluate_sh(coefficients, d), d, w), coefficients, atol=1e-12)


def test_projecting_an_image_integrates_its_bilinear_reconstruction():
    constant = project_equirect(np.full((16, 32, 3), [1.0, 2.0, 0.5]))
    np.testing.assert_allclose(constant[0], np.sqrt(4 * np.pi) * np.array([1.0, 2.0, 0.5]), rtol=1e-9)
    assert np.abs(constant[1:]).max() < 1e-9 * constant[0].min()


@pytest.mark.slow
def test_the_projection_rule_has_converged():
    for h in (16, 32):
        img = RNG.random((h, 2 * h, 3))
        np.testing.assert_allclose(project_equirect(img), project_equirect(img, nodes=8), atol=1e-9 * np.sqrt(4 * np.pi))


@pytest.mark.slow
def test_a_band_limited_image_comes_back_to_second_order():
    # A band-limited function sampled into an image comes back up to the bilinear interpolation error, O(1/H^2).
    coefficients = RNG.normal(size=(sh_count(SH_ORDER), 3))
    errors = [
        np.abs(project_equirect(evaluate_sh(coefficients, texel_directions(h, 2 * h))) - coefficients).max() for h in (16, 32, 64)
    ]
    assert errors[2] < 0.02 and 3.6 < errors[0] / errors[1] < 4.4 and 3.6 < errors[1] / errors[2] < 4.4, errors


def test_clamped_cosine_zonal_coefficients_are_the_closed_forms():
    lam = zonal_coefficients(lambda mu: np.maximum(mu, 0.0), 6, breakpoints=(-1.0, 0.0, 1.0))
    np.testing.assert_allclose(lam, np.pi * np.array([1.0, 2.0 / 3.0, 0.25, 0.0, -1.0 / 24.0, 0.0, 1.0 / 64.0]), atol=1e-14)


def test_funk_hecke_convolution_matches_direct_integration():
    coefficients = RNG.normal(size=(sh_count(SH_ORDER), 2))
    d, w = _sphere_rule(40)
    radiance = evaluate_sh(coefficients, d)
    kernel = lambda mu: np.exp(1.5 * mu) * (0.3 + mu * mu)  # smooth: the sphere rule integrates it exactly enough
    lam = zonal_coefficients(lambda mu: np.stack([kernel(mu), 2.0 * kernel(mu)], -1), SH_ORDER)
    normals = _unit(RNG.normal(size=(7, 3)))
    direct = np.stack([(w[:, None] * kernel(d @ n)[:, None] * radiance * [1.0, 2.0]).sum(0) for n in normals])
    np.testing.assert_allclose(evaluate_sh(coefficients, normals, zonal=lam), direct, rtol=1e-10)


def test_the_docstrings_figures_for_the_order_are_measured():
    doc = " ".join(spherical_harmonics.__doc__.split())
    lam = zonal_coefficients(lambda mu: np.maximum(mu, 0.0), 6, breakpoints=(-1.0, 0.0, 1.0))
    mu = np.linspace(-1.0, 1.0, 20001)
    exact = np.maximum(mu, 0.0)
    # A sun s of irradiance E: E sum_l lambda_l (2l + 1) / (4 pi) P_l(n.s), against E max(n.s, 0).
    series = [lam[l] * (2 * l + 1) / (4 * np.pi) * np.polynomial.legendre.legval(mu, [0] * l + [1]) for l in range(5)]
    worst = {o: np.abs(exact - sum(series[: o + 1])).max() for o in (2, 4)}
    rms = {o: np.sqrt(np.trapezoid((exact - sum(series[: o + 1])) ** 2, mu) / np.trapezoid(exact**2, mu)) for o in (2, 4)}
    figures = [100 * lam[6] / lam[0], 100 * -lam[4] / lam[0], 100 * worst[4], 100 * worst[2], 100 * rms[4], 100 * rms[2]]
    stated = [float(f) for f in re.findall(r"([\d.]+)%", doc)[:6]]
    np.testing.assert_allclose(stated, np.round(figures, 1))


@pytest.mark.parametrize("bad", [(-1.0, 0.5, 0.2), (0.5,), (-2.0, 1.0), (1.0, -1.0)])
def test_zonal_coefficients_refuse_bad_breakpoints(bad):
    with pytest.raises(ValueError, match="breakpoints"):
        zonal_coefficients(np.ones_like, 2, breakpoints=bad)


def test_the_docstrings_examples_hold():
    from atlasgen.optics import spherical_harmonics

    assert doctest.testmod(spherical_harmonics).failed == 0
