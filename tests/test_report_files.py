"""Finding and reading the report.json files a merge combines: one-line errors naming the file."""

import json

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
    bad.write_text('{"a":' + "[" * 100000 + "]" * 100000 + "}")
    with pytest.raises(InputError, match=r"bad.json: malformed JSON \(arrays or objects nested too deeply to read\)"):
        read_report_json(bad, "x", "cmd")
    with pytest.raises(InputError, match="expected a regular file, got a folder"):
        read_report_json(tmp_path, "x", "cmd")  # a folder


@pytest.mark.parametrize("constant", ["NaN", "Infinity", "-Infinity"])
def test_nan_and_infinities_are_refused_with_one_line(tmp_path, constant):
    path = tmp_path / "report.json"
    path.write_text('{"total_seconds": ' + constant + "}")
    name = constant
    with pytest.raises(InputError) as refused:
        read_report_json(path, "validation", "atlasgen validate")
    assert (
        str(refused.value)
        == f"{path.as_posix()}: field 'total_seconds': expected a finite number (JSON has no {name}), got {name}"
    )


@pytest.mark.parametrize("text,line", [
    ('{"results": [{"psnr": 1}, {"refs": {"model": {"psnr": [2, NaN]}}}], "flip": Infinity}',
     "field 'results[1].refs.model.psnr[1]': expected a finite number (JSON has no NaN), got NaN"),
    ('{"a\\nb": {"c": 1e999}}', "field 'a\\nb.c': expected a finite number (beyond a double's range), got 1e999"),
    ("-Infinity", "expected a finite number (JSON has no -Infinity), got -Infinity"),
])  # fmt: skip
def test_the_line_names_the_field_of_the_first_number_json_cannot_hold(tmp_path, text, line):
    """The reader meets the constant before it knows any field: the line names the field all the same."""
    path = tmp_path / "report.json"
    path.write_text(text)
    with pytest.raises(InputError) as refused:
        read_report_json(path, "validation", "atlasgen validate")
    assert str(refused.value) == f"{path.as_posix()}: {line}"


@pytest.mark.parametrize("value", [float("nan"), float("inf"), "1.5", True, [1], {}])
def test_check_number_refuses_what_is_not_a_finite_number(value):
    from atlasgen.errors import FieldError
    from atlasgen.io.report_files import check_number

    with pytest.raises(FieldError, match=r"^t\.json: field 'materials\.clay\.bake_s': expected a finite number or null, got "):
        check_number("t.json", "materials.clay.bake_s", value)
    assert check_number("t.json", "x", 2) == 2


def _validation_report(figure) -> dict:
    ref = {"seconds": 1.0, "speed_ratio": 2.0, "psnr_db": figure, "flip": 0.1, "meets_goal": True, "images": {}}
    row = {"material": "clay", "scene": "front", "exposure": 1.0, "atlas_seconds": 0.5, "references": {"model": ref},
           "atlas_image": "images/a.png", "notes": []}  # fmt: skip
    environment = {"gpu": "lavapipe", "mitsuba": "3.9.1", "atlas_timing": "wall", "mitsuba_timing": "wall"}
    return {"atlas": "a.dds", "settings": {"spp": 16, "physical_spp": 64, "goals": {"psnr_db": 30, "flip": 0.2}},
            "environment": environment, "total_seconds": 1.0, "results": [row]}  # fmt: skip


@pytest.mark.parametrize("figure,expected", [
    ("high", "field 'results[0].references.model.psnr_db': expected a finite number or null, got 'high'"),
    (None, None),
])  # fmt: skip
def test_a_merged_validation_report_refuses_a_figure_that_is_not_a_number(tmp_path, figure, expected):
    import json

    from atlasgen.errors import FieldError
    from atlasgen.reports.validation import read_validation_report

    path = tmp_path / "report.json"
    path.write_text(json.dumps(_validation_report(figure)))
    if expected is None:
        assert read_validation_report(path)["results"][0]["references"]["model"]["psnr_db"] is None
        return
    with pytest.raises(FieldError) as refused:
        read_validation_report(path)
    assert str(refused.value) == f"{path.as_posix()}: {expected}"


def test_a_merged_validation_report_with_nan_is_refused_through_the_cli(tmp_path):
    from click.testing import CliRunner

    from atlasgen.cli.main import app

    source = tmp_path / "clay"
    source.mkdir()
    (source / "report.json").write_text(json.dumps(_validation_report(1.0)).replace("1.0", "NaN", 1))
    result = CliRunner().invoke(app, ["validate", "--merge", str(source), "-o", str(tmp_path / "out")])
    assert result.exit_code == 3, result.output
    assert result.output.splitlines() == [
        f"atlasgen: error: {(source / 'report.json').as_posix()}: field 'total_seconds': expected a finite number "
        "(JSON has no NaN), got NaN"
    ]
    assert not (tmp_path / "out").exists()


def test_a_timings_file_with_a_non_number_bake_time_is_refused_with_one_line(tmp_path):
    from atlasgen.errors import FieldError
    from atlasgen.reports.library import _bake_seconds

    path = tmp_path / "atlas.timings.json"
    assert _bake_seconds({"materials": {"clay": {"bake_s": 0.25}}}, path, "clay") == 0.25
    assert _bake_seconds({}, path, "clay") is None
    with pytest.raises(
        FieldError, match=r"atlas\.timings\.json: field 'materials\.clay\.bake_s': expected a finite number or null, got 'slow'"
    ):
        _bake_seconds({"materials": {"clay": {"bake_s": "slow"}}}, path, "clay")
    with pytest.raises(FieldError, match=r"field 'materials': expected an object"):
        _bake_seconds({"materials": [1]}, path, "clay")


def test_a_report_over_the_size_limit_is_refused_unread(tmp_path, monkeypatch):
    """A 48 MB report.json of empty objects took 1.27 GB to read; the limit is lowered here to stand for it."""
    from atlasgen.io import report_files

    path = tmp_path / "report.json"
    path.write_text('{"results": [], "pad": [' + ", ".join(["{}"] * 50) + "]}")
    monkeypatch.setattr(report_files, "REPORT_LIMIT", (100, "a report written by atlasgen"))
    with pytest.raises(InputError) as refused:
        read_report_json(path, "validation", "atlasgen validate")
    size = path.stat().st_size
    assert str(refused.value) == f"{path.as_posix()}: {size} bytes; expected a report written by atlasgen, at most 100 bytes"
