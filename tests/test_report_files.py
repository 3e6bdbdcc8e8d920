"""Finding and reading the report.json files a merge combines: one-line errors naming the file."""

import pytest

from atlasgen.errors import InputError
from atlasgen.io.report_files import read_report_json, report_json_paths


def test_folders_and_json_files_both_name_a_report(tmp_path):
    assert report_json_paths([tmp_path / "a", tmp_path / "b.json"], "x", "cmd") == [
        tmp_path / "a" / "report.json",
        tmp_path / "b.json",
    ]


def test_no_sources_names_the_command_that_writes_them():
    with pytest.raises(InputError, match="no validation reports to merge; expected folders written by atlasgen validate -o"):
        report_json_paths([], "validation", "atlasgen validate")


def test_a_round_trip_and_every_failure(tmp_path):
    good = tmp_path / "good.json"
    good.write_text('{"results": [1, 2]}')
    assert read_report_json(good, "x", "cmd") == {"results": [1, 2]}
    with pytest.raises(
        InputError, match=r"missing/report.json: no such separable report; run atlasgen report separable -o .*missing first"
    ):
        read_report_json(tmp_path / "missing" / "report.json", "separable", "atlasgen report separable")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(InputError, match="bad.json: malformed JSON"):
        read_report_json(bad, "x", "cmd")
    with pytest.raises(InputError, match="cannot read"):
        read_report_json(tmp_path, "x", "cmd")  # a folder
