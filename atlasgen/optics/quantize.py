"""8-bit quantisation (UNORM8, linear or sRGB) and its exact inverse as a GPU sampler applies it.

The one encoding to and decoding from 8-bit codes: atlas levels, separable factors judged
on what is stored, and display images on their way to PNG all go through it.
"""

from __future__ import annotations

import numpy as np

from atlasgen.optics.srgb import SRGB_DECODE_LUT, encode_srgb

__all__ = ["quantize_rgba", "dequantize_rgba", "unorm_scale"]


def unorm_scale(peak: float) -> float:
    """The scale that maps [0, ``peak``] onto all of UNORM8's codes: the smallest float32 >= ``peak``
    (the include's constants are f32, so stored * scale is what a shader computes, and nothing
    reaches above 1), or 1 when ``peak`` is 0 (or not positive and finite)."""
    peak = float(peak)
    if not (peak > 0.0 and np.isfinite(peak)):
        return 1.0
    scale = np.float32(peak)
    if float(scale) < peak:
        scale = np.nextafter(scale, np.float32(np.inf))
    return float(scale)


def quantize_rgba(linear: np.ndarray, srgb: bool) -> np.ndarray:
    """Linear RGBA (or RGB) in [0, 1] to 8-bit codes; RGB sRGB-encoded when ``srgb``, alpha always linear.

    code = rint(255 clip(x, 0, 1)), rounding to nearest as D3D's float-to-UNORM conversion
    does; with ``srgb`` the first three channels are encoded by :func:`encode_srgb` first.
    Values already display-encoded (:mod:`atlasgen.optics.display`) use ``srgb=False``.
    """
    x = np.clip(linear, 0.0, 1.0)
    if srgb:
        x = x.copy()
        x[..., :3] = encode_srgb(x[..., :3])
    return np.rint(x * np.float32(255.0) if x.dtype == np.float32 else x * 255.0).astype(np.uint8)


def dequantize_rgba(texels: np.ndarray, srgb: bool) -> np.ndarray:
    """8-bit codes (RGBA or RGB) to the floats a sampler returns: code / 255, or the sRGB decode of RGB when ``srgb``."""
    out = texels.astype(np.float64) / 255.0
    if srgb:
        out[..., :3] = SRGB_DECODE_LUT[texels[..., :3]]
    return out
