"""8-bit quantisation of atlas levels, and its exact inverse as a GPU sampler applies it."""

from __future__ import annotations

import numpy as np

from atlasgen.optics.srgb import SRGB_DECODE_LUT, encode_srgb

__all__ = ["quantize_rgba", "dequantize_rgba"]


def quantize_rgba(linear: np.ndarray, srgb: bool) -> np.ndarray:
    """Linear RGBA in [0, 1] to RGBA8; RGB sRGB-encoded when ``srgb``, alpha always linear.

    Rounds to nearest (``np.rint``), as D3D's float-to-UNORM conversion does.
    """
    x = np.clip(linear, 0.0, 1.0)
    if srgb:
        x = x.copy()
        x[..., :3] = encode_srgb(x[..., :3])
    return np.rint(x * np.float32(255.0) if x.dtype == np.float32 else x * 255.0).astype(np.uint8)


def dequantize_rgba(texels: np.ndarray, srgb: bool) -> np.ndarray:
    """RGBA8 to the linear floats a sampler returns (sRGB decoded for RGB when ``srgb``)."""
    out = texels.astype(np.float64) / 255.0
    if srgb:
        out[..., :3] = SRGB_DECODE_LUT[texels[..., :3]]
    return out
