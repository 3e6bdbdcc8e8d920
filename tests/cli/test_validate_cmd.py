"""``atlasgen validate`` through click: a tiny end-to-end run and each bad input's message and exit code."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner
from validate.validation_fixtures import mitsuba_rgb, validation_atlas  # noqa: F401  (shared fixtures)

from atlasgen.cli.main import app


def test_validate_writes_the_report(validation_atlas, mitsuba_rgb, gpu_device, tmp_path):  # noqa: F811
    out = tmp_path / "v"
    result = CliRunner().invoke(app, ["validate", "matte", "--scene", "front", "--resolution", "24x18", "--no-physical",
                                      "--atlas", str(validation_atlas), "-o", str(out), "-q"])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "1/1 LUT results meet the goals" in result.output or "0/1 LUT results meet the goals" in result.output
    data = json.loads((out / "report.json").read_text())
    assert [r["material"] for r in data["results"]] == ["matte"]
    assert data["settings"]["scenes"][0]["width"] == 24
    assert gpu_device.take_errors() == []


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


def test_missing_llvm_backend_exits_5_and_names_libllvm19(validation_atlas, tmp_path, monkeypatch):  # noqa: F811
    dr = pytest.importorskip("drjit")

    monkeypatch.setattr(dr, "has_backend", lambda backend: False)
    out = tmp_path / "v"
    result = CliRunner().invoke(app, ["validate", "matte", "--atlas", str(validation_atlas), "-o", str(out)])
    assert result.exit_code == 5
    assert "install libllvm19" in result.output
    assert not out.exists()
