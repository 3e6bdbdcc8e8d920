"""``atlasgen validate`` through click: a tiny end-to-end run and each bad input's message and exit code."""

from __future__ import annotations

import json
import re

import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app
from tests.validate.validation_fixtures import mitsuba_rgb, validation_atlas  # noqa: F401  (shared fixtures)


@pytest.fixture(autouse=True)
def _in_a_fresh_folder(tmp_path, monkeypatch):
    """Every run here from a folder of its own: the default caches (build/cache, build/cache/references)
    are relative to it, so no test reads or fills the checkout's."""
    monkeypatch.chdir(tmp_path)


@pytest.mark.slow
def test_validate_writes_the_report(validation_atlas, mitsuba_rgb, gpu_device, tmp_path):  # noqa: F811
    out = tmp_path / "v"
    result = CliRunner().invoke(app, ["validate", "matte", "--scene", "front", "--resolution", "24x18", "--no-physical",
                                      "--atlas", str(validation_atlas), "-o", str(out), "-q"])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "1/1 LUT results meet the storage goals" in result.output or "0/1 LUT results meet the storage goals" in result.output
    data = json.loads((out / "report.json").read_text())
    assert [r["material"] for r in data["results"]] == ["matte"]
    assert data["settings"]["scenes"][0]["width"] == 24


@pytest.mark.slow
def test_a_frame_that_shows_no_pixel_of_the_material_reports_no_figures(validation_atlas, mitsuba_rgb, gpu_device, tmp_path):  # noqa: F811
    """At 2x1 the sphere covers no pixel: the means of nothing were NaN, which broke the plot's log axis and
    the JSON (exit 1, 'a bug'). They are null now, printed n/a, and the goal is not met."""
    out = tmp_path / "v"
    result = CliRunner().invoke(app, ["validate", "matte", "--scene", "front", "--resolution", "2x1", "--no-physical",
                                      "--atlas", str(validation_atlas), "-o", str(out), "-q"])  # fmt: skip
    assert result.exit_code == 0, result.output
    model = json.loads((out / "report.json").read_text())["results"][0]["references"]["model"]
    assert model["coverage"] == 0.0 and model["flip"] is None and model["psnr_db"] is None and not model["meets_goal"]


@pytest.mark.parametrize(
    "args, code, message",
    [
        (["nosuch"], 3, "no material 'nosuch'; known:"),
        (["mate"], 3, "no material 'mate' (did you mean 'matte'?); known:"),
        (["matte", "--scene", "sideways"], 3, "unknown validation scene; expected one of front, back"),
        (["matte", "--resolution", "big"], 2, "expected WIDTHxHEIGHT"),
        (["matte", "--spp", "0"], 2, "--spp"),
    ],
)
@pytest.mark.slow
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
@pytest.mark.slow
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
    result = runner.invoke(
        app, ["validate", "--merge", str(tmp_path / "matte"), str(tmp_path / "coat"), "-o", str(tmp_path / "all")]
    )
    assert result.exit_code == 0, result.output
    data = json.loads((tmp_path / "all" / "report.json").read_text())
    assert [r["material"] for r in data["results"]] == ["matte", "coat"]
    s = data["summary"]
    lines = result.output.strip().splitlines()
    assert [line.split(":")[0] for line in lines[:-1]] == ["matte", "coat"]
    assert lines[-1] == (f"{(tmp_path / 'all' / 'index.html').as_posix()} (2 material/scene results, "
                         f"{s['lut_meeting_goals']}/2 LUT results meet the storage goals, {data['total_seconds']:.1f} s)")  # fmt: skip
    assert gpu_device.take_errors() == []


@pytest.mark.parametrize(
    "make_arg, message",
    [
        (lambda tmp, folder: tmp / "nosuch.toml", "nosuch.toml: no such file"),
        # Same name, other content: the atlas's slices are not what this file describes.
        (
            lambda tmp, folder: _write(tmp / "matte.toml", (folder / "matte.toml").read_text().replace("0.8", "0.7")),
            "matte.toml: changed since",
        ),
        (lambda tmp, folder: _write(tmp / "other.toml", 'type = "lambert"\n'), "material 'other' is not in"),
    ],
    ids=["missing", "changed-since-the-bake", "not-in-the-atlas"],
)
@pytest.mark.slow
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


TINY_RUN = ["--scene", "front", "--resolution", "24x18", "--no-physical"]


def _goals(monkeypatch, psnr_db, flip):
    """Set the LUT goals a run records (atlasgen.validate.run reads them when it runs)."""
    import atlasgen.validate.run as run

    monkeypatch.setattr(run, "GOAL_PSNR_DB", psnr_db)
    monkeypatch.setattr(run, "GOAL_FLIP", flip)


@pytest.mark.mitsuba
@pytest.mark.parametrize("strict", [False, True])
@pytest.mark.slow
def test_strict_exits_6_when_a_goal_is_missed_and_still_writes_the_report(validation_atlas, mitsuba_rgb, gpu_device,  # noqa: F811
                                                                          tmp_path, monkeypatch, strict):  # fmt: skip
    _goals(monkeypatch, psnr_db=1000.0, flip=0.01)  # no image reaches 1000 dB
    out = tmp_path / "v"
    args = ["validate", "matte", *TINY_RUN, "--atlas", str(validation_atlas), "-o", str(out)] + (["--strict"] if strict else [])
    result = CliRunner().invoke(app, args)
    assert result.exit_code == (6 if strict else 0), result.output
    psnr = json.loads((out / "report.json").read_text())["results"][0]["references"]["model"]["psnr_db"]
    assert result.stdout.splitlines()[0] == (f"matte: goals missed: storage; storage 0/1 met (PSNR >= 1000 dB, FLIP <= 0.01; "
                                             f"worst {psnr:.1f} dB, FLIP {_flip(out):.4f}); look not measured: physical "
                                             f"reference not rendered (--no-physical)")  # fmt: skip
    if strict:
        progress, message = result.stderr.strip().splitlines()
        assert progress == "validated matte (1/1)"
        assert message == (f"atlasgen: error: {(out / 'index.html').as_posix()}: 1 goal(s) missed: matte on front: PSNR "
                           f"{psnr:.1f} dB, FLIP {_flip(out):.4f} (PSNR >= 1000 dB, FLIP <= 0.01)")  # fmt: skip
    assert gpu_device.take_errors() == []


@pytest.mark.mitsuba
@pytest.mark.slow
def test_strict_passes_when_every_goal_is_met_and_merge_checks_again(validation_atlas, mitsuba_rgb, gpu_device,  # noqa: F811
                                                                     tmp_path, monkeypatch):  # fmt: skip
    _goals(monkeypatch, psnr_db=0.0, flip=1.0)  # every image meets these
    runner = CliRunner()
    for material in ("matte", "coat"):
        result = runner.invoke(app, ["validate", material, *TINY_RUN, "--atlas", str(validation_atlas),
                                     "-o", str(tmp_path / material), "--strict"])  # fmt: skip
        assert result.exit_code == 0, result.output
        assert result.stdout.startswith(f"{material}: storage goals met; storage 1/1 met (PSNR >= 0 dB, FLIP <= 1;")
    merge = ["validate", "--merge", str(tmp_path / "matte"), str(tmp_path / "coat"), "-o", str(tmp_path / "all"), "--strict"]
    assert runner.invoke(app, merge).exit_code == 0
    # The merge judges the goals the runs recorded: a stricter record fails it.
    report = tmp_path / "coat" / "report.json"
    data = json.loads(report.read_text())
    data["results"][0]["references"]["model"]["meets_goal"] = False
    report.write_text(json.dumps(data))
    result = runner.invoke(app, merge)
    assert result.exit_code == 6 and "1 goal(s) missed: coat on front: PSNR" in result.stderr
    assert gpu_device.take_errors() == []


@pytest.mark.mitsuba
@pytest.mark.slow
def test_a_separable_material_names_its_error_and_budget_not_0_of_0_goals(validation_atlas, mitsuba_rgb, gpu_device, tmp_path):  # noqa: F811
    out = tmp_path / "v"
    result = CliRunner().invoke(
        app, ["validate", "gloss", *TINY_RUN, "--atlas", str(validation_atlas), "-o", str(out), "--strict"]
    )
    assert result.exit_code == 0, result.output
    claimed = json.loads((out / "report.json").read_text())["results"][0]["claimed_errors"]
    first, last = result.stdout.strip().splitlines()
    look = json.loads((out / "report.json").read_text())["results"][0]["references"]["model"]
    verdict = "all goals met" if look["psnr_db"] >= 30 and look["flip"] <= 0.05 else "goals missed: look"
    assert first.startswith(f"gloss: {verdict}; look against the source BSDF it was factored from: {look['psnr_db']:.1f} dB, "
                            f"FLIP {look['flip']:.3f} (goal >= 30 dB, FLIP <= 0.05)")  # fmt: skip
    assert first.endswith(f"; separable error {claimed['relative_rms_8bit']:.2%} (8-bit, claimed; "
                          f"budget none), {claimed['measured_relative_rms_atlas_vs_source']:.2%} measured in the scenes "
                          f"(worst, atlas against source)")  # fmt: skip
    assert "no LUT goals apply" in last and "0/0" not in result.output
    assert gpu_device.take_errors() == []


@pytest.mark.mitsuba
@pytest.mark.parametrize(
    "flag, expected",
    [
        ([], ["validated matte (1/2)", "validated coat (2/2)"]),
        (["-q"], []),
        (
            ["-v"],
            [
                "matte / front: atlas",
                "matte / front: model reference",
                "validated matte (1/2)",
                "coat / front: atlas",
                "coat / front: model reference",
                "validated coat (2/2)",
            ],
        ),
    ],
    ids=["default", "quiet", "verbose"],
)
@pytest.mark.slow
def test_progress_is_one_line_per_material_on_stderr(validation_atlas, mitsuba_rgb, gpu_device, tmp_path, flag, expected):  # noqa: F811
    result = CliRunner().invoke(app, ["validate", "matte", "coat", *TINY_RUN, "--atlas", str(validation_atlas),
                                      "-o", str(tmp_path / "v"), *flag])  # fmt: skip
    assert result.exit_code == 0, result.output
    # Timings and errors vary: compare each line up to its first figure.
    assert [re.sub(r" [0-9.]+ .*", "", line) for line in result.stderr.splitlines()] == expected
    assert len(result.stdout.splitlines()) == (1 if flag == ["-q"] else 3)
    assert gpu_device.take_errors() == []


def _flip(out):
    return json.loads((out / "report.json").read_text())["results"][0]["references"]["model"]["flip"]


def _write(path, text):
    path.write_text(text)
    return path


@pytest.mark.mitsuba
@pytest.mark.slow
def test_the_reference_cache_defaults_to_build_cache_references_and_serves_a_second_run(validation_atlas, mitsuba_rgb,  # noqa: F811
                                                                                        gpu_device, tmp_path):  # fmt: skip
    runner = CliRunner()
    args = ["validate", "matte", *TINY_RUN, "--atlas", str(validation_atlas), "-q"]
    assert runner.invoke(app, [*args, "-o", "first"]).exit_code == 0
    assert len(list((tmp_path / "build" / "cache" / "references").glob("*.npz"))) == 1  # the model reference
    assert runner.invoke(app, [*args, "-o", "second"]).exit_code == 0
    environment = json.loads((tmp_path / "second" / "report.json").read_text())["environment"]
    assert environment["reference_renders_from_cache"] == 1 and environment["reference_renders_stored"] == 0
    assert environment["reference_cache"] == "build/cache/references"
    result = runner.invoke(app, [*args, "-o", "third", "--no-reference-cache", "--reference-cache", str(tmp_path / "elsewhere")])
    assert result.exit_code == 0 and not (tmp_path / "elsewhere").exists()
    assert gpu_device.take_errors() == []
