"""Gauss-Legendre rules against closed-form integrals."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.optics.quadrature import cosine_rule, gauss_legendre_rule, hemispherical_average, integrate_gauss_legendre


@pytest.mark.parametrize("n", [1, 2, 5, 12, 32])
def test_the_n_point_rule_is_exact_to_degree_2n_minus_1_and_no_further(n):
    x, w = gauss_legendre_rule(n)
    assert x.shape == w.shape == (n,)
    for k in range(2 * n):
        exact = 2.0 / (k + 1) if k % 2 == 0 else 0.0
        assert np.dot(w, x**k) == pytest.approx(exact, abs=1e-13)
    # x^(2n) is the first monomial it misses: the rule's error is a positive multiple of the
    # 2n-th derivative (A&S 25.4.30), large enough to see for a few points.
    if n <= 5:
        assert np.dot(w, x ** (2 * n)) < 2.0 / (2 * n + 1) - 1e-3


def test_rules_are_cached_and_read_only():
    x, w = gauss_legendre_rule(32)
    assert gauss_legendre_rule(32)[0] is x
    c, cw = cosine_rule()
    for a in (x, w, c, cw):
        with pytest.raises(ValueError):
            a[0] = 0.0


@given(lo=st.floats(-3, 3), width=st.floats(0.0, 3.0))
@pytest.mark.slow
def test_integrals_over_intervals_match_antiderivatives(lo, width):
    hi = lo + width
    got = integrate_gauss_legendre(np.exp, np.array([lo, 0.0]), np.array([hi, np.pi]))
    np.testing.assert_allclose(got, [np.exp(hi) - np.exp(lo), np.expm1(np.pi)], rtol=1e-13, atol=1e-13)


def test_intervals_broadcast_and_a_reversed_interval_changes_sign():
    lo = np.zeros((2, 3))
    hi = np.array([np.pi, np.pi / 2, 1.0])
    got = integrate_gauss_legendre(np.sin, lo, hi)
    assert got.shape == (2, 3)
    np.testing.assert_allclose(got, np.broadcast_to([2.0, 1.0, 1.0 - np.cos(1.0)], (2, 3)), rtol=1e-14)
    assert integrate_gauss_legendre(np.sin, np.pi, 0.0) == pytest.approx(-2.0, rel=1e-14)


@pytest.mark.parametrize("k", range(0, 40))
def test_cosine_rule_integrates_powers_of_the_cosine(k):
    c, w = cosine_rule()
    assert np.all((c > 0) & (c < 1))
    # 2 int_0^1 c^k c dc = 2 / (k + 2), exact up to degree 2 * 32 - 2 in c^k.
    assert np.dot(w, c**k) == pytest.approx(2.0 / (k + 2), rel=1e-13)


def test_hemispherical_average_of_several_functions_at_once():
    avg = hemispherical_average(lambda c: np.stack([np.ones_like(c), c, np.sqrt(1 - c * c)], axis=-1))
    # 2 int c dc = 1; 2 int c^2 dc = 2/3; 2 int c sqrt(1 - c^2) dc = 2/3 (the last is not a polynomial).
    np.testing.assert_allclose(avg[:2], [1.0, 2.0 / 3.0], rtol=1e-14)
    assert avg[2] == pytest.approx(2.0 / 3.0, rel=1e-4)
