"""A labelled contact sheet of the atlas's used slices, written as PNG with OpenImageIO."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from atlasgen.contract import HEIGHT, WIDTH
from atlasgen.errors import OutputError
from atlasgen.optics.srgb import encode_srgb

__all__ = ["render_contact_sheet", "slice_display_image", "encode_png", "write_png"]

ZOOM = 2
COLUMNS = 4
LABEL_H = 18
PAD = 6


def slice_display_image(level0: np.ndarray, slice_index: int, srgb: bool) -> np.ndarray:
    """Display RGB in [0, 1] of one stored slice: its RGB then its alpha in grey, side by side.

    N.V = 1 (facing) is at the top, as an artist reads it.
    """
    texels = level0[slice_index].astype(np.float64) / 255.0
    rgb = texels[..., :3] if srgb else encode_srgb(texels[..., :3])
    alpha = np.repeat(texels[..., 3:4], 3, axis=2)
    return np.concatenate([rgb, alpha], axis=1)[::-1]


def encode_png(image: np.ndarray, zoom: int = 1) -> bytes:
    """8-bit PNG bytes of display RGB in [0, 1] (nearest-neighbour ``zoom``), by OpenImageIO."""
    import OpenImageIO as oiio

    if zoom > 1:
        image = np.kron(image, np.ones((zoom, zoom, 1)))
    buf = oiio.ImageBuf(oiio.ImageSpec(image.shape[1], image.shape[0], 3, oiio.FLOAT))
    buf.set_pixels(oiio.ROI(), np.ascontiguousarray(image, dtype=np.float32))
    return _png_bytes(buf)


def _png_bytes(buf, target_path=None) -> bytes:
    """8-bit PNG bytes of an OIIO ImageBuf.

    OIIO writes to files only: through a private scratch folder (beside ``target_path``
    when given, so a full disk is reported for the output's own folder, and named so that
    the next write of ``target_path`` removes it if this process is killed), so callers
    can place the bytes atomically.
    """
    import OpenImageIO as oiio

    from atlasgen.io.atomic import scratch_folder

    if target_path is None:
        folder = tempfile.TemporaryDirectory(prefix="atlasgen-png-")
    else:
        folder = scratch_folder(target_path)
    with folder as scratch:
        tmp = str(Path(scratch) / "image.png")
        if not buf.write(tmp, oiio.UINT8):
            name = Path(target_path).as_posix() if target_path is not None else tmp
            raise OutputError(f"{name}: cannot write PNG ({oiio.geterror()})")
        return Path(tmp).read_bytes()


def write_png(image: np.ndarray, path, zoom: int = 1) -> None:
    """Write display RGB in [0, 1] as an 8-bit PNG (:func:`encode_png`), atomically."""
    from atlasgen.io.atomic import write_file_atomically

    write_file_atomically(path, encode_png(image, zoom))


def render_contact_sheet(result, target_path) -> bytes:
    """PNG bytes of every used slice: its RGB (left) and alpha (right), labelled ``id name``.

    Texels are shown as stored (sRGB display of the 8-bit codes, before the slice
    scale), which is what a texture viewer would show an artist; alpha is grey.
    """
    import OpenImageIO as oiio

    srgb = result.manifest["encoding"] == "srgb"
    cells = []
    for m in result.manifest["materials"]:
        for k in range(m["slice_count"]):
            s = m["first_slice"] + k
            label = f"{s} {m['name']}" + (f" [{k}]" if m["slice_count"] > 1 else "")
            cells.append((label, slice_display_image(result.levels[0], s, srgb)))
    cell_w, cell_h = 2 * WIDTH * ZOOM + PAD, HEIGHT * ZOOM + LABEL_H + PAD
    rows = max(1, (len(cells) + COLUMNS - 1) // COLUMNS)
    sheet = np.full((rows * cell_h + PAD, COLUMNS * cell_w + PAD, 3), 0.12)
    for i, (_, image) in enumerate(cells):
        y = PAD + (i // COLUMNS) * cell_h
        x = PAD + (i % COLUMNS) * cell_w
        big = np.kron(image, np.ones((ZOOM, ZOOM, 1)))
        sheet[y : y + big.shape[0], x : x + big.shape[1]] = big
    buf = oiio.ImageBuf(oiio.ImageSpec(sheet.shape[1], sheet.shape[0], 3, oiio.FLOAT))
    buf.set_pixels(oiio.ROI(), sheet.astype(np.float32))
    for i, (label, _) in enumerate(cells):
        y = PAD + (i // COLUMNS) * cell_h + HEIGHT * ZOOM + LABEL_H - 4
        x = PAD + (i % COLUMNS) * cell_w
        oiio.ImageBufAlgo.render_text(buf, x, y, label, 13, "", (0.95, 0.95, 0.95))
    return _png_bytes(buf, target_path)
