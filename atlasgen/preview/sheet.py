"""A contact sheet: labelled pictures in a grid, row by row."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["sheet_columns", "arrange_sheet", "GAP"]

#: Pixels between cells and around the sheet.
GAP = 4
_BACKGROUND = (10, 10, 12)


def sheet_columns(count: int, most: int = 4) -> int:
    """Columns of a sheet of ``count`` cells: ceil(sqrt(count)), at most ``most``, at least 1.

    >>> [sheet_columns(n) for n in (1, 2, 3, 4, 5, 9, 10, 12, 30)]
    [1, 2, 2, 2, 3, 3, 4, 4, 4]
    """
    return max(1, min(most, math.ceil(math.sqrt(count))))


def arrange_sheet(cells: list[np.ndarray], columns: int | None = None) -> np.ndarray:
    """``(h_i, w_i, 3)`` uint8 cells in a grid of ``columns`` (:func:`sheet_columns` by default), in order.

    Every cell gets the largest cell's size, its picture at the top left; cells are
    :data:`GAP` pixels apart and from the edge. One cell comes back as it is.
    """
    if not cells:
        raise ValueError("a contact sheet needs at least one cell")
    if len(cells) == 1:
        return cells[0]
    columns = columns or sheet_columns(len(cells))
    rows = math.ceil(len(cells) / columns)
    cell_h, cell_w = max(c.shape[0] for c in cells), max(c.shape[1] for c in cells)
    sheet = np.empty((GAP + rows * (cell_h + GAP), GAP + columns * (cell_w + GAP), 3), np.uint8)
    sheet[:] = _BACKGROUND
    for i, cell in enumerate(cells):
        y, x = GAP + (i // columns) * (cell_h + GAP), GAP + (i % columns) * (cell_w + GAP)
        sheet[y : y + cell.shape[0], x : x + cell.shape[1]] = cell
    return sheet
