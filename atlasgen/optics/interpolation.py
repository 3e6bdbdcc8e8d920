"""Linear filtering as a GPU sampler does it, and the CPU twin of the include's ``atlas_sample``.

A texture with n texels along an axis is read at a continuous texel coordinate x, texel
i's centre at x = i: value = t[i0] (1 - f) + t[i0 + 1] f with i0 = floor(x), f = x - i0,
and x clamped to [0, n - 1] (clamp-to-edge addressing; Vulkan spec, "Texel Filtering").
Bilinear filtering does this along x, then along y. Every CPU reconstruction of stored
texels (atlas slices, separable factors, tabulated spectra) uses these functions.
"""

from __future__ import annotations

import numpy as np

from atlasgen.contract import atlas_uv

__all__ = ["linear_stencil", "interpolate_1d", "interpolate_2d", "sample_slice"]


def linear_stencil(n: int, x):
    """The two texels and the weight of linear filtering at texel coordinates ``x``, clamp-to-edge.

    Returns ``(i0, i1, f)`` with value = t[i0] (1 - f) + t[i1] f: x is clamped to
    [0, n - 1], i0 = min(floor(x), n - 2) and i1 = min(i0 + 1, n - 1), so the last
    texel centre is reached with f = 1 and a one-texel axis reads its only texel.
    """
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, n - 1)
    i0 = np.minimum(np.floor(x).astype(np.intp), max(n - 2, 0))
    return i0, np.minimum(i0 + 1, n - 1), x - i0


def _trailing(weight, table: np.ndarray, grid_axes: int):
    # The weight, shaped to broadcast over the table's value axes (colour channels).
    return weight.reshape(weight.shape + (1,) * (table.ndim - grid_axes))


def interpolate_1d(table: np.ndarray, x) -> np.ndarray:
    """Linear filtering of ``table[n, ...]`` along its first axis at texel coordinates ``x``.

    Returns ``x.shape + table.shape[1:]``; coordinates outside [0, n - 1] read the edge
    texels (:func:`linear_stencil`).
    """
    table = np.asarray(table)
    i0, i1, f = linear_stencil(table.shape[0], x)
    f = _trailing(f, table, 1)
    return table[i0] * (1.0 - f) + table[i1] * f


def interpolate_2d(table: np.ndarray, x, y) -> np.ndarray:
    """Bilinear filtering of ``table[ny, nx, ...]`` at texel coordinates (x, y), clamp-to-edge.

    x indexes columns (axis 1) and y rows (axis 0); filtered along x first, then y, as
    lerp(lerp(t00, t01, fx), lerp(t10, t11, fx), fy). Returns ``broadcast(x, y).shape +
    table.shape[2:]``; at texel centres it returns the texels exactly.
    """
    table = np.asarray(table)
    x0, x1, fx = linear_stencil(table.shape[1], x)
    y0, y1, fy = linear_stencil(table.shape[0], y)
    fx, fy = _trailing(fx, table, 2), _trailing(fy, table, 2)
    top = table[y0, x0] * (1 - fx) + table[y0, x1] * fx
    bottom = table[y1, x0] * (1 - fx) + table[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


def sample_slice(table: np.ndarray, n_dot_l, n_dot_v, nearest: bool = False) -> np.ndarray:
    """Look up an ``(H, W, C)`` slice at (N.L, N.V) with clamp-to-edge addressing.

    Coordinates follow the atlas contract (:func:`atlasgen.contract.atlas_uv`): texel i
    centre at N.L = -1 + 2i/(W-1), texel j centre at N.V = j/(H-1). ``nearest`` reads
    the texel containing the point, as ``atlas_sample`` does for slices flagged
    ``nearest`` (toon bands); otherwise the lookup is bilinear (:func:`interpolate_2d`).
    """
    h, w = table.shape[:2]
    u, v = atlas_uv(n_dot_l, n_dot_v, w, h)
    if nearest:
        x = np.minimum(np.floor(u * w).astype(np.int64), w - 1)
        y = np.minimum(np.floor(v * h).astype(np.int64), h - 1)
        return table[y, x]
    return interpolate_2d(table, u * w - 0.5, v * h - 0.5)
