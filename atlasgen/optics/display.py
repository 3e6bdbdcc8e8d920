"""Display transforms: linear radiance to sRGB-encoded display values in [0, 1].

Two transforms, for two purposes:

- :func:`display_aces` is for looking at renders: a filmic curve rolls highlights off
  smoothly instead of clipping them, so a PNG beside a render's EXR shows its bright
  parts. The curve bends every value, so it is not used to measure errors.
- :func:`display_clip` is for measuring: the image metrics (RMSE, PSNR, FLIP) and the
  validation report's images compare what an sRGB display shows of the exposed
  radiance, value for value below 1; only what the display cannot show is clipped.

Both end in the sRGB transfer function (IEC 61966-2-1); 8-bit codes come from
:func:`atlasgen.optics.quantize.quantize_rgba` (``srgb=False``: already encoded).
"""

from __future__ import annotations

import numpy as np

from atlasgen.optics.srgb import encode_srgb

__all__ = ["display_aces", "display_clip"]


def display_aces(linear, exposure: float = 1.0) -> np.ndarray:
    """Narkowicz's ACES fit, then sRGB: encode_srgb(clip(x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14), 0, 1)).

    x = max(exposure * L, 0) (K. Narkowicz, "ACES Filmic Tone Mapping Curve", 2015).
    NaN maps to 0 and +inf to white, so a broken pixel never breaks the image.
    """
    x = np.maximum(np.nan_to_num(np.asarray(linear, dtype=np.float64) * exposure, nan=0.0, posinf=1e6), 0.0)
    y = np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)
    return encode_srgb(y)


def display_clip(linear, exposure: float = 1.0) -> np.ndarray:
    """encode_srgb(clip(exposure * L, 0, 1)): the exposed radiance as an sRGB display shows it.

    NaN maps to 0 so a broken pixel shows as an error, never as a crash; +inf to 1.
    """
    x = np.nan_to_num(np.asarray(linear, dtype=np.float64) * float(exposure), nan=0.0, posinf=1.0, neginf=0.0)
    return encode_srgb(np.clip(x, 0.0, 1.0))
