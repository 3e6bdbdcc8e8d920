"""Image files: 8-bit PNG and float OpenEXR, both encoded by OpenImageIO.

One writer per format, arguments in one order, ``write_*(path, pixels)``, as every writer
in :mod:`atlasgen.io` takes them. PNG takes 8-bit codes only: turning floats into codes
(rounding, sRGB encoding, tone mapping) is :mod:`atlasgen.optics.quantize` and
:mod:`atlasgen.optics.display`, not a file format's business. Files are replaced
atomically (:mod:`atlasgen.io.atomic`); the ``encode_*`` functions return the bytes for
callers that write several files all-or-nothing.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

import numpy as np

from atlasgen.errors import OutputError
from atlasgen.io.atomic import remove_stale_temporaries, scratch_folder, write_file_atomically
from atlasgen.io.oiio import import_oiio
from atlasgen.io.referenced_files import real_folder_path
from atlasgen.io.text import path_kind

__all__ = [
    "PNG_SIGNATURE",
    "encode_png",
    "encode_exr",
    "write_png",
    "write_exr",
    "is_png_file",
    "is_utf8_path",
    "openable_name",
    "error_text",
]

#: A PNG file's first eight bytes (ISO/IEC 15948, 5.2).
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def is_png_file(path) -> bool:
    """Whether ``path`` is a regular file that starts with :data:`PNG_SIGNATURE` (a named pipe or device is not read:
    :func:`atlasgen.io.text.path_kind`)."""
    if path_kind(path) is not None:
        return False
    try:
        with open(path, "rb") as file:
            return file.read(len(PNG_SIGNATURE)) == PNG_SIGNATURE
    except OSError:
        return False


def _encode(pixels: np.ndarray, pixel_type: str, suffix: str, channel_names=None, attributes=None, near=None) -> bytes:
    """The bytes of ``pixels`` ``(h, w, c)`` as an OpenImageIO-written file of format ``suffix``.

    OpenImageIO writes to a path, so the file is made in a private scratch folder and read
    back: beside ``near`` (the output the bytes are for, :func:`atlasgen.io.atomic.scratch_folder`),
    so that a failure names the output and needs room only where the output goes; in the
    system's temporary folder when ``near`` is None.
    """
    oiio = import_oiio()

    h, w, c = pixels.shape
    spec = oiio.ImageSpec(w, h, c, pixel_type)
    if channel_names is not None:
        spec.channelnames = tuple(channel_names)
    if suffix == ".exr":
        spec.attribute("compression", "zip")
        # OpenImageIO stamps EXRs with the current time unless DateTime is set; an empty
        # value writes none, so the same pixels give the same bytes.
        spec.attribute("DateTime", "")
    for name, value in (attributes or {}).items():
        spec.attribute(name, value)
    shown = f"{Path(near).as_posix()}: cannot write" if near is not None else f"cannot encode a {suffix} image"
    # OpenImageIO takes UTF-8 names only (pybind11 refused a folder named with byte 0xff, an internal error):
    # beside such an output, the scratch file goes to the system's temporary folder.
    beside = near is not None and is_utf8_path(near)
    scratch = scratch_folder(near) if beside else _system_scratch()
    with scratch as folder:
        path = str(Path(folder) / f"image{suffix}")
        out = oiio.ImageOutput.create(path)
        if out is None or not out.open(path, spec):
            raise OutputError(f"{shown} ({error_text(oiio.geterror, 'unknown format')})")
        ok = out.write_image(np.ascontiguousarray(pixels))
        error = error_text(out.geterror, "")
        closed = out.close()
        if not ok or not closed:
            error = error or error_text(out.geterror, "the encoder failed")
            # OpenImageIO names its own file, the scratch copy; the user's file is the output.
            raise OutputError(f"{shown} ({error.replace(path, Path(near).as_posix()) if near is not None else error})")
        # A failure in the last flush, at close, is not reported (OpenImageIO's close returns True): with the
        # file size limit at 4 KiB a 5 KB EXR came back cut at 4096 bytes and was committed. What is returned
        # must decode whole, to the shape written.
        problem = _decode_problem(oiio, path, pixels.shape)
        if problem is not None:
            raise OutputError(f"{shown} (the file written does not read back: {problem})")
        try:
            return Path(path).read_bytes()
        except OSError as exc:
            raise OutputError(f"{shown} ({exc.strerror})") from None


def _system_scratch():
    """A private folder in the system's temporary folder, named by this process as the commit's temporaries are, after
    removing those of processes that are gone: a kill (or a Ctrl-C during the clean-up) left an
    ``atlasgen-image-<random>`` folder there that no later run removed."""
    stand_in = Path(tempfile.gettempdir()) / "atlasgen-image"
    remove_stale_temporaries(stand_in)
    return scratch_folder(stand_in)


def error_text(geterror, default: str) -> str:
    """OpenImageIO's pending error as one line, or ``default`` where there is none.

    Its Python binding decodes the message as UTF-8 and raised UnicodeDecodeError where the message
    quotes a file's own bytes (an EXR whose attribute name holds byte 0xff): an internal error, where
    the user's file is what is wrong.

    >>> error_text(lambda: "bad\\n header  ", "unreadable"), error_text(lambda: "", "unreadable")
    ('bad header', 'unreadable')

    A line it repeats (a truncated EXR's "End of file" came twice, for each attempt to read it) is given once:

    >>> error_text(lambda: "End of file\\nEnd of file\\nBad header", "unreadable")
    'End of file Bad header'
    >>> error_text(lambda: b"\\xff".decode("utf-8"), "unreadable")
    'unreadable (its message quotes bytes that are not UTF-8)'
    """
    try:
        text = geterror()
    except UnicodeDecodeError:
        return f"{default} (its message quotes bytes that are not UTF-8)"
    lines = dict.fromkeys(" ".join(line.split()) for line in text.splitlines())
    return " ".join(line for line in lines if line) or default


def is_utf8_path(path) -> bool:
    """Whether ``path``'s bytes are UTF-8, which OpenImageIO's Python names must be.

    >>> import os
    >>> is_utf8_path("sky.exr"), is_utf8_path(os.fsdecode(b"\\xffd/sky.exr"))
    (True, False)
    """
    try:
        os.fsencode(os.fspath(path)).decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


@contextlib.contextmanager
def openable_name(path):
    """A name OpenImageIO can open for the file at ``path``: ``path`` itself, or where its bytes are no UTF-8,
    a link to it with an ASCII name in a temporary folder (the file is read where it is, not copied)."""
    if is_utf8_path(path):
        yield str(path)
        return
    with tempfile.TemporaryDirectory(prefix="atlasgen-image-") as folder:
        suffix = "".join(c for c in Path(path).suffix if c.isascii())
        link = Path(folder) / f"image{suffix}"
        # Its folder as the system finds it: abspath folds a "link/.." as text, and the link led to another file.
        os.symlink(real_folder_path(path), link)
        yield str(link)


def _decode_problem(oiio, path: str, shape) -> str | None:
    """None where the image file at ``path`` decodes whole to ``shape`` ``(h, w, c)``, else what is wrong."""
    image = oiio.ImageInput.open(path)
    if image is None:
        return error_text(oiio.geterror, "unreadable")
    try:
        pixels = image.read_image()
        error = error_text(image.geterror, "")
    finally:
        image.close()
    if pixels is None or error:
        return error or "its pixels do not decode"
    got = np.shape(pixels) if np.ndim(pixels) == 3 else (*np.shape(pixels), 1)
    return None if tuple(got) == tuple(shape) else f"{got} pixels, expected {tuple(shape)}"


def encode_png(codes: np.ndarray, near=None, compression: int | None = None) -> bytes:
    """PNG bytes of 8-bit codes ``(h, w, c)``: c = 1 (grey), 2 (grey, alpha), 3 (RGB) or 4 (RGBA).

    The codes are stored as given, alpha straight (not premultiplied), as PNG defines it;
    the PNG carries no colour profile, so viewers read the colour as sRGB. ``compression`` is
    zlib's level, 0 (none, fastest) to 9 (smallest); None: the encoder's default, 6. The same
    codes at the same level give the same bytes.
    """
    codes = np.asarray(codes)
    if codes.dtype != np.uint8 or codes.ndim != 3 or not 1 <= codes.shape[2] <= 4:
        raise TypeError(f"expected 8-bit codes shaped (h, w, 1..4), got {codes.dtype} {codes.shape}")
    # PNG's alpha is straight; OpenImageIO would otherwise take the codes as premultiplied
    # and divide the colour by alpha.
    attributes = {"oiio:UnassociatedAlpha": 1} if codes.shape[2] in (2, 4) else {}
    if compression is not None:
        if not 0 <= compression <= 9:
            raise ValueError(f"PNG compression must be a zlib level from 0 to 9, not {compression!r}")
        attributes["png:compressionLevel"] = int(compression)
    return _encode(codes, "uint8", ".png", attributes=attributes, near=near)


def encode_exr(pixels: np.ndarray, channel_names=("R", "G", "B"), near=None) -> bytes:
    """OpenEXR bytes of ``(h, w, c)`` pixels as float32, ZIP-compressed, with the given channel names;
    ``near``: the output they are for (encoded beside it, and named by a failure)."""
    pixels = np.asarray(pixels, dtype=np.float32)
    if pixels.ndim != 3 or pixels.shape[2] != len(channel_names):
        raise ValueError(
            f"expected pixels shaped (h, w, {len(channel_names)}) for channels {tuple(channel_names)}, got {pixels.shape}"
        )
    return _encode(pixels, "float", ".exr", channel_names, near=near)


def write_png(path, codes: np.ndarray) -> None:
    """Write 8-bit codes as a PNG (:func:`encode_png`), replacing ``path`` atomically."""
    write_file_atomically(path, encode_png(codes, near=path))


def write_exr(path, pixels: np.ndarray, channel_names=("R", "G", "B")) -> None:
    """Write float pixels as a float32 OpenEXR (:func:`encode_exr`), replacing ``path`` atomically."""
    write_file_atomically(path, encode_exr(pixels, channel_names, near=path))
