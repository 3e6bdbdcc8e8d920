"""The CPU twin of the include's ``atlas_sample``: a slice looked up at (N.L, N.V) as a GPU sampler does."""

from __future__ import annotations

import numpy as np

from atlasgen.contract import atlas_uv

__all__ = ["sample_slice"]


def sample_slice(table: np.ndarray, n_dot_l, n_dot_v, nearest: bool = False) -> np.ndarray:
    """Look up an ``(H, W, C)`` slice at (N.L, N.V) with clamp-to-edge addressing.

    Coordinates follow the atlas contract (:func:`atlasgen.contract.atlas_uv`): texel i
    centre at N.L = -1 + 2i/(W-1), texel j centre at N.V = j/(H-1). ``nearest`` reads
    the texel containing the point, as ``atlas_sample`` does for slices flagged
    ``nearest`` (toon bands); otherwise the lookup is bilinear.
    """
    h, w = table.shape[:2]
    u, v = atlas_uv(n_dot_l, n_dot_v, w, h)
    if nearest:
        x = np.minimum(np.floor(u * w).astype(np.int64), w - 1)
        y = np.minimum(np.floor(v * h).astype(np.int64), h - 1)
        return table[y, x]
    x = np.clip(u * w - 0.5, 0.0, w - 1.0)
    y = np.clip(v * h - 0.5, 0.0, h - 1.0)
    x0 = np.minimum(np.floor(x).astype(np.int64), w - 2)
    y0 = np.minimum(np.floor(y).astype(np.int64), h - 2)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    top = table[y0, x0] * (1 - fx) + table[y0, x0 + 1] * fx
    bottom = table[y0 + 1, x0] * (1 - fx) + table[y0 + 1, x0 + 1] * fx
    return top * (1 - fy) + bottom * fy
