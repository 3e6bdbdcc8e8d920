"""A labelled contact sheet of the atlas's used slices, and single-slice previews, as PNG."""

from __future__ import annotations

import numpy as np

from atlasgen.contract import HEIGHT, WIDTH
from atlasgen.io.images import encode_png
from atlasgen.io.oiio import import_oiio
from atlasgen.optics.quantize import dequantize_rgba, quantize_rgba
from atlasgen.optics.srgb import encode_srgb

__all__ = ["render_contact_sheet", "slice_display_image", "slice_png"]

ZOOM = 2
COLUMNS = 4
LABEL_H = 18
PAD = 6


def _enlarge(image: np.ndarray, zoom: int) -> np.ndarray:
    """Nearest-neighbour enlargement by a whole factor, so texels stay sharp squares."""
    return np.kron(image, np.ones((zoom, zoom, 1))) if zoom > 1 else image


def slice_display_image(level0: np.ndarray, slice_index: int, srgb: bool, zoom: int = 1) -> np.ndarray:
    """Display RGB in [0, 1] of one stored slice: its RGB then its alpha in grey, side by side.

    N.V = 1 (facing) is at the top, as an artist reads it. The texels are shown as
    stored: sRGB codes as they are, linear codes sRGB-encoded for display.
    """
    texels = dequantize_rgba(level0[slice_index], srgb=False)  # code / 255: the stored values
    rgb = texels[..., :3] if srgb else encode_srgb(texels[..., :3])
    alpha = np.repeat(texels[..., 3:4], 3, axis=2)
    return _enlarge(np.concatenate([rgb, alpha], axis=1)[::-1], zoom)


def slice_png(level0: np.ndarray, slice_index: int, srgb: bool, zoom: int = 1) -> bytes:
    """PNG bytes of :func:`slice_display_image`."""
    return encode_png(quantize_rgba(slice_display_image(level0, slice_index, srgb, zoom), srgb=False))


def render_contact_sheet(result) -> bytes:
    """PNG bytes of every used slice: its RGB (left) and alpha (right), labelled ``id name``.

    Texels are shown as stored (sRGB display of the 8-bit codes, before the slice
    scale), which is what a texture viewer would show an artist; alpha is grey.
    """
    oiio = import_oiio()

    srgb = result.manifest.srgb
    cells = []
    for m in result.manifest.materials:
        for k, s in enumerate(m.slices):
            label = f"{s} {m.name}" + (f" [{k}]" if m.slice_count > 1 else "")
            cells.append((label, slice_display_image(result.levels[0], s, srgb, ZOOM)))
    cell_w, cell_h = 2 * WIDTH * ZOOM + PAD, HEIGHT * ZOOM + LABEL_H + PAD
    rows = max(1, (len(cells) + COLUMNS - 1) // COLUMNS)
    sheet = np.full((rows * cell_h + PAD, COLUMNS * cell_w + PAD, 3), 0.12)
    for i, (_, image) in enumerate(cells):
        y = PAD + (i // COLUMNS) * cell_h
        x = PAD + (i % COLUMNS) * cell_w
        sheet[y : y + image.shape[0], x : x + image.shape[1]] = image
    buf = oiio.ImageBuf(oiio.ImageSpec(sheet.shape[1], sheet.shape[0], 3, oiio.FLOAT))
    buf.set_pixels(oiio.ROI(), sheet.astype(np.float32))
    for i, (label, _) in enumerate(cells):
        y = PAD + (i // COLUMNS) * cell_h + HEIGHT * ZOOM + LABEL_H - 4
        x = PAD + (i % COLUMNS) * cell_w
        oiio.ImageBufAlgo.render_text(buf, x, y, label, 13, "", (0.95, 0.95, 0.95))
    pixels = np.asarray(buf.get_pixels(oiio.FLOAT), dtype=np.float64)
    return encode_png(quantize_rgba(pixels, srgb=False))
