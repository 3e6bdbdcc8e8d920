"""The field validator's pure helpers (atlasgen/io/fields.py): its docstrings' examples."""

from __future__ import annotations

import doctest

from atlasgen.io import fields


def test_the_docstrings_examples_hold():
    result = doctest.testmod(fields)
    assert result.attempted > 0 and result.failed == 0
