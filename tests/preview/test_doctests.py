"""The preview modules' examples run as written."""

from __future__ import annotations

import doctest
import importlib

import pytest


@pytest.mark.parametrize(
    "module", ["atlasgen.preview.label", "atlasgen.preview.sheet", "atlasgen.preview.previewer", "atlasgen.preview.reference"]
)
def test_the_examples_in_the_docstrings_hold(module):
    result = doctest.testmod(importlib.import_module(module))
    assert result.attempted > 0 and result.failed == 0
