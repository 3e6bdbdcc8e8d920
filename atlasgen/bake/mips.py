"""Box-filtered mip chains, per slice (2D array) or across slices (3D volume)."""

from __future__ import annotations

import numpy as np

__all__ = ["build_array_mips", "build_volume_mips", "halve"]


def halve(image: np.ndarray, axes) -> np.ndarray:
    """Average 2-texel blocks along each axis in ``axes`` that is longer than 1 (a box filter).

    An axis of length 1 is kept, as GPUs do once one dimension reaches 1
    (64x32 -> ... -> 2x1 -> 1x1).
    """
    out = image
    for axis in axes:
        n = out.shape[axis]
        if n == 1:
            continue
        shape = out.shape[:axis] + (n // 2, 2) + out.shape[axis + 1 :]
        out = out.reshape(shape).mean(axis=axis + 1)
    return out


def build_array_mips(level0: np.ndarray) -> list[np.ndarray]:
    """Mip chain of a 2D array ``(layers, H, W, C)``, each layer filtered on its own.

    Filtering is done on linear floats, so a chain built from an sRGB-encoded atlas
    averages light, not code values.
    """
    levels = [level0]
    while levels[-1].shape[1] > 1 or levels[-1].shape[2] > 1:
        levels.append(halve(levels[-1], (1, 2)))
    return levels


def build_volume_mips(level0: np.ndarray) -> list[np.ndarray]:
    """Mip chain of a volume ``(D, H, W, C)``: depth halves too, so level 1 merges neighbouring slices."""
    levels = [level0]
    while any(n > 1 for n in levels[-1].shape[:3]):
        levels.append(halve(levels[-1], (0, 1, 2)))
    return levels
