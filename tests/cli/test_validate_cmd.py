"""``atlasgen validate`` through click: a tiny end-to-end run and each bad input's message and exit code."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app

from tests.validate.validation_fixtures import mitsuba_rgb, validation_atlas  # noqa: F401  (shared fixtures)


@pytest.mark.slow
def test_validate_writes_the_report(validation_atlas, mitsuba_rgb, gpu_device, tmp_path):  # noqa: F811
    out = tmp_path / "v"
    result = CliRunner().invoke(app, ["validate", "matte", "--scene", "front", "--resolution", "24x18", "--no-physical",
                                      "--atlas", str(validation_atlas), "-o", str(out), "-q"])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "1/1 LUT results meet the goals" in result.output or "0/1 LUT results meet the goals" in result.output
    data = json.loads((out / "report.json").read_text())
    assert [r["material"] for r in data["results"]] == ["matte"]
    assert data["settings"]["scenes"][0]["width"] == 24


@pytest.mark.parametrize(
    "args, code, message",
    [
        (["nosuch"], 3, "no material 'nosuch'; known:"),
        (["matte", "--scene", "sideways"], 3, "unknown validation scene; expected one of front, back"),
        (["matte", "--resolution", "big"], 2, "expected WIDTHxHEIGHT"),
        (["matte", "--spp", "0"], 2, "--spp"),
    ],
)
def test_bad_input_gets_one_clear_line_and_writes_nothing(validation_atlas, tmp_path, args, code, message):  # noqa: F811
    out = tmp_path / "v"
    result = CliRunner().invoke(app, ["validate", *args, "--atlas", str(validation_atlas), "-o", str(out)])
    assert result.exit_code == code
    assert message in result.output
    assert not out.exists()


def test_missing_atlas_says_to_bake_first(tmp_path):
    result = CliRunner().invoke(app, ["validate", "--atlas", str(tmp_path / "none.dds"), "-o", str(tmp_path / "v")])
    assert result.exit_code == 3 and "bake one first" in result.output


@pytest.mark.mitsuba  # needs drjit
def test_missing_llvm_backend_exits_5_and_names_libllvm19(validation_atlas, tmp_path, monkeypatch):  # noqa: F811
    dr = pytest.importorskip("drjit")

    monkeypatch.setattr(dr, "has_backend", lambda backend: False)
    out = tmp_path / "v"
    result = CliRunner().invoke(app, ["validate", "matte", "--atlas", str(validation_atlas), "-o", str(out)])
    assert result.exit_code == 5
    assert "install libllvm19" in result.output
    assert not out.exists()


@pytest.mark.slow
def test_a_material_file_validates_that_material_and_merge_combines_runs(validation_atlas, mitsuba_rgb, gpu_device, tmp_path):  # noqa: F811
    folder = validation_atlas.parent / "materials"
    tiny = ["--scene", "front", "--resolution", "24x18", "--no-physical", "--atlas", str(validation_atlas), "-q"]
    runner = CliRunner()
    for material in ("matte", "coat"):
        result = runner.invoke(app, ["validate", str(folder / f"{material}.toml"), *tiny, "-o", str(tmp_path / material)])
        assert result.exit_code == 0, result.output
        assert [r["material"] for r in json.loads((tmp_path / material / "report.json").read_text())["results"]] == [material]
    result = runner.invoke(app, ["validate", "--merge", str(tmp_path / "matte"), str(tmp_path / "coat"), "-o", str(tmp_path / "all")])
    assert result.exit_code == 0, result.output
    data = json.loads((tmp_path / "all" / "report.json").read_text())
    assert [r["material"] for r in data["results"]] == ["matte", "coat"]
    s = data["summary"]
    assert result.output.strip() == (f"{(tmp_path / 'all' / 'index.html').as_posix()} (2 material/scene results, "
                                     f"{s['lut_meeting_goals']}/2 LUT results meet the goals, {data['total_seconds']:.1f} s)")  # fmt: skip


@pytest.mark.parametrize(
    "make_arg, message",
    [
        (lambda tmp, folder: tmp / "nosuch.toml", "nosuch.toml: no such file"),
        # Same name, other content: the atlas's slices are not what this file describes.
        (lambda tmp, folder: _write(tmp / "matte.toml", (folder / "matte.toml").read_text().replace("0.8", "0.7")),
         "matte.toml: changed since"),
        (lambda tmp, folder: _write(tmp / "other.toml", 'type = "lambert"\n'), "material 'other' is not in"),
    ],
    ids=["missing", "changed-since-the-bake", "not-in-the-atlas"],
)
def test_a_bad_material_file_gets_one_line_naming_it(validation_atlas, tmp_path, make_arg, message):  # noqa: F811
    path = make_arg(tmp_path, validation_atlas.parent / "materials")
    out = tmp_path / "v"
    result = CliRunner().invoke(app, ["validate", str(path), "--atlas", str(validation_atlas), "-o", str(out)])
    assert result.exit_code == 3
    assert result.output.count("\n") == 1 and result.output.startswith(f"atlasgen: error: {path.as_posix()}: ")
    assert message in result.output
    assert not out.exists()


def test_merge_of_a_folder_without_a_report_names_it(tmp_path):
    result = CliRunner().invoke(app, ["validate", "--merge", str(tmp_path / "none"), "-o", str(tmp_path / "v")])
    assert result.exit_code == 3
    assert result.output.strip() == (f"atlasgen: error: {(tmp_path / 'none' / 'report.json').as_posix()}: no such "
                                     f"validation report; run atlasgen validate -o {(tmp_path / 'none').as_posix()} first")  # fmt: skip
    assert not (tmp_path / "v").exists()


def _write(path, text):
    path.write_text(text)
    return path
