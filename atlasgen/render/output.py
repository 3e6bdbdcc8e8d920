"""Writing renders: a linear float EXR and a tone-mapped sRGB PNG, both through OpenImageIO.

Files are replaced atomically (:mod:`atlasgen.io.atomic`): a failed write never leaves a
half-written image or an EXR without its PNG. Radiance is made finite before it is
written (:func:`finite_radiance`), so no render ever holds a NaN or infinite pixel.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from atlasgen.io.atomic import write_files_atomically
from atlasgen.errors import OutputError

__all__ = ["finite_radiance", "tone_map", "encode_image", "write_exr", "write_png", "write_render", "write_aov", "aov_channels"]


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


def tone_map(radiance: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """Linear radiance to 8-bit sRGB for display.

    y = x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14) with x = exposure * L, clamped to
    [0, 1] (K. Narkowicz, "ACES Filmic Tone Mapping Curve", 2015), then the sRGB transfer
    function (IEC 61966-2-1) and rounding to nearest.
    """
    from atlasgen.optics.srgb import encode_srgb

    x = np.maximum(np.nan_to_num(np.asarray(radiance, dtype=np.float64) * exposure, nan=0.0, posinf=1e6), 0.0)
    y = np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)
    return np.rint(encode_srgb(y) * 255.0).astype(np.uint8)


def encode_image(pixels: np.ndarray, channel_names, pixel_type: str, suffix: str) -> bytes:
    """The bytes of an image file (format from ``suffix``: ``.exr`` or ``.png``) written by OpenImageIO.

    OpenImageIO writes to a path, so the file is made in a private temporary folder
    and read back; callers then place it atomically.
    """
    import tempfile

    import OpenImageIO as oiio

    h, w, c = pixels.shape
    spec = oiio.ImageSpec(w, h, c, pixel_type)
    spec.channelnames = tuple(channel_names)
    if suffix == ".exr":
        spec.attribute("compression", "zip")
        # OpenImageIO stamps EXRs with the current time unless DateTime is set; an empty
        # value writes none, so the same render gives the same bytes.
        spec.attribute("DateTime", "")
    with tempfile.TemporaryDirectory(prefix="atlasgen-image-") as folder:
        path = str(Path(folder) / f"image{suffix}")
        out = oiio.ImageOutput.create(path)
        if out is None or not out.open(path, spec):
            raise OutputError(f"cannot encode a {suffix} image ({oiio.geterror() or 'unknown format'})")
        ok = out.write_image(np.ascontiguousarray(pixels))
        error = out.geterror()
        out.close()
        if not ok:
            raise OutputError(f"cannot encode a {suffix} image ({error})")
        return Path(path).read_bytes()


def _exr_bytes(radiance) -> bytes:
    return encode_image(finite_radiance(radiance), ("R", "G", "B"), "float", ".exr")


def _png_bytes(radiance, exposure) -> bytes:
    return encode_image(tone_map(finite_radiance(radiance), exposure), ("R", "G", "B"), "uint8", ".png")


def write_exr(path, radiance: np.ndarray) -> None:
    """Linear radiance ``(h, w, 3)`` as a float32 RGB OpenEXR (replaced atomically)."""
    write_files_atomically({Path(path): _exr_bytes(radiance)})


def write_png(path, radiance: np.ndarray, exposure: float = 1.0) -> None:
    """``(h, w, 3)`` linear radiance, tone-mapped with :func:`tone_map`, as an 8-bit sRGB PNG."""
    write_files_atomically({Path(path): _png_bytes(radiance, exposure)})


def write_render(exr_path, radiance: np.ndarray, exposure: float = 1.0) -> list[Path]:
    """The EXR and, beside it, the PNG (same stem): both replaced, or neither.

    The PNG is renamed into place last: it is what the Makefile's render rule targets,
    so a run killed between the two renames is run again.
    """
    exr_path = Path(exr_path)
    png_path = exr_path.with_suffix(".png")
    write_files_atomically({exr_path: _exr_bytes(radiance), png_path: _png_bytes(radiance, exposure)}, primary=png_path)
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
    pixels, channels = aov_channels(name, value)
    write_files_atomically({Path(path): encode_image(pixels, channels, "float", ".exr")})
