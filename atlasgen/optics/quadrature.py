"""Gauss-Legendre quadrature: the rule on [-1, 1], integrals over intervals, and the cosine-weighted rule.

An n-point Gauss-Legendre rule integrates polynomials of degree up to 2n - 1 exactly
(Abramowitz & Stegun, *Handbook of Mathematical Functions*, 25.4.29). The models'
integrands (Fresnel reflectance, Penner's ring kernels, the back-lighting azimuth) are
smooth on their intervals, where the rule converges exponentially.
"""

from __future__ import annotations

from functools import cache

import numpy as np

__all__ = ["gauss_legendre_rule", "integrate_gauss_legendre", "cosine_rule", "hemispherical_average"]


@cache
def gauss_legendre_rule(n: int = 32):
    """Nodes x_k in (-1, 1) and weights w_k of the n-point rule: int_-1^1 f(x) dx ~ sum_k w_k f(x_k).

    The arrays are cached and read-only.
    """
    nodes, weights = np.polynomial.legendre.leggauss(n)
    nodes.setflags(write=False)
    weights.setflags(write=False)
    return nodes, weights


def integrate_gauss_legendre(integrand, lo, hi, n: int = 32):
    """int_lo^hi f(x) dx over broadcast intervals, by the n-point rule mapped onto each.

    With x = (hi + lo) / 2 + (hi - lo) / 2 t, the integral is (hi - lo) / 2 sum_k w_k f(x_k).

    Parameters
    ----------
    integrand : callable
        Maps nodes of shape ``lo.shape + (n,)`` to values of the same shape.
    lo, hi : array_like
        Interval ends, broadcast together.

    Returns
    -------
    ndarray
        The integrals, shaped like ``lo`` and ``hi`` broadcast.
    """
    x, w = gauss_legendre_rule(n)
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    half = 0.5 * (hi - lo)
    xs = (0.5 * (hi + lo))[..., None] + half[..., None] * x
    return half * (integrand(xs) @ w)


@cache
def cosine_rule(n: int = 32):
    """Nodes c_k in (0, 1) and weights w_k with sum_k w_k f(c_k) ~ 2 int_0^1 f(c) c dc.

    The n-point rule mapped onto [0, 1], c = (x + 1) / 2, with the weight 2 (dc / dx) c = c
    folded in. Cached and read-only.
    """
    x, w = gauss_legendre_rule(n)
    c = 0.5 * (x + 1.0)
    weights = w * c
    c.setflags(write=False)
    weights.setflags(write=False)
    return c, weights


def hemispherical_average(function_of_cosine, n: int = 32):
    """2 int_0^1 f(c) c dc: the cosine-weighted average of f over the hemisphere.

    For a reflectance F(c) this is F_avg, the albedo of the surface under uniform
    (cosine-weighted) light. ``function_of_cosine`` maps cosines of shape (n,) to (n,) or (n, k) values; computed
    with :func:`cosine_rule`.
    """
    c, w = cosine_rule(n)
    return np.tensordot(w, np.asarray(function_of_cosine(c), dtype=np.float64), axes=(0, 0))
