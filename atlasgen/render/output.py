"""Writing renders: a linear float EXR with a display PNG beside it, and g-buffer layers as EXR.

The files are encoded by :mod:`atlasgen.io.images` and replaced atomically
(:mod:`atlasgen.io.atomic`): a failed write never leaves a half-written image or an EXR
without its PNG. Radiance is made finite before it is
written (:func:`finite_radiance`), so no render ever holds a NaN or infinite pixel.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from atlasgen.io.atomic import write_files_atomically
from atlasgen.io.images import encode_exr, encode_png
from atlasgen.optics.display import display_aces
from atlasgen.optics.quantize import quantize_rgba

__all__ = ["finite_radiance", "display_codes", "render_png", "write_render", "write_aov", "aov_channels"]

#: The largest value of the renderer's ``rgba16float`` HDR target (IEEE half).
HDR_MAX = 65504.0


def finite_radiance(radiance) -> np.ndarray:
    """float32 radiance with NaN as 0 and everything else clamped to [-HDR_MAX, HDR_MAX].

    Lights or materials far beyond the HDR target's range overflow it to infinity, and
    infinity times zero is NaN; clamping to the half-float range is what the target does
    where it saturates instead, so such pixels are as bright as it can hold.
    """
    values = np.asarray(radiance, dtype=np.float32)
    return np.clip(np.nan_to_num(values, nan=0.0, posinf=HDR_MAX, neginf=-HDR_MAX), -HDR_MAX, HDR_MAX)


def _display_codes(radiance, exposure: float) -> np.ndarray:
    return quantize_rgba(display_aces(finite_radiance(radiance), exposure), srgb=False)


@functools.lru_cache(maxsize=8)
def _half_float_codes(exposure: float) -> np.ndarray:
    """:func:`_display_codes` of every IEEE half, indexed by its bits (65536 uint8)."""
    every_half = np.arange(1 << 16, dtype=np.uint16).view(np.float16).astype(np.float32)
    codes = _display_codes(every_half.reshape(1, -1, 1), exposure).reshape(-1)
    codes.flags.writeable = False
    return codes


def display_codes(radiance: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """``(h, w, 3)`` linear radiance as 8-bit sRGB codes for viewing: :func:`~atlasgen.optics.display.display_aces`.

    Every step is per value, so radiance read back from the ``rgba16float`` HDR target (every
    value a half) is mapped through a table of all 65536 halves' codes, the same codes as the
    formula gives each value, for a fraction of its cost; other radiance goes through the formula.
    """
    values = np.asarray(radiance)
    if values.dtype == np.float32 and values.size > (1 << 16):
        halves = values.astype(np.float16)
        if np.array_equal(halves.astype(np.float32), values, equal_nan=True):
            return _half_float_codes(float(exposure))[halves.view(np.uint16)]
    return _display_codes(values, exposure)


def render_png(radiance: np.ndarray, exposure: float = 1.0, near=None) -> bytes:
    """PNG bytes of :func:`display_codes` (``near``: the output they are for, :func:`atlasgen.io.images.encode_png`)."""
    return encode_png(display_codes(radiance, exposure), near=near)


def write_render(exr_path, radiance: np.ndarray, exposure: float = 1.0, extra: dict | None = None,
                 writer: str | None = None) -> list[Path]:  # fmt: skip
    """The linear float32 EXR and, beside it, the PNG (:func:`render_png`, same stem): both replaced, or neither.

    One commit (:func:`atlasgen.io.atomic.write_files_atomically`), the PNG its primary: it is
    what the Makefile's render rule targets, so a killed run leaves it stale and is run again.
    ``extra``: more files of the same commit (path: bytes), such as the render's depfile; ``writer``: the
    command's name in a set it may share (:func:`atlasgen.io.atomic.write_files_atomically`).
    """
    exr_path = Path(exr_path)
    png_path = exr_path.with_suffix(".png")
    write_files_atomically(
        {exr_path: encode_exr(finite_radiance(radiance), near=exr_path), png_path: render_png(radiance, exposure, near=png_path),
         **(extra or {})},
        primary=png_path,
        writer=writer,
    )  # fmt: skip
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


def write_aov(path, name: str, value: np.ndarray, extra: dict | None = None, writer: str | None = None) -> None:
    """One g-buffer layer as a float32 OpenEXR (see :func:`aov_channels`), in one commit that also
    removes the PNG an earlier render wrote beside it: that PNG shows a lit image this EXR no longer holds.
    ``extra``: more files of the same commit (path: bytes); ``writer`` as :func:`write_render`'s."""
    path = Path(path)
    write_files_atomically({path: encode_exr(*aov_channels(name, value), near=path), **(extra or {})}, primary=path,
                           remove=[path.with_suffix(".png")], writer=writer)  # fmt: skip
