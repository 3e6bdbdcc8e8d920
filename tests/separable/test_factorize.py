"""Factorization: SVD against numpy's full SVD, rank-1 cases, monotone error, signs, NMF and ND."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.separable.approximate import approximate_brdf
from atlasgen.separable.factorize import (
    factorize,
    factorize_nd,
    factorize_nmf,
    factorize_svd,
    fix_signs,
    matrix_errors,
)
from atlasgen.separable.parametrization import get_parametrization
from atlasgen.separable.source import BrdfSource, sample_matrix
from tests.separable.separable_helpers import analytic


def _setup(source, name="half_diff", n=32, target="f_cos"):
    p = get_parametrization(name)
    m, _ = sample_matrix(source, p, n, target)
    w1, w2 = p.quadrature_weights(n)
    return p, m, w1, w2


@pytest.mark.slow
def test_svd_matches_numpy_full_svd():
    """Independent computation: the rank-K sum equals the truncated numpy SVD of the weighted matrix."""
    p, m, w1, w2 = _setup(analytic("ggx", alpha=0.3, f0=(0.9, 0.6, 0.2)))
    f = factorize_svd(m, w1, w2, 4, p.name)
    r1, r2 = np.sqrt(w1), np.sqrt(w2)
    for c in range(3):
        a = m[c] * r1[:, None] * r2[None, :]
        u, s, vt = np.linalg.svd(a, full_matrices=False)
        expect = (u[:, :4] * s[:4]) @ vt[:4] / r1[:, None] / r2[None, :]
        got = np.einsum("ki,kj->ij", f.g[:, c], f.h[:, c].reshape(4, -1))
        np.testing.assert_allclose(got, expect, atol=1e-9 * np.abs(expect).max())
        np.testing.assert_allclose(f.singular_values[c], s[:4], rtol=1e-9)


@pytest.mark.slow
def test_lambert_is_rank_one():
    """f cos of Lambert is colour/pi * cos(theta_l): one term reproduces it exactly."""
    colour = (0.8, 0.5, 0.2)
    src = analytic("lambert", diffuse=colour)
    # In/out with texels uniform in cos(theta_l): cos(theta_l) is linear in the texel
    # coordinate, so even the interpolated rebuild is exact at random (l, v) pairs.
    result = approximate_brdf(src, "in_out", terms=1, target="f_cos")
    assert result.errors["relative_rms"] < 1e-6
    assert result.matrix_errors_by_terms["f_cos"][0] < 1e-6
    # Half/difference: f times the proxy cos(theta_d) is a function of pi2 alone.
    result = approximate_brdf(src, "half_diff", terms=1, target="f_proxy")
    assert result.matrix_errors_by_terms["f_proxy"][0] < 1e-6


def _product_source(name, use_y=True):
    """f * proxy = g(pi1) h(pi2), g and h linear in the texel coordinates (so interpolation is exact too).

    (The proxy, cos(theta_d) or cos(theta_l), is a function of pi2 alone, so f itself is a
    product g(pi1) * (h / proxy)(pi2).)
    """
    p = get_parametrization(name)

    def f(l, v):
        n = np.broadcast_to(np.array([0.0, 0.0, 1.0]), np.shape(l))
        x1, x2, y2, _ = p.coordinates(n, l, v, 32)
        g = 1.0 + 0.5 * x1 / 31
        h = 0.2 + 0.3 * x2 / 31 + (0.7 * y2 / 31 if use_y else 0.0)
        return (g * h / p.proxy_at(n, l, v))[..., None] * np.array([1.0, 0.5, 0.25])

    return BrdfSource("product", evaluate_f=f)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["in_out", "half_diff"])
def test_product_form_is_recovered_at_rank_one(name):
    # h varies along pi2's first axis only: the grid continues texels below the horizon
    # with the nearest valid azimuth, and at a zero polar angle the azimuth is
    # undefined, so a product in the azimuth would not stay one there (a BRDF's does).
    # The full 2D product is test_two_dimensional_product_on_the_half_diff_grid_is_rank_one.
    src = _product_source(name, use_y=False)
    result = approximate_brdf(src, name, terms=3, target="f_proxy")
    # The rebuilt BRDF at 1e5 random (l, v) pairs: the product, to rounding.
    assert result.errors_by_terms["f_proxy"][0]["relative_rms"] < 1e-6
    # On the grid, two texels (theta_h = 0 or 90 deg with theta_d = 90 deg) are l = -v on
    # the horizon, where the half vector and so the test's own coordinates are
    # undefined; the rebuild never reads them. Everything else is rank 1.
    assert result.matrix_errors_by_terms["f_proxy"][0] < 1e-4
    sv = result.factors.singular_values
    assert np.all(sv[:, 1] < 1e-4 * sv[:, 0])
    g = result.factors.g[0, 0]
    np.testing.assert_allclose(g / g[0], 1.0 + 0.5 * np.arange(32) / 31, rtol=1e-5)


def test_two_dimensional_product_on_the_half_diff_grid_is_rank_one():
    p = get_parametrization("half_diff")
    a1, (ax, ay) = p.grid(32)
    g = 1.0 + np.cos(a1)
    h = np.outer(1.0 + np.sin(ay), 0.5 + ax).ravel()
    m = np.stack([np.outer(g, h) * c for c in (1.0, 0.3, 0.1)])
    w1, w2 = p.quadrature_weights(32)
    f = factorize_svd(m, w1, w2, 2, p.name)
    assert matrix_errors(m, w1, w2, f)[0] < 1e-12
    np.testing.assert_allclose(f.g[0, 0] / f.g[0, 0, 0], g / g[0], rtol=1e-10)
    np.testing.assert_allclose(f.h[0, 1].ravel() / f.h[0, 1].ravel()[0], h / h[0], rtol=1e-10)


@pytest.mark.slow
@given(
    alpha=st.floats(0.03, 1.0),
    f0=st.floats(0.02, 1.0),
    source=st.sampled_from(["ggx", "beckmann", "ward", "blinn_phong"]),
    name=st.sampled_from(["half_diff", "in_out"]),
    target=st.sampled_from(["f_cos", "f_proxy"]),
)
@settings(max_examples=25, deadline=None)
def test_error_never_grows_with_terms(alpha, f0, source, name, target):
    """Eckart-Young: the weighted grid residual of K SVD terms is non-increasing in K."""
    src = analytic(source, alpha=alpha, f0=(f0, f0, f0), exponent=2.0 / alpha**2)
    p, m, w1, w2 = _setup(src, name, target=target)
    errors = matrix_errors(m, w1, w2, factorize_svd(m, w1, w2, 8, name))
    assert all(b <= a + 1e-12 for a, b in zip(errors, errors[1:])), errors
    assert errors[0] <= 1.0 + 1e-12


@pytest.mark.slow
def test_reported_error_by_terms_is_monotone_for_the_goal_materials():
    """The interpolated error at random pairs follows the grid residual; it may only wiggle by interpolation noise."""
    for alpha in (0.05, 0.2, 0.5):
        result = approximate_brdf(analytic("ggx", alpha=alpha), terms=8)
        for target, errs in result.errors_by_terms.items():
            rel = [e["relative_rms"] for e in errs]
            assert all(b <= a + 5e-4 for a, b in zip(rel, rel[1:])), (alpha, target, rel)


def test_sign_convention_is_deterministic():
    rng = np.random.default_rng(0)
    u, _, vt = np.linalg.svd(rng.normal(size=(6, 9)), full_matrices=False)
    a_u, a_vt = fix_signs(u, vt)
    signs = np.where(rng.random(6) < 0.5, -1.0, 1.0)
    b_u, b_vt = fix_signs(u * signs, vt * signs[:, None])
    np.testing.assert_array_equal(a_u, b_u)
    np.testing.assert_array_equal(a_vt, b_vt)
    pivot = np.argmax(np.abs(a_u), axis=0)
    assert np.all(a_u[pivot, np.arange(6)] > 0)
    # The product u_k v_k^T is unchanged.
    np.testing.assert_allclose(a_u @ a_vt, u @ vt, atol=1e-12)


def test_first_term_of_a_non_negative_brdf_is_non_negative():
    p, m, w1, w2 = _setup(analytic("ggx", alpha=0.3))
    f = factorize_svd(m, w1, w2, 3, p.name)
    assert f.g[0].min() >= -1e-12 and f.h[0].min() >= -1e-12


def test_all_zero_matrix_gives_zero_factors():
    m = np.zeros((3, 32, 1024))
    w1 = np.full(32, 1 / 32)
    w2 = np.full(1024, 1 / 1024)
    for method in ("svd", "nmf", "nd"):
        f = factorize(m, w1, w2, 4, "half_diff", method)
        assert np.all(f.g == 0) and np.all(f.h == 0)
    assert matrix_errors(m, w1, w2, factorize(m, w1, w2, 2, "half_diff")) == [0.0, 0.0]


def test_nmf_and_nd_are_non_negative_and_nd_is_exact_for_rank_one():
    p, m, w1, w2 = _setup(analytic("ggx", alpha=0.3))
    nmf = factorize_nmf(m, w1, w2, 3, p.name, iterations=100)
    assert nmf.g.min() >= 0 and nmf.h.min() >= 0
    svd_err = matrix_errors(m, w1, w2, factorize_svd(m, w1, w2, 3, p.name))[-1]
    nmf_err = matrix_errors(m, w1, w2, nmf)[-1]
    assert svd_err <= nmf_err + 1e-12  # SVD is optimal; NMF pays for non-negativity
    assert nmf_err < 0.5
    # ND of an exactly rank-1 non-negative matrix is exact.
    rng = np.random.default_rng(2)
    r1 = np.stack([np.outer(rng.random(32), rng.random(1024)) for _ in range(3)])
    nd = factorize_nd(r1, w1 / w1.sum(), w2 / w2.sum(), p.name)
    np.testing.assert_allclose(nd.g[0][:, :, None] * nd.h[0].reshape(3, 1, -1), r1, rtol=1e-10)


def test_nmf_reaches_the_factors_of_lee_and_seungs_updates_in_double_precision():
    """factorize_nmf iterates in single precision for speed; the factors are those of Lee & Seung's
    multiplicative updates (2001) written here in double, from the same |SVD| start, to a part in 1e4."""
    p, m, w1, w2 = _setup(analytic("ggx", alpha=0.2, f0=(0.9, 0.6, 0.2)))
    terms, iterations = 4, 200
    got = factorize_nmf(m, w1, w2, terms, p.name, iterations=iterations)
    r1, r2 = np.sqrt(w1), np.sqrt(w2)
    for c in range(3):
        a = np.maximum(m[c], 0.0) * r1[:, None] * r2[None, :]
        u, s, vt = np.linalg.svd(a, full_matrices=False)
        u, vt = u[:, :terms], vt[:terms]
        w = np.abs(u) * np.sqrt(s[:terms]) + 1e-12
        h = np.abs(vt) * np.sqrt(s[:terms])[:, None] + 1e-12
        for _ in range(iterations):
            h *= (w.T @ a) / (w.T @ w @ h + 1e-12)
            w *= (a @ h.T) / (w @ (h @ h.T) + 1e-12)
        expect = w @ h / r1[:, None] / r2[None, :]
        rebuilt = np.einsum("ki,kj->ij", got.g[:, c], got.h[:, c].reshape(terms, -1))
        np.testing.assert_allclose(rebuilt, expect, atol=1e-4 * np.abs(expect).max())
