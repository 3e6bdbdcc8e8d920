"""The sRGB transfer function (IEC 61966-2-1), as GPUs apply it to *_SRGB formats."""

from __future__ import annotations

import numpy as np

__all__ = ["encode_srgb", "decode_srgb", "SRGB_DECODE_LUT"]


def encode_srgb(linear):
    """Linear [0, 1] to sRGB-encoded [0, 1].

    c = 12.92 L for L <= 0.0031308, else 1.055 L^(1/2.4) - 0.055 (IEC 61966-2-1, eq. 5).
    """
    x = np.asarray(linear)
    if x.dtype != np.float32:  # float32 stays float32: the atlas's own mips are built in it
        x = x.astype(np.float64)
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, x * 12.92, np.power(x, 1.0 / 2.4) * 1.055 - 0.055).astype(x.dtype, copy=False)


def decode_srgb(encoded):
    """sRGB-encoded [0, 1] to linear [0, 1].

    L = c / 12.92 for c <= 0.04045, else ((c + 0.055) / 1.055)^2.4 (IEC 61966-2-1, eq. 4).
    """
    c = np.asarray(encoded, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, np.power((c + 0.055) / 1.055, 2.4))


#: Linear value of each 8-bit sRGB code, as a sampler returns it.
SRGB_DECODE_LUT = decode_srgb(np.arange(256) / 255.0)
