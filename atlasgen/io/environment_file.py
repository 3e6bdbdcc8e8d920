"""Reading an equirectangular environment image (OpenEXR or Radiance HDR) and checking it.

The image is radiance in W/(m^2 sr), in Mitsuba's ``envmap`` layout
(:mod:`atlasgen.optics.equirect`): twice as wide as high, RGB or RGBA. Alpha is ignored, as
Mitsuba's ``envmap`` ignores it (it reads the stored RGB; tests/io/test_environment_file.py
checks against Mitsuba). Every refusal is one line naming the file and what was expected.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from atlasgen.errors import FieldError, InputError
from atlasgen.io.images import error_text, openable_name
from atlasgen.io.oiio import import_oiio
from atlasgen.io.text import MISSING, path_kind

__all__ = ["ENVIRONMENT_SUFFIXES", "MIN_ENVIRONMENT_HEIGHT", "MAX_ENVIRONMENT_HEIGHT", "read_environment_file"]

#: The file types an environment may be, by suffix (lower case).
ENVIRONMENT_SUFFIXES = (".exr", ".hdr")
#: Fewest rows: 4 rows (8x4) put a row at each pole and two in between.
MIN_ENVIRONMENT_HEIGHT = 4
#: Most rows: an 8K image (8192x4096). Its float64 copies while it is resampled take a few GB already; a
#: 16K one took 8 GB, and a small compressed file can declare one. The renderer shades with a 256x128 copy.
MAX_ENVIRONMENT_HEIGHT = 4096
#: OpenImageIO's names of those formats.
_FORMATS = {"openexr": "OpenEXR", "hdr": "Radiance HDR"}


def _where(pixels: np.ndarray, bad: np.ndarray) -> str:
    rows, cols = np.nonzero(bad.any(axis=-1))
    return f"{int(bad.any(axis=-1).sum())} texels, the first at row {int(rows[0])}, column {int(cols[0])}"


def read_environment_file(path, error: type[FieldError] = FieldError) -> np.ndarray:
    """The radiance of an equirectangular OpenEXR or Radiance HDR image, float32 ``(H, W, 3)``.

    Raises
    ------
    InputError
        ``path: no such environment image`` where there is no such file.
    FieldError
        ``error`` (e.g. :class:`~atlasgen.errors.SceneError`), one line naming ``path``: not an
        .exr or .hdr file, not readable as one, not RGB(A), not half or float, not 2:1, fewer than 4 rows, or
        larger than :data:`MAX_ENVIRONMENT_HEIGHT`, or holding a non-finite or negative value (the message
        says how many and where).
    """
    oiio = import_oiio()

    shown = Path(path).as_posix()
    if Path(path).suffix.lower() not in ENVIRONMENT_SUFFIXES:
        raise error(shown, None, f"expected an OpenEXR (.exr) or Radiance HDR (.hdr) environment image, got {Path(path).name!r}")
    kind = path_kind(path)
    if kind == MISSING:
        raise InputError(f"{shown}: no such environment image")
    if kind is not None:
        raise error(shown, None, f"expected an OpenEXR or Radiance HDR image, got {kind}")
    with openable_name(path) as name:  # OpenImageIO refused a name that is no UTF-8: an internal error
        inp = oiio.ImageInput.open(name)
    if inp is None:
        reason = error_text(oiio.geterror, "unreadable")
        raise error(shown, None, f"expected an OpenEXR or Radiance HDR image ({reason})")
    try:
        kind = inp.format_name()
        spec = inp.spec()
        if kind not in _FORMATS:
            raise error(shown, None, f"expected an OpenEXR or Radiance HDR image, got a {kind} image")
        if spec.deep:
            # read_image flattened nothing: most texels came back as 0, others as a different NaN each run.
            raise error(shown, None, "expected a flat image, got a deep OpenEXR (samples per pixel)")
        names = tuple(spec.channelnames)
        if spec.nchannels not in (3, 4) or names[:3] != ("R", "G", "B"):
            raise error(shown, None, f"expected RGB or RGBA channels, got {', '.join(names) or 'none'}")
        # Radiance is a float: OpenImageIO reads integer channels (an EXR's uint, kept for IDs) as a fraction
        # of their range, and 50 came back as 1.2e-8, a black sky rendered without a word.
        formats = [str(f) for f in (tuple(spec.channelformats) or (spec.format,) * spec.nchannels)][:3]
        if any(f not in ("half", "float") for f in formats):
            raise error(shown, None, f"expected half or float colour channels, got {', '.join(formats)}")
        if spec.width != 2 * spec.height:
            raise error(shown, None, f"expected an equirectangular image twice as wide as high, got {spec.width}x{spec.height}")
        if spec.height < MIN_ENVIRONMENT_HEIGHT:
            raise error(shown, None, f"expected at least {2 * MIN_ENVIRONMENT_HEIGHT}x{MIN_ENVIRONMENT_HEIGHT} texels, "
                                     f"got {spec.width}x{spec.height}")  # fmt: skip
        if spec.height > MAX_ENVIRONMENT_HEIGHT:
            raise error(shown, None, f"expected at most {2 * MAX_ENVIRONMENT_HEIGHT}x{MAX_ENVIRONMENT_HEIGHT} texels "
                                     f"(downsample it first), got {spec.width}x{spec.height}")  # fmt: skip
        pixels = inp.read_image(0, 0, 0, 3, oiio.FLOAT)
        if pixels is None:
            reason = error_text(inp.geterror, "unreadable")
            raise error(shown, None, f"expected a readable {_FORMATS[kind]} image ({reason})")
    finally:
        inp.close()
    pixels = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, 3)
    finite = np.isfinite(pixels)
    if not finite.all():
        raise error(shown, None, f"expected finite radiance, got NaN or infinity in {_where(pixels, ~finite)}")
    if (pixels < 0.0).any():
        raise error(shown, None, f"expected non-negative radiance, got negative values in {_where(pixels, pixels < 0.0)}")
    return pixels
