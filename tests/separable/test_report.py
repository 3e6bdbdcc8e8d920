"""The separable report: every promised plot and table, from measured data; the CLI's error paths."""

import json

import pytest
from click.testing import CliRunner

from atlasgen.errors import InputError
from atlasgen.materials.material import read_material
from atlasgen.reports.separable import write_separable_report


@pytest.mark.slow
def test_report_writes_markdown_json_and_the_plots(write_material, tmp_path, separable_atlas):
    atlas, _ = separable_atlas
    material = read_material(write_material("lobe", 'type = "separable"\nsource = "blinn_phong"\nexponent = 40.0\nterms = 2\n'))
    out = write_separable_report([material], tmp_path / "report", atlas_path=atlas, resolutions=(8, 16), repeats=1,
                                 parametrizations=("half_diff", "in_out"))
    plots = out["plots"]["lobe"]
    assert set(plots) == {"terms", "resolution", "pareto", "parametrization"}
    for png in plots.values():
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = out["markdown"].read_text()
    for png in plots.values():
        assert f"]({png.name})" in text
    data = json.loads(out["json"].read_text())[0]
    # The table shows the measured numbers: the chosen K's float error, as a percentage.
    assert f"{100 * data['chosen']['float']['relative_rms']:.2f}%" in text
    assert [r["resolution"] for r in data["by_resolution"]] == [8] * 4 + [16] * 4
    # The Pareto front only ever improves the error as time grows.
    errs = [p["relative_rms"] for p in data["pareto"]]
    assert errs == sorted(errs, reverse=True)
    assert set(data["by_parametrization"]) == {"half_diff", "in_out"}
    assert data["nonnegative"]["nd"]["terms"] == 1 and len(data["nonnegative"]["nmf"]) == 4
    # A material absent from the atlas is said to be absent, not measured.
    assert "missing" in data["atlas"]


def test_report_needs_a_separable_material(write_material, tmp_path):
    lut = read_material(write_material("clay", 'type = "lambert"\n'))
    with pytest.raises(InputError, match="no separable materials"):
        write_separable_report([lut], tmp_path / "r")


def test_cli_maps_errors_to_messages(write_material, tmp_path):
    from atlasgen.cli.report_cmd import report

    write_material("clay", 'type = "lambert"\n')
    runner = CliRunner()
    res = runner.invoke(report, ["separable", "nope", "-m", str(tmp_path / "materials"), "-o", str(tmp_path / "r")])
    assert res.exit_code == 3 and "no material named nope" in res.output
    res = runner.invoke(report, ["separable", "-m", str(tmp_path / "materials"), "-o", str(tmp_path / "r")])
    assert res.exit_code == 3 and "no separable materials" in res.output
