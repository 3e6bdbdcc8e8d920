"""atlasgen/io/field_reads.py: the field a formatter stopped on, the one a refusal of a hand-edited report names."""

from __future__ import annotations

import doctest
from dataclasses import asdict, dataclass, field

import pytest

from atlasgen.io import field_reads
from atlasgen.io.field_reads import ABSENT, FieldReads


def test_doctests():
    result = doctest.testmod(field_reads)
    assert result.attempted > 0 and result.failed == 0


@dataclass
class _Study:
    name: str
    rows: list
    extra: dict = field(default_factory=dict)


def _failure(document, use):
    reads = FieldReads()
    tracked = reads.track(document, "[3]")
    with pytest.raises((TypeError, KeyError, AttributeError, ValueError)):
        use(tracked)
    return reads.last


def test_each_kind_of_read_is_noted_with_its_path():
    doc = {"rows": [{"x": 1.0}, {"x": "two"}], "table": {"a": 1, "b": None}}
    assert _failure(doc, lambda d: sum(r["x"] for r in d["rows"])) == ("[3].rows[1].x", "two")
    assert _failure(doc, lambda d: [v + 1 for v in d["table"].values()]) == ("[3].table.b", None)
    assert _failure(doc, lambda d: [v + 1 for _, v in d["table"].items()]) == ("[3].table.b", None)
    assert _failure(doc, lambda d: d.get("rows")[-1]["x"] + 1) == ("[3].rows[1].x", "two")
    assert _failure(doc, lambda d: d["rows"][0]["y"]) == ("[3].rows[0].y", ABSENT)


def test_a_dataclass_s_fields_are_noted_and_it_stays_one():
    study = _Study("lobe", [1, 2, "3"])
    reads = FieldReads()
    tracked = reads.track(study, "[0]")
    assert isinstance(tracked, _Study) and asdict(tracked) == asdict(study)
    with pytest.raises(TypeError):
        sum(tracked.rows)
    assert reads.last == ("[0].rows[2]", "3")
    with pytest.raises(AttributeError, match="'list' object has no attribute 'items'"):
        reads.track({"rows": [1]})["rows"].items()


def test_the_tracked_document_equals_the_original():
    doc = {"a": [1, {"b": [2.5, None]}], "c": "text"}
    assert FieldReads().track(doc) == doc and FieldReads().track(list(doc["a"])) == doc["a"]


def _culprit(document, use):
    reads = FieldReads()
    tracked = reads.track(document, "[0]")
    with pytest.raises((TypeError, KeyError, AttributeError, ValueError)):
        use(tracked)
    return reads.culprit()


def test_a_key_taken_from_the_document_names_the_field_that_gave_it():
    """look.reference made [1], {} or "x": the page looks it up in references, and the refusal named
    'references.[1]', a field no report has. The field that gave the key is named."""
    for bad in ([1], {}, "x"):
        doc = {"look": {"reference": bad}, "references": {"model": {"psnr": 40.0}}}
        assert _culprit(doc, lambda d: d["references"][d["look"]["reference"]]["psnr"]) == ("[0].look.reference", bad)


def test_a_value_read_before_the_failure_is_named_by_its_kind():
    """A formatter reads a row's figures, then formats them, or scans every row before it uses one: the last read
    was a good value (relative_rms beside the edited relative_rms_se; row 27 for an edited row 0). The value of
    another kind than the same field of the other rows, or than siblings that are all numbers, is named."""
    figures = {"relative_rms": 0.02, "relative_rms_se": "x", "relative_log_rms": 0.01}

    def page(d):
        se = d["chosen"]["relative_rms_se"]
        rms = d["chosen"]["relative_rms"]
        return f"{rms:.2%} +- {se:.2%}"

    assert _culprit({"chosen": figures}, page) == ("[0].chosen.relative_rms_se", "x")
    rows = [{"cost": "x" if i == 0 else float(i), "error": 0.1} for i in range(30)]
    assert _culprit({"rows": rows}, lambda d: sorted(r["cost"] for r in d["rows"])) == ("[0].rows[0].cost", "x")
    # A good text among numbers is not blamed where the last read is of no other kind.
    named = {"name": "gold", "a": 1.0, "b": 2.0}
    assert _culprit(named, lambda d: d["a"] + d["b"] + d["missing"]) == ("[0].missing", ABSENT)
