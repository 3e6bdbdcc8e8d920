"""Real spherical harmonics: the basis, the projection of an equirectangular image, zonal kernels.

The basis is the real orthonormal one graphics uses (Ramamoorthi & Hanrahan, "An Efficient
Representation for Irradiance Environment Maps", SIGGRAPH 2001, eq. 3 and appendix), with z
the polar axis and no Condon-Shortley phase, indexed k = l*l + l + m:

    Y_l0      = K_l0 P_l(z)
    Y_lm      = sqrt(2) K_lm P_l^m(z) / sin^m(theta) Re((x + i y)^m)       m > 0
    Y_l,-m    = sqrt(2) K_lm P_l^m(z) / sin^m(theta) Im((x + i y)^m)
    K_lm      = sqrt((2l + 1) / (4 pi) (l - m)! / (l + m)!)

so Y_00 = 0.282095, Y_1,-1 = 0.488603 y, Y_10 = 0.488603 z, Y_11 = 0.488603 x, Y_2,-2 =
1.092548 xy, Y_20 = 0.315392 (3z^2 - 1), Y_22 = 0.546274 (x^2 - y^2) (their eq. 12). The
frame is the world's (x, y, z) whatever is "up": the basis only needs to agree between the
projection and the evaluation, and the zonal convolution below is rotation-invariant.

Funk-Hecke (their eq. 7): a kernel K(n.l) that depends on l only through n.l acts on each band
alone, int K(n.l) L(l) dl = sum_l lambda_l sum_m L_lm Y_lm(n), with
lambda_l = 2 pi int_-1^1 K(mu) P_l(mu) dmu (:func:`zonal_coefficients`).

The renderer's order, :data:`SH_ORDER` = 4 (25 coefficients a channel). A clamped cosine's
lambda_l are pi, 2 pi/3, pi/4, 0, -pi/24, 0, pi/64 (odd bands above 1 vanish), so the largest
band that l <= 4 leaves out is lambda_6 = pi/64, 1.6% of lambda_0, where l <= 2 would leave out
lambda_4 = pi/24, 4.2% of it. For the hardest environment, a sun (a delta) of irradiance E,
the truncated clamped cosine differs from E max(n.s, 0) by at most 5.9% of E at l <= 4 and
9.4% at l <= 2, and by 4.4% and 8.8% of its RMS over the sphere; smooth skies lose far less
(tests/optics/test_spherical_harmonics.py measures these figures). Bands 3 and 5 add nothing
to a clamped cosine, but a slice's kernel is not one (back-light, Fresnel, view dependence), so
the basis keeps every band up to 4.
"""

from __future__ import annotations

import math

import numpy as np

from atlasgen.optics.equirect import uv_to_direction
from atlasgen.optics.quadrature import gauss_legendre_rule

__all__ = [
    "SH_ORDER",
    "sh_count",
    "sh_order_of",
    "sh_band",
    "sh_basis",
    "evaluate_sh",
    "zonal_coefficients",
    "project_equirect",
    "project_directions",
]

#: The renderer's SH order: bands l <= 4, 25 coefficients per channel (why: the module's docstring).
SH_ORDER = 4


def sh_count(order: int) -> int:
    """Coefficients of bands 0..order: (order + 1)^2.

    >>> sh_count(4)
    25
    """
    return (order + 1) ** 2


def sh_order_of(count: int) -> int:
    """The order whose :func:`sh_count` is ``count``; ValueError for a count that is no square.

    >>> sh_order_of(9)
    2
    """
    order = math.isqrt(count) - 1
    if order < 0 or sh_count(order) != count:
        raise ValueError(f"{count} coefficients are not (order + 1)^2 for any order")
    return order


def sh_band(order: int) -> np.ndarray:
    """The band l of each coefficient index k = l*l + l + m, k < (order + 1)^2.

    >>> sh_band(2).tolist()
    [0, 1, 1, 1, 2, 2, 2, 2, 2]
    """
    return np.repeat(np.arange(order + 1), 2 * np.arange(order + 1) + 1)


def sh_basis(directions, order: int = SH_ORDER) -> np.ndarray:
    """Y_k(d) for unit ``directions`` ``(..., 3)``: ``(..., (order + 1)^2)`` float64.

    P_l^m(z) / sin^m is built by the recurrence Q_mm = (2m - 1)!!, Q_m+1,m = (2m + 1) z Q_mm,
    Q_lm = ((2l - 1) z Q_l-1,m - (l + m - 1) Q_l-2,m) / (l - m) (Abramowitz & Stegun 8.5.3),
    and (x + i y)^m by complex multiplication, so no angle is computed and the poles are exact.

    >>> sh_basis([0.0, 0.0, 1.0], 1).round(6).tolist()
    [0.282095, 0.0, 0.488603, 0.0]
    >>> sh_basis([1.0, 0.0, 0.0], 2)[8].round(6)  # Y_22 = 0.546274 (x^2 - y^2)
    np.float64(0.546274)
    """
    d = np.asarray(directions, dtype=np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    out = np.empty(d.shape[:-1] + (sh_count(order),))
    re, im = np.ones_like(x), np.zeros_like(x)  # (x + i y)^m, m = 0
    q_mm = np.ones_like(z)  # Q_mm, m = 0
    for m in range(order + 1):
        if m > 0:
            re, im = re * x - im * y, re * y + im * x
            q_mm = q_mm * (2 * m - 1)
        q_prev, q = np.zeros_like(z), q_mm
        for l in range(m, order + 1):
            if l == m + 1:
                q_prev, q = q, (2 * m + 1) * z * q_mm
            elif l > m + 1:
                q_prev, q = q, ((2 * l - 1) * z * q - (l + m - 1) * q_prev) / (l - m)
            k = math.sqrt((2 * l + 1) / (4.0 * math.pi) * math.factorial(l - m) / math.factorial(l + m))
            if m == 0:
                out[..., l * l + l] = k * q
            else:
                out[..., l * l + l + m] = math.sqrt(2.0) * k * q * re
                out[..., l * l + l - m] = math.sqrt(2.0) * k * q * im
    return out


def evaluate_sh(coefficients, directions, zonal=None) -> np.ndarray:
    """sum_k c_k Y_k(d), each band l scaled by ``zonal[..., l, :]`` when given.

    ``coefficients`` is ``(K,)`` or ``(K, C)`` with K = (order + 1)^2; ``directions`` unit
    ``(..., 3)``; ``zonal`` (optional) ``(..., order + 1)`` or ``(..., order + 1, C)``,
    broadcast against the directions' leading shape: with lambda_l (:func:`zonal_coefficients`)
    this is the Funk-Hecke convolution sum_l lambda_l sum_m L_lm Y_lm(n). Returns ``(...,)`` or
    ``(..., C)``.

    >>> c = np.zeros(9); c[0] = np.sqrt(4 * np.pi)  # a constant 1
    >>> float(evaluate_sh(c, [0.6, 0.0, 0.8]).round(12))
    1.0
    """
    c = np.asarray(coefficients, dtype=np.float64)
    order = sh_order_of(c.shape[0])
    y = sh_basis(directions, order)
    if zonal is None:
        return np.tensordot(y, c, axes=(-1, 0))
    lam = np.asarray(zonal, dtype=np.float64)
    if c.ndim == 2:
        return np.einsum("...k,...kc,kc->...c", y, lam[..., sh_band(order), :], c)
    return np.einsum("...k,...k,k->...", y, lam[..., sh_band(order)], c)


def zonal_coefficients(kernel, order: int = SH_ORDER, breakpoints=(-1.0, 1.0), nodes: int = 16) -> np.ndarray:
    """lambda_l = 2 pi int_-1^1 K(mu) P_l(mu) dmu, l = 0..order, by Gauss-Legendre between ``breakpoints``.

    ``kernel`` maps cosines mu of shape ``(n,)`` to values ``(n, ...)``; returns
    ``(order + 1, ...)``. The ``nodes``-point rule on each interval between consecutive
    breakpoints is exact when K is a polynomial of degree <= 2 nodes - 1 - order there, so put
    the breakpoints at K's kinks (a clamped cosine: -1, 0, 1; a slice: its texel centres).

    >>> lam = zonal_coefficients(lambda mu: np.maximum(mu, 0.0), 4, breakpoints=(-1.0, 0.0, 1.0))
    >>> ((lam / np.pi).round(12) + 0.0).tolist()  # 1, 2/3, 1/4, 0, -1/24 (Ramamoorthi & Hanrahan 2001, eq. 8)
    [1.0, 0.666666666667, 0.25, 0.0, -0.041666666667]
    """
    b = np.asarray(breakpoints, dtype=np.float64)
    if b.ndim != 1 or b.size < 2 or np.any(np.diff(b) <= 0.0) or b[0] < -1.0 or b[-1] > 1.0:
        raise ValueError(f"breakpoints must increase within [-1, 1], got {breakpoints!r}")
    t, w = gauss_legendre_rule(nodes)
    half = 0.5 * np.diff(b)
    mu = ((0.5 * (b[1:] + b[:-1]))[:, None] + half[:, None] * t).ravel()
    weight = (half[:, None] * w).ravel()
    values = np.asarray(kernel(mu), dtype=np.float64)
    legendre = np.stack([np.polynomial.legendre.legval(mu, [0.0] * l + [1.0]) for l in range(order + 1)])
    return 2.0 * np.pi * np.tensordot(legendre * weight, values, axes=(1, 0))


def project_directions(values, directions, weights, order: int = SH_ORDER) -> np.ndarray:
    """sum_i w_i f_i Y_k(d_i): the projection of samples ``values`` ``(N, C)`` with quadrature ``weights`` ``(N,)``.

    Returns ``(K, C)``. For a quadrature exact on the sphere, this is L_k = int f Y_k dw.
    """
    y = sh_basis(directions, order)
    return np.einsum("nk,n,nc->kc", y, np.asarray(weights, dtype=np.float64), np.asarray(values, dtype=np.float64))


def project_equirect(image, order: int = SH_ORDER, nodes: int | None = None) -> np.ndarray:
    """L_k = int L(w) Y_k(w) dw of an equirectangular ``image`` ``(H, W, C)``: ``(K, C)`` float64.

    L is the image as Mitsuba's ``envmap`` reconstructs it (:mod:`atlasgen.optics.equirect`):
    bilinear between samples at theta_j = pi j / (H - 1) and phi_i = 2 pi (i + 1/2) / W,
    periodic in phi. The integral is taken over that reconstruction, cell by cell (between
    neighbouring rows and columns), with a ``nodes``-point Gauss-Legendre rule per axis and
    dw = sin(theta) dtheta dphi; the integrand is smooth within a cell. ``nodes`` defaults to 4 below
    64 rows and 3 from there on (the cells are smaller), which keeps the rule's error below 1e-9 of
    L_00 from 16 rows up (tests/optics/test_spherical_harmonics.py).
    """
    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 3 or img.shape[0] < 2 or img.shape[1] < 1:
        raise ValueError(f"expected an image (H >= 2, W, C), got shape {img.shape}")
    h, w_, c = img.shape
    t, wt = gauss_legendre_rule(nodes if nodes is not None else (4 if h < 64 else 3))
    f = 0.5 * (t + 1.0)  # fractions within a cell, in (0, 1)
    # theta nodes: (H - 1) cells x nodes; phi nodes: W periodic cells x nodes.
    dtheta, dphi = np.pi / (h - 1), 2.0 * np.pi / w_
    rows = (np.arange(h - 1)[:, None] + f).ravel()  # fractional row coordinate
    cols = (np.arange(w_)[:, None] + f).ravel()  # fractional column coordinate (column i at phi_i)
    theta = rows * dtheta
    row_weight = np.tile(0.5 * wt, h - 1) * dtheta * np.sin(theta)
    col_weight = np.tile(0.5 * wt, w_) * dphi
    r0 = np.floor(rows).astype(np.intp)
    fr = rows - r0
    c0 = np.floor(cols).astype(np.intp) % w_
    fc = (cols - np.floor(cols))[:, None]
    c1 = (c0 + 1) % w_
    # Along phi first: every row at every phi node, (H, Nphi, C).
    along_phi = img[:, c0] * (1.0 - fc) + img[:, c1] * fc
    phi = 2.0 * np.pi * (cols + 0.5) / w_
    out = np.zeros((sh_count(order), c))
    chunk = max(1, 2_000_000 // (len(cols) * sh_count(order)))
    for start in range(0, len(rows), chunk):
        sl = slice(start, start + chunk)
        values = along_phi[r0[sl]] * (1.0 - fr[sl, None, None]) + along_phi[r0[sl] + 1] * fr[sl, None, None]
        d = uv_to_direction(phi[None, :] / (2.0 * np.pi), theta[sl, None] / np.pi)
        weighted = values * (row_weight[sl, None, None] * col_weight[None, :, None])
        out += sh_basis(d, order).reshape(-1, out.shape[0]).T @ weighted.reshape(-1, c)
    return out
