"""Writing renders: a linear float EXR and a tone-mapped sRGB PNG, both through OpenImageIO."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import OutputError

__all__ = ["tone_map", "write_exr", "write_png", "write_aov", "aov_channels"]


def tone_map(radiance: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Linear radiance to 8-bit sRGB for display.

    y = x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14) with x = exposure * L, clamped to
    [0, 1] (K. Narkowicz, "ACES Filmic Tone Mapping Curve", 2015), then the sRGB transfer
    function (IEC 61966-2-1) and rounding to nearest.
    """
    from ..srgb import encode_srgb

    x = np.maximum(np.nan_to_num(np.asarray(radiance, dtype=np.float64) * exposure, nan=0.0, posinf=1e6), 0.0)
    y = np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)
    return np.rint(encode_srgb(y) * 255.0).astype(np.uint8)


def _write(path, pixels: np.ndarray, channel_names, pixel_type) -> None:
    import OpenImageIO as oiio

    path = Path(path)
    if not path.parent.exists():
        raise OutputError(f"{path.as_posix()}: folder {path.parent.as_posix()!r} does not exist")
    h, w, c = pixels.shape
    spec = oiio.ImageSpec(w, h, c, pixel_type)
    spec.channelnames = tuple(channel_names)
    if path.suffix.lower() == ".exr":
        spec.attribute("compression", "zip")
    out = oiio.ImageOutput.create(str(path))
    if out is None or not out.open(str(path), spec):
        raise OutputError(f"{path.as_posix()}: cannot write ({oiio.geterror() or 'unknown format'})")
    ok = out.write_image(np.ascontiguousarray(pixels))
    out.close()
    if not ok:
        raise OutputError(f"{path.as_posix()}: cannot write ({out.geterror()})")


def write_exr(path, radiance: np.ndarray) -> None:
    """Linear radiance ``(h, w, 3)`` as a float32 RGB OpenEXR."""
    _write(path, np.asarray(radiance, dtype=np.float32), ("R", "G", "B"), "float")


def write_png(path, radiance: np.ndarray, exposure: float = 1.0) -> None:
    """``(h, w, 3)`` linear radiance, tone-mapped with :func:`tone_map`, as an 8-bit sRGB PNG."""
    _write(path, tone_map(radiance, exposure), ("R", "G", "B"), "uint8")


def aov_channels(name: str, value: np.ndarray) -> tuple[np.ndarray, tuple]:
    """A g-buffer layer as float32 pixels and EXR channel names.

    ``normal`` -> N.x, N.y, N.z; ``depth`` -> Z (view depth, +inf where empty);
    ``id`` -> id (material slice, 65535 where empty); ``albedo`` -> R, G, B.
    """
    value = np.asarray(value)
    if name == "normal":
        return value.astype(np.float32), ("N.x", "N.y", "N.z")
    if name == "albedo":
        return value.astype(np.float32), ("R", "G", "B")
    if name == "depth":
        return value.astype(np.float32)[..., None], ("Z",)
    if name == "id":
        return value.astype(np.float32)[..., None], ("id",)
    raise ValueError(f"unknown AOV {name!r}")


def write_aov(path, name: str, value: np.ndarray) -> None:
    """One g-buffer layer as a float32 OpenEXR (see :func:`aov_channels`)."""
    pixels, channels = aov_channels(name, value)
    _write(path, pixels, channels, "float")
