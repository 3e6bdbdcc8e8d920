"""How K separable terms are laid out in K atlas slices, and how they are mapped to UNORM8.

Layout of term k (slice ``first_slice + k``, 64x32 texels, level 0):

* left half, texels u in [0, 32): g_k(pi1), RGB = one factor per colour channel. g is
  one-dimensional, so every row holds the same 32 values (pi1 texel i = column i).
* right half, texels u in [32, 64): h_k(pi2), RGB per channel, column x = pi2's first
  angle, row y = its second.
* A = 0 (unused).

Each (term, factor, channel) has its own scale and bias:
value = stored * scale + bias, stored in [0, 1]. A factor with no negative value gets
bias 0 (the full 8-bit range for [0, max]); a signed one gets bias = min and
scale = max - min (SVD terms after the first have mixed signs).
"""

from __future__ import annotations

import numpy as np

from atlasgen.optics.quantize import dequantize_rgba, quantize_rgba
from atlasgen.separable.factorize import Factors
from atlasgen.separable.rebuild import factors_from_slices

__all__ = ["FACTOR_RESOLUTION", "CHANNEL_LAYOUT", "factors_to_slices", "encode_factor_slices", "quantize_factors"]

#: Texels per axis of one factor texture: half a 64x32 slice.
FACTOR_RESOLUTION = 32

CHANNEL_LAYOUT = (
    "slice k = term k; left 32x32 half: g_k(pi1) in RGB (per colour channel, same value in every row), "
    "right 32x32 half: h_k(pi2) in RGB (x = first pi2 angle, y = second); A = 0; "
    "value = stored * factor_scale[k][factor][channel] + factor_bias[k][factor][channel], factor 0 = g, 1 = h"
)


def factors_to_slices(factors: Factors) -> np.ndarray:
    """Float slices ``(K, 32, 64, 4)`` holding K terms in the layout above."""
    n = factors.resolution
    if n != FACTOR_RESOLUTION:
        raise ValueError(f"factors must be {FACTOR_RESOLUTION} texels per axis to fill a slice, got {n}")
    k = factors.terms
    out = np.zeros((k, n, 2 * n, 4))
    out[:, :, :n, :3] = factors.g.transpose(0, 2, 1)[:, None, :, :]
    out[:, :, n:, :3] = factors.h.transpose(0, 2, 3, 1)
    return out


def encode_factor_slices(values: np.ndarray):
    """Map float slices into [0, 1] with one scale and bias per term, factor and channel.

    Returns
    -------
    stored : ndarray (K, 32, 64, 4) in [0, 1]
    scale, bias : ndarray (K, 2, 3)
        value = stored * scale + bias; factor 0 = g (left half), 1 = h (right half).
    clamped_fraction : float
        Share of texels outside [0, 1] before clipping (0 unless values are non-finite).
    """
    k = values.shape[0]
    half = values.shape[2] // 2
    scale = np.ones((k, 2, 3))
    bias = np.zeros((k, 2, 3))
    stored = np.zeros_like(values)
    outside = 0
    for factor, cols in enumerate((slice(0, half), slice(half, None))):
        block = values[:, :, cols, :3]
        lo = block.min(axis=(1, 2))
        hi = block.max(axis=(1, 2))
        signed = lo < 0.0
        b = np.where(signed, lo, 0.0)
        span = np.where(signed, hi - lo, hi)
        s = np.where(span > 0.0, span, 1.0)
        # float32 values: exactly what the manifest and the shader's f32 constants hold.
        s = s.astype(np.float32).astype(np.float64)
        b = b.astype(np.float32).astype(np.float64)
        scale[:, factor] = s
        bias[:, factor] = b
        scaled = (block - b[:, None, None, :]) / s[:, None, None, :]
        outside += int(np.count_nonzero((scaled < -1e-6) | (scaled > 1.0 + 1e-6)))
        stored[:, :, cols, :3] = np.clip(scaled, 0.0, 1.0)
    return stored, scale, bias, outside / max(values[..., :3].size, 1)


def quantize_factors(factors: Factors, srgb: bool = True) -> Factors:
    """The factors as an 8-bit atlas returns them: encode, round to UNORM8, decode, rescale.

    RGB is sRGB-encoded when ``srgb`` (the default atlas encoding, IEC 61966-2-1), by
    :func:`atlasgen.optics.quantize.quantize_rgba` as the bake does; used to judge
    candidates on what is actually stored.
    """
    stored, scale, bias, _ = encode_factor_slices(factors_to_slices(factors))
    decoded = dequantize_rgba(quantize_rgba(stored, srgb), srgb)
    return factors_from_slices(decoded, scale, bias, factors.parametrization, factors.target)
