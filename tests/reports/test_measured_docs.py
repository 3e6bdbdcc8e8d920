"""docs/materials.md's measured tables are what atlasgen.reports.measured_docs measures now."""

from __future__ import annotations

import doctest

import pytest

from atlasgen.reports import measured_docs
from atlasgen.reports.measured_docs import DOC, read_measured_table, replace_measured_table, skin_fit_table, stylisation_table


def test_the_skin_fit_table_is_the_golden_manifests():
    assert read_measured_table(DOC.read_text(encoding="utf-8"), "skin-fit") == skin_fit_table()


@pytest.mark.slow
def test_the_stylisation_table_is_measured_and_the_look_costs_more_than_the_table():
    measured = stylisation_table()
    assert read_measured_table(DOC.read_text(encoding="utf-8"), "stylisation") == measured
    for row in measured[2:]:
        model_db, fit_db = (float(cell.split(" ± ")[0]) for cell in row.strip("|").split("|")[1:])
        assert model_db + 3.0 < fit_db, row


def test_a_table_is_replaced_between_its_markers_and_nothing_else_moves():
    text = "intro\n  <!-- measured: a -->\n  | old |\n  <!-- /measured -->\nmiddle\n<!-- measured: b -->\n| b |\n<!-- /measured -->\n"
    new = replace_measured_table(text, "a", ["| new |", "|---|"])
    assert new == text.replace("  | old |\n", "  | new |\n  |---|\n")
    assert read_measured_table(new, "b") == ["| b |"]
    with pytest.raises(ValueError, match="no table 'c'"):
        replace_measured_table(text, "c", [])
    assert doctest.testmod(measured_docs).failed == 0
