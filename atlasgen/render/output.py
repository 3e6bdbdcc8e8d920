"""Writing renders: a linear float EXR with a display PNG beside it, and g-buffer layers as EXR.

The files are encoded by :mod:`atlasgen.io.images` and replaced atomically
(:mod:`atlasgen.io.atomic`): a failed write never leaves a half-written image or an EXR
without its PNG.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from atlasgen.io.atomic import write_files_atomically
from atlasgen.io.images import encode_exr, encode_png, write_exr
from atlasgen.optics.display import display_aces
from atlasgen.optics.quantize import quantize_rgba

__all__ = ["render_png", "write_render", "write_aov", "aov_channels"]


def render_png(radiance: np.ndarray, exposure: float = 1.0) -> bytes:
    """PNG bytes of ``(h, w, 3)`` linear radiance for viewing: :func:`~atlasgen.optics.display.display_aces`, 8 bits."""
    return encode_png(quantize_rgba(display_aces(radiance, exposure), srgb=False))


def write_render(exr_path, radiance: np.ndarray, exposure: float = 1.0) -> list[Path]:
    """The linear float32 EXR and, beside it, the PNG (:func:`render_png`, same stem): both replaced, or neither."""
    exr_path = Path(exr_path)
    png_path = exr_path.with_suffix(".png")
    write_files_atomically({exr_path: encode_exr(radiance), png_path: render_png(radiance, exposure)})
    return [exr_path, png_path]


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
    """One g-buffer layer as a float32 OpenEXR (see :func:`aov_channels`), replaced atomically."""
    write_exr(path, *aov_channels(name, value))
