"""Moving separable factors from the grid a BRDF was sampled on to the grid the atlas stores.

Both grids are endpoint-inclusive, t = i / (n - 1), and the GPU reconstructs a factor
linearly between stored texels (:mod:`atlasgen.separable.rebuild`). A coarser sampling
grid is carried up by linear interpolation, which a linear filter then reproduces
exactly at the coarse samples. A finer grid is carried down by least squares: the
stored texels are the ones whose linear reconstruction comes closest, in the 2-norm
over the fine samples, to the fine factor, which a sharp lobe needs more than point
samples at the stored texel centres.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from atlasgen.optics.interpolation import linear_stencil
from atlasgen.separable.factorize import Factors

__all__ = ["interpolation_matrix", "resampling_matrix", "resample_factors"]


def interpolation_matrix(source: int, target: int) -> np.ndarray:
    """``(target, source)`` matrix of linear interpolation between endpoint-inclusive grids.

    Row j holds the weights of the two source samples around t = j / (target - 1), as a
    linear filter reads them (:func:`atlasgen.optics.interpolation.linear_stencil`).
    """
    if source < 2 or target < 2:
        raise ValueError(f"grids need at least 2 samples, got {source} -> {target}")
    i0, i1, frac = linear_stencil(source, np.arange(target, dtype=np.float64) * (source - 1) / (target - 1))
    matrix = np.zeros((target, source))
    rows = np.arange(target)
    matrix[rows, i0] = 1.0 - frac
    matrix[rows, i1] += frac
    return matrix


@lru_cache(maxsize=16)
def resampling_matrix(source: int, target: int) -> np.ndarray:
    """``(target, source)`` operator taking a factor sampled on ``source`` texels to ``target``.

    Upsampling (source <= target) is :func:`interpolation_matrix`. Downsampling is the
    least-squares fit x = B^+ y, where B = interpolation_matrix(target, source) is how
    the stored texels are filtered back onto the fine grid and B^+ its pseudo-inverse.
    """
    if source <= target:
        matrix = interpolation_matrix(source, target)
    else:
        matrix = np.linalg.pinv(interpolation_matrix(target, source))
    matrix.flags.writeable = False
    return matrix


def resample_factors(factors: Factors, resolution: int) -> Factors:
    """The factors on ``resolution`` texels per axis: g along pi1, h along both pi2 axes.

    h is a tensor product in its two axes, so applying the 1D operator R per axis,
    R H R^T, is the 2D interpolation (up) or the 2D least-squares fit (down).
    """
    if factors.resolution == resolution:
        return factors
    r = resampling_matrix(factors.resolution, resolution)
    g = np.einsum("ji,kci->kcj", r, factors.g)
    h = np.einsum("ji,kcyi->kcyj", r, factors.h)
    h = np.einsum("ji,kcix->kcjx", r, h)
    return Factors(g, h, factors.parametrization, factors.singular_values, factors.target)
