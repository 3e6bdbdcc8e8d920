"""A labelled contact sheet of the atlas's used slices, written as PNG with OpenImageIO."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from .contract import HEIGHT, WIDTH
from .errors import OutputError
from .srgb import encode_srgb

__all__ = ["render_contact_sheet"]

ZOOM = 2
COLUMNS = 4
LABEL_H = 18
PAD = 6


def render_contact_sheet(result, target_path) -> bytes:
    """PNG bytes of every used slice: its RGB (left) and alpha (right), labelled ``id name``.

    Texels are shown as stored (sRGB display of the 8-bit codes, before the slice
    scale), which is what a texture viewer would show an artist; alpha is grey.
    """
    import OpenImageIO as oiio

    srgb = result.manifest["encoding"] == "srgb"
    level0 = result.levels[0].astype(np.float64) / 255.0
    cells = []
    for m in result.manifest["materials"]:
        for k in range(m["slice_count"]):
            s = m["first_slice"] + k
            label = f"{s} {m['name']}" + (f" [{k}]" if m["slice_count"] > 1 else "")
            rgb = level0[s, ..., :3] if srgb else encode_srgb(level0[s, ..., :3])
            alpha = np.repeat(level0[s, ..., 3:4], 3, axis=2)
            cells.append((label, np.concatenate([rgb, alpha], axis=1)))
    cell_w, cell_h = 2 * WIDTH * ZOOM + PAD, HEIGHT * ZOOM + LABEL_H + PAD
    rows = max(1, (len(cells) + COLUMNS - 1) // COLUMNS)
    sheet = np.full((rows * cell_h + PAD, COLUMNS * cell_w + PAD, 3), 0.12)
    for i, (_, image) in enumerate(cells):
        y = PAD + (i // COLUMNS) * cell_h
        x = PAD + (i % COLUMNS) * cell_w
        # Flip vertically so N.V = 1 (facing) is at the top, as artists expect to read it.
        big = np.kron(image[::-1], np.ones((ZOOM, ZOOM, 1)))
        sheet[y : y + big.shape[0], x : x + big.shape[1]] = big
    buf = oiio.ImageBuf(oiio.ImageSpec(sheet.shape[1], sheet.shape[0], 3, oiio.FLOAT))
    buf.set_pixels(oiio.ROI(), sheet.astype(np.float32))
    for i, (label, _) in enumerate(cells):
        y = PAD + (i // COLUMNS) * cell_h + HEIGHT * ZOOM + LABEL_H - 4
        x = PAD + (i % COLUMNS) * cell_w
        oiio.ImageBufAlgo.render_text(buf, x, y, label, 13, "", (0.95, 0.95, 0.95))
    folder = Path(target_path).parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".preview.", suffix=".png", dir=folder)
    except OSError as exc:
        raise OutputError(f"{folder.as_posix()}: cannot write output folder ({exc.strerror})") from None
    os.close(fd)
    try:
        out = buf.copy(oiio.UINT8) if hasattr(buf, "copy") else buf
        if not out.write(tmp, oiio.UINT8):
            raise OutputError(f"{Path(target_path).as_posix()}: cannot write preview ({oiio.geterror()})")
        return Path(tmp).read_bytes()
    finally:
        os.unlink(tmp)
