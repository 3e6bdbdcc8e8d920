"""The contact sheet's grid."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.preview.sheet import GAP, arrange_sheet, sheet_columns


@settings(max_examples=30)
@given(st.lists(st.tuples(st.integers(1, 12), st.integers(1, 12)), min_size=2, max_size=11), st.integers(1, 5))
def test_every_cell_sits_at_its_grid_place(sizes, columns):
    cells = [np.full((h, w, 3), i + 1, np.uint8) for i, (h, w) in enumerate(sizes)]
    sheet = arrange_sheet(cells, columns)
    cell_h, cell_w = max(h for h, _ in sizes), max(w for _, w in sizes)
    rows = -(-len(cells) // columns)
    assert sheet.shape == (GAP + rows * (cell_h + GAP), GAP + columns * (cell_w + GAP), 3)
    for i, (h, w) in enumerate(sizes):
        y, x = GAP + (i // columns) * (cell_h + GAP), GAP + (i % columns) * (cell_w + GAP)
        assert (sheet[y : y + h, x : x + w] == i + 1).all()
    # Nothing else carries a cell's value: each is drawn once, whole.
    assert sum(int((sheet == i + 1).all(axis=2).sum()) for i in range(len(cells))) == sum(h * w for h, w in sizes)


def test_one_cell_is_the_sheet_and_none_is_refused():
    cell = np.zeros((5, 7, 3), np.uint8)
    assert arrange_sheet([cell]) is cell
    with pytest.raises(ValueError):
        arrange_sheet([])


def test_columns_grow_as_the_square_root_up_to_four():
    assert [sheet_columns(n) for n in range(1, 18)] == [1, 2, 2, 2, 3, 3, 3, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4]
