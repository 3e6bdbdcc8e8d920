"""Which command's report a folder holds: a validation report and a separable one never replace each other."""

from __future__ import annotations

import doctest
import json

import pytest

from atlasgen.errors import OutputError
from atlasgen.reports import report_kind
from atlasgen.reports.report_kind import refuse_another_report

VALIDATION = {"atlas": "a.dds", "settings": {}, "results": []}
SEPARABLE = [{"name": "gold", "source": "gold.toml"}]


@pytest.mark.parametrize(
    ("existing", "writing", "refused"),
    [
        (VALIDATION, "separable", "a validation report"),
        (SEPARABLE, "validation", "a separable report"),
        (VALIDATION, "validation", None),
        (SEPARABLE, "separable", None),
        ({"something": "else"}, "validation", None),  # not a report of ours: the commit decides
        ("not json", "separable", None),
        ("[" * 2000 + "]" * 2000, "separable", None),  # too deep for the decoder: a RecursionError was an internal error
        (None, "validation", None),  # no report.json yet
    ],
)
def test_a_report_refuses_a_folder_holding_the_other_command_s(tmp_path, existing, writing, refused):
    if existing is not None:
        text = existing if isinstance(existing, str) else json.dumps(existing)
        (tmp_path / "report.json").write_text(text)
    if refused is None:
        refuse_another_report(tmp_path, writing)
        return
    with pytest.raises(OutputError) as info:
        refuse_another_report(tmp_path, writing)
    assert str(info.value) == (f"{(tmp_path / 'report.json').as_posix()}: already written by another command's outputs "
                               f"({refused}); expected a folder of its own for each command's outputs; nothing was replaced")  # fmt: skip


def test_the_module_s_doctests_pass():
    result = doctest.testmod(report_kind)
    assert result.attempted >= 1 and result.failed == 0


def test_a_separable_report_given_to_validate_merge_is_named_as_one(tmp_path):
    """validate --merge of a separable report's folder said "not a validation report (missing everything)"."""
    from atlasgen.errors import InputError
    from atlasgen.reports.validation import read_validation_report

    path = tmp_path / "report.json"
    path.write_text('[{"name": "gold", "chosen": {}}]\n')
    with pytest.raises(InputError) as info:
        read_validation_report(path)
    assert str(info.value) == (f"{path.as_posix()}: a separable report (atlasgen report separable), not a validation "
                               "report; expected the folder of an atlasgen validate run")  # fmt: skip
