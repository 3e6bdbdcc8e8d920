"""Least-squares projection of a BSDF onto the renderer's (N.L, N.V) slice equation.

Per texel (N.L, N.V) the renderer adds, per unit irradiance and unit albedo,

    f^cos(phi) = sum_c D_c(phi) r_c e_c + A S(phi),

where ``r = A.rgb`` and ``A = A.a`` are the texel's unknowns, D_c the radiance one unit of
``A.rgb`` channel c adds (1/pi today) and S the specular lobe times the cosine
(:mod:`atlasgen.optics.specular`), both at the azimuth phi between l and v. A physical
BSDF gives a target t_c(phi) = f(l, v) cos(theta_l) that generally depends on phi in
a way the slice cannot; its projection is the non-negative weighted least-squares fit

    min_{r >= 0, A >= 0}  sum_s w_s sum_c (t_c(phi_s) - D_c(phi_s) r_c - S_c(phi_s) A)^2

over azimuth samples phi_s with weights w_s (Lawson & Hanson, *Solving Least Squares
Problems*, 1974, ch. 23). With four unknowns per texel the problem is solved exactly and
vectorised by enumerating the 2^4 faces of the non-negative orthant: each face's
unconstrained minimiser (its normal equations) is a candidate, and
the feasible candidate of least objective is the optimum, since the objective is a
convex quadratic and its constrained minimiser is the unconstrained minimiser of the
face it lies on. Fewer free unknowns win ties, so a texel with no lobe gets A = 0.

Where the samples cannot tell the unknowns apart (l = n, where every azimuth is the same
direction, or a lobe that is nearly zero at every sample) the minimiser is not unique
and a huge A can buy a negligible gain. A ridge lambda A^2 with lambda = 1e-6 max_i G_ii
(Tikhonov regularisation; Hoerl & Kennard, Technometrics 12, 1970) leaves such a texel to
the diffuse term, as a Lambertian surface expects; elsewhere it moves the fit by about
1e-6 relative.

The ridge decides the split texel by texel, which suits a Lambertian surface but not a
sharp lobe: at N.L = 1 and N.V = 1 a conductor's peak would go to the diffuse term, and
the bilinear filter would spread that diffuse value over the half texel next to it, where
the lobe has moved and the diffuse term cannot follow. :func:`continue_collinear_texels`
therefore splits such a texel as its nearest separable texel does: A is held at that
texel's A (the split is the one quantity the samples cannot see, so it is taken from where
they can) and A.rgb takes the rest, which leaves the texel's own fit unchanged.

Once ``r`` has been rounded to what the atlas stores, :func:`refine_specular_scale`
re-fits A alone against it: A = max(0, sum w S . (t - D r_q) / sum w S . S).
"""

from __future__ import annotations

import itertools

import numpy as np

#: 1 - cos^2 of the angle between a texel's diffuse and lobe samples below which the two are collinear.
COLLINEAR_TOLERANCE = 1e-9
#: Relative Tikhonov weight: lambda = RIDGE * max_i G_ii per texel (see the module docstring).
RIDGE = 1e-6

__all__ = ["RIDGE", "COLLINEAR_TOLERANCE", "pair_directions", "solve_nonnegative_least_squares", "project_slice_texels",
           "collinear_texels", "continue_collinear_texels", "refine_specular_scale", "weighted_residual"]  # fmt: skip


def pair_directions(n_dot_l, n_dot_v, phi, shape):
    """Unit l, v ``shape + (3,)`` in the local frame (n = +z) from broadcastable cosines N.L, N.V
    and the azimuth phi of l from v, v in the xz plane: the (l, v) pair of a texel's sample."""
    nl, nv = np.asarray(n_dot_l, dtype=np.float64), np.asarray(n_dot_v, dtype=np.float64)
    sl, sv = np.sqrt(np.maximum(1.0 - nl * nl, 0.0)), np.sqrt(np.maximum(1.0 - nv * nv, 0.0))
    l = np.stack([np.broadcast_to(c, shape) for c in (sl * np.cos(phi), sl * np.sin(phi), nl)], axis=-1)
    v = np.stack([np.broadcast_to(c, shape) for c in (sv, 0.0 * phi, nv)], axis=-1)
    return l, v


def solve_nonnegative_least_squares(gram: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """argmin_{x >= 0} x^T G x - 2 h^T x for a stack of small problems, exactly.

    ``gram`` is ``(..., n, n)`` symmetric positive semi-definite (G = B^T W B) and
    ``rhs`` ``(..., n)`` (h = B^T W t, so h lies in G's range); n up to about 6, since
    all 2^n faces of the orthant are tried. Returns ``(..., n)``.
    """
    gram = np.asarray(gram, dtype=np.float64)
    rhs = np.asarray(rhs, dtype=np.float64)
    n = rhs.shape[-1]
    scale = np.maximum(np.abs(gram).max(axis=(-2, -1)), 1e-300)
    tol = 1e-12 * np.maximum(np.abs(rhs).max(axis=-1), 1e-300) / scale  # a negligible x, in x's units
    best = np.zeros(rhs.shape)
    best_obj = np.zeros(rhs.shape[:-1])  # x = 0
    faces = sorted((m for m in itertools.product((0.0, 1.0), repeat=n) if any(m)), key=sum)
    for mask in faces:
        m = np.asarray(mask)
        # The face's normal equations, the fixed unknowns' rows replaced by x_i = 0; a relative
        # ridge of 1e-12 makes singular faces (a lobe that is zero at every sample) solvable.
        g = gram * (m[:, None] * m[None, :]) + np.diag(1.0 - m) * scale[..., None, None]
        g = g + 1e-12 * scale[..., None, None] * np.eye(n)
        x = np.linalg.solve(g, (rhs * m)[..., None])[..., 0]
        feasible = (x >= -tol[..., None]).all(axis=-1)
        x = np.maximum(x, 0.0) * m
        obj = np.einsum("...i,...ij,...j->...", x, gram, x) - 2.0 * np.einsum("...i,...i->...", rhs, x)
        # A strict, relative improvement: ties (a lobe that carries nothing) keep the smaller face.
        better = feasible & (obj < best_obj - 1e-10 * np.maximum(np.abs(best_obj), 1e-300))
        best = np.where(better[..., None], x, best)
        best_obj = np.where(better, obj, best_obj)
    return best


def _design(diffuse, lobe):
    """The per-sample design matrix B (..., S, 3 channels, 4 unknowns): r_c acts on channel c, A on all."""
    diffuse = np.asarray(diffuse, dtype=np.float64)
    lobe = np.broadcast_to(np.asarray(lobe, dtype=np.float64), diffuse.shape)
    b = np.zeros(diffuse.shape + (4,))
    for c in range(3):
        b[..., c, c] = diffuse[..., c]
    b[..., 3] = lobe
    return b


#: The (i, j), i <= j, of the Gram matrix B^T W B that :func:`_design`'s zeros leave non-zero.
_GRAM_ENTRIES = ((0, 0), (1, 1), (2, 2), (3, 3), (0, 3), (1, 3), (2, 3))


def project_slice_texels(target, diffuse, lobe, weights, ridge: float = RIDGE) -> np.ndarray:
    """The non-negative least-squares slice value (r, g, b, A) of each texel.

    Parameters
    ----------
    target
        ``(..., S, 3)``: the BSDF's f cos(theta_l) at each texel's S azimuth samples.
    diffuse
        ``(..., S, 3)``: the renderer's f cos for A.rgb = (1, 1, 1), A = 0, per channel.
    lobe
        ``(..., S, 3)`` or ``(..., S, 1)``: the renderer's f cos for A.rgb = 0, A = 1.
    weights
        ``(..., S)``, >= 0: each sample's weight in the squared error.

    Returns
    -------
    ``(..., 4)``: linear RGBA >= 0, the minimiser of the module's weighted residual.
    """
    b = _design(diffuse, lobe)
    bw = b * np.asarray(weights, dtype=np.float64)[..., None, None]
    t = np.asarray(target, dtype=np.float64)
    # G = B^T W B and h = B^T W t entry by entry: the RGB unknowns act on one channel each, so
    # G's off-diagonal RGB entries are zero and are not summed (half the time of one einsum over
    # all sixteen, and the same sums, term for term).
    gram = np.zeros(b.shape[:-3] + (4, 4))
    for i, j in _GRAM_ENTRIES:
        gram[..., i, j] = gram[..., j, i] = np.einsum("...sc,...sc->...", bw[..., i], b[..., j])
    rhs = np.stack([np.einsum("...sc,...sc->...", bw[..., i], t) for i in range(4)], axis=-1)
    lam = ridge * np.diagonal(gram, axis1=-2, axis2=-1).max(axis=-1)
    return solve_nonnegative_least_squares(gram + lam[..., None, None] * np.diag([0.0, 0.0, 0.0, 1.0]), rhs)


def collinear_texels(diffuse, lobe, weights, tolerance: float = COLLINEAR_TOLERANCE) -> np.ndarray:
    """Texels whose samples cannot tell A.rgb from A: the lobe is a non-zero multiple of the diffuse term.

    With g_dd = sum w D.D, g_ss = sum w S.S and g_ds = sum w D.S over a texel's samples and
    channels, the two are collinear where g_ss > 0 and 1 - g_ds^2 / (g_dd g_ss) <= ``tolerance``
    (Cauchy-Schwarz is an equality only for proportional vectors): N.L = 1 or N.V = 1, where
    every azimuth gives the same pair. Shapes as :func:`project_slice_texels`; returns ``(...)`` bool.
    """
    d = np.asarray(diffuse, dtype=np.float64)
    s = np.broadcast_to(np.asarray(lobe, dtype=np.float64), d.shape)
    w = np.asarray(weights, dtype=np.float64)[..., None]
    g_dd, g_ss, g_ds = ((w * a * b).sum(axis=(-2, -1)) for a, b in ((d, d), (s, s), (d, s)))
    product = g_dd * g_ss
    return (g_ss > 0.0) & (g_ds * g_ds >= (1.0 - tolerance) * product)


def _nearest_separable(collinear: np.ndarray, separable: np.ndarray):
    """(rows, cols) of the nearest ``separable`` texel (Euclidean, in texels; first in row-major
    order on a tie) for each ``collinear`` texel, in row-major order. The collinear texels are
    one row and one column of a 64x32 slice, so a brute-force search is cheap, and keeps SciPy
    off the bake's import path."""
    targets = np.argwhere(collinear)
    sources = np.argwhere(separable)
    d2 = ((targets[:, None, :] - sources[None, :, :]) ** 2).sum(-1)
    nearest = sources[np.argmin(d2, axis=1)]
    return nearest[:, 0], nearest[:, 1]


def continue_collinear_texels(rgba, diffuse, lobe, weights, tolerance: float = COLLINEAR_TOLERANCE) -> np.ndarray:
    """The slice ``rgba`` ``(H, W, 4)`` with each collinear texel (:func:`collinear_texels`) split as its nearest separable texel.

    At a collinear texel S = k D per channel, with k = g_ds / g_dd, so the texel's fit
    depends on r_c + k A alone. A becomes A' = min(A_n, min_c (r_c + k A) / k), A_n the A of
    the nearest texel (Euclidean, in texels) that is not collinear and has a lobe, and
    r_c' = r_c + k (A - A'):
    the fit at the texel's own samples is the same, and A continues into the row or column
    where the samples cannot fix it. Other texels are returned as they are.
    """
    rgba = np.array(rgba, dtype=np.float64)
    d = np.asarray(diffuse, dtype=np.float64)
    s = np.broadcast_to(np.asarray(lobe, dtype=np.float64), d.shape)
    collinear = collinear_texels(d, s, weights, tolerance)
    w = np.asarray(weights, dtype=np.float64)[..., None]
    # A texel without a lobe (the light below the horizon) has no A to continue from.
    separable = ~collinear & ((w * s * s).sum(axis=(-2, -1)) > 0.0)
    if not collinear.any() or not separable.any():
        return rgba
    k = (w * d * s).sum(axis=(-2, -1))[collinear] / (w * d * d).sum(axis=(-2, -1))[collinear]
    rows, cols = _nearest_separable(collinear, separable)
    neighbour = rgba[rows, cols, 3]
    total = rgba[collinear, :3] + (k * rgba[collinear, 3])[:, None]  # r_c + k A, what the samples fix
    a = np.minimum(neighbour, total.min(axis=-1) / k)
    rgba[collinear, 3] = a
    rgba[collinear, :3] = np.maximum(total - (k * a)[:, None], 0.0)
    return rgba


def refine_specular_scale(target, diffuse, lobe, weights, rgb, ridge: float = RIDGE) -> np.ndarray:
    """A >= 0 that best fits ``target`` with A.rgb held at ``rgb`` (``(..., 3)``, e.g. as stored in 8 bits).

    A = max(0, sum_s w_s sum_c S_c (t_c - D_c r_c) / (sum_s w_s sum_c S_c^2 + lambda)), with
    the ridge lambda of :func:`project_slice_texels`; 0 where the lobe vanishes at every
    sample. Returns ``(...)``.
    """
    t = np.asarray(target, dtype=np.float64)
    d = np.asarray(diffuse, dtype=np.float64)
    s = np.broadcast_to(np.asarray(lobe, dtype=np.float64), d.shape)
    w = np.asarray(weights, dtype=np.float64)[..., None]
    rest = t - d * np.asarray(rgb, dtype=np.float64)[..., None, :]
    num = (w * s * rest).sum(axis=(-2, -1))
    den = (w * s * s).sum(axis=(-2, -1))
    per_channel = (w * d * d).sum(axis=-2).max(axis=-1)  # the diagonal of the full problem's Gram matrix
    den = den + ridge * np.maximum(den, per_channel)
    return np.maximum(np.divide(num, den, out=np.zeros_like(num), where=den > 0.0), 0.0)


def weighted_residual(target, diffuse, lobe, weights, rgba) -> np.ndarray:
    """sum_s w_s sum_c (t_c - D_c r_c - S_c A)^2 per texel for slice values ``rgba`` ``(..., 4)``."""
    rgba = np.asarray(rgba, dtype=np.float64)
    d = np.asarray(diffuse, dtype=np.float64)
    s = np.broadcast_to(np.asarray(lobe, dtype=np.float64), d.shape)
    # D_c r_c + S_c A: the design matrix's product without its zeros (the same sums).
    fit = d * rgba[..., None, :3] + s * rgba[..., None, 3:]
    err = np.asarray(target, dtype=np.float64) - fit
    return (np.asarray(weights, dtype=np.float64)[..., None] * err * err).sum(axis=(-2, -1))
