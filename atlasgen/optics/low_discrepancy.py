"""The Halton sequence with a random shift: randomised quasi-Monte Carlo points in the unit cube.

Point k of the Halton sequence (Halton 1960) has as coordinate i the radical inverse of k in the i-th prime
base b_i: the digits of k in base b_i mirrored about the radix point, phi_b(sum_j d_j b^j) = sum_j d_j b^(-j-1).
Every prefix is evenly spread (star discrepancy O((log N)^d / N)), so a smooth integrand's error falls about as
1/N rather than Monte Carlo's 1/sqrt(N), and the sequence can be extended: points [n, n + m) add to
[0, n). A Cranley-Patterson rotation (Cranley & Patterson 1976), x -> frac(x + u) with u uniform in the
cube, keeps that spread and makes each estimate unbiased; estimates with independent shifts are
independent, so two of them measure the error as two Monte Carlo seeds do.
"""

from __future__ import annotations

import numpy as np

__all__ = ["PRIMES", "radical_inverse", "halton_points"]

#: The bases of the first coordinates.
PRIMES = (2, 3, 5, 7, 11, 13, 17)


def radical_inverse(k, base: int) -> np.ndarray:
    """phi_base(k) in [0, 1) for non-negative integers ``k`` (any shape), float64.

    >>> radical_inverse(np.arange(8), 2).tolist()
    [0.0, 0.5, 0.25, 0.75, 0.125, 0.625, 0.375, 0.875]
    >>> radical_inverse([1, 2, 3, 4], 3).round(6).tolist()
    [0.333333, 0.666667, 0.111111, 0.444444]
    """
    k = np.asarray(k, dtype=np.int64).copy()
    if np.any(k < 0):
        raise ValueError("radical_inverse needs non-negative integers")
    out = np.zeros(k.shape)
    scale = 1.0 / base
    while np.any(k):
        out += (k % base) * scale
        k //= base
        scale /= base
    return out


def halton_points(first: int, count: int, dimensions: int, seed: int = 0) -> np.ndarray:
    """Points ``first`` to ``first + count - 1`` of the ``dimensions``-D Halton sequence, each coordinate
    shifted by the same uniform offset drawn from ``seed`` (modulo 1): ``(count, dimensions)`` float64 in [0, 1).

    >>> p = halton_points(0, 4, 2, seed=None)
    >>> p.tolist()
    [[0.0, 0.0], [0.5, 0.3333333333333333], [0.25, 0.6666666666666666], [0.75, 0.1111111111111111]]
    """
    if dimensions > len(PRIMES):
        raise ValueError(f"at most {len(PRIMES)} dimensions, got {dimensions}")
    k = np.arange(first, first + count)
    points = np.stack([radical_inverse(k, b) for b in PRIMES[:dimensions]], axis=-1)
    if seed is None:
        return points
    shift = np.random.default_rng(seed).random(dimensions)
    return np.mod(points + shift, 1.0)
