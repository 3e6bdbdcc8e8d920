"""The shape of a JSON document read back (atlasgen/io/json_shape.py): the first field that differs, on one line."""

from __future__ import annotations

import doctest

import pytest

from atlasgen.errors import FieldError
from atlasgen.io import json_shape
from atlasgen.io.json_shape import Count, Fields, Figure, Flag, Items, Nullable, Number, Text, check_shape


def test_the_doctests_hold():
    result = doctest.testmod(json_shape)
    assert result.attempted > 0 and result.failed == 0


ROW = Fields({"terms": Count(), "error": Figure()}, {"note": Text(("a", "b"))})
TABLE = Fields({"rows": Items(ROW, unique=("terms",)), "at": Nullable(Number())}, others=Flag(), keys=("done",))


def _refusal(value) -> str:
    with pytest.raises(FieldError) as caught:
        check_shape("t.json", "[0]", value, TABLE)
    return str(caught.value)


def test_a_document_of_the_shape_passes():
    check_shape("t.json", "[0]", {"rows": [{"terms": 1, "error": 0.0, "note": "a"}, {"terms": 2, "error": 3}],
                                  "at": None, "done": True}, TABLE)  # fmt: skip


@pytest.mark.parametrize(("value", "expected"), [
    ({"rows": [{"terms": 1, "error": 0.1}]}, "field '[0].at': expected a value, got none (no such key)"),
    ({"rows": [{"terms": 1, "error": 0.1}], "at": "x"}, "field '[0].at': expected a finite number, got 'x'"),
    ({"rows": [{"terms": 1, "error": 0.1}], "at": 1, "other": 1}, "field '[0].other': expected no such field"),
    ({"rows": [{"terms": 1, "error": 0.1}], "at": 1, "done": 1}, "field '[0].done': expected true or false, got 1"),
    ({"rows": [{"terms": 1, "error": 0.1, "note": "c"}], "at": 1}, "field '[0].rows[0].note': expected one of a, b"),
    ({"rows": [{"terms": 1, "error": 0.1}, {"terms": 1, "error": 0.2}], "at": 1},
     "field '[0].rows[1]': expected one row per (terms), not a second, got (1,)"),
    ({"rows": [{"terms": 1.0, "error": 0.1}], "at": 1}, "field '[0].rows[0].terms': expected a whole number >= 1"),
    ({"rows": [{"terms": 1, "error": float("nan")}], "at": 1}, "field '[0].rows[0].error': expected a finite number"),
    ({"rows": {"terms": 1}, "at": 1}, "field '[0].rows': expected a list, got {'terms': 1}"),
    ([], "field '[0]': expected an object, got []"),
])  # fmt: skip
def test_the_first_field_unlike_the_shape_is_named(value, expected):
    line = _refusal(value)
    assert line.startswith("t.json: ") and expected in line and "\n" not in line, line
