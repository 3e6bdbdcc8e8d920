"""The atlas contract (atlasgen/contract.py): its docstrings' examples, and the constant rule every writer follows."""

from __future__ import annotations

import doctest

from atlasgen import contract
from atlasgen.contract import NAME_PATTERN, material_constant


def test_the_docstrings_examples_hold():
    result = doctest.testmod(contract)
    assert result.attempted > 0 and result.failed == 0


def test_a_constant_is_an_identifier_in_every_shading_language_and_no_keyword():
    """MATERIAL_ and capitals: never a WGSL/GLSL/HLSL keyword, never an include function's (lower-case) name."""
    for name in ("a", "fn", "gold-film", "Z9_x-y", "x" * 63):
        assert NAME_PATTERN.fullmatch(name)
        constant = material_constant(name)
        assert constant.startswith("MATERIAL_") and constant[9:] == constant[9:].upper()
        assert all(c.isalnum() or c == "_" for c in constant) and constant.isascii()
