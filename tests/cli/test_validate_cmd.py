"""``atlasgen validate`` through click: a tiny end-to-end run and each bad input's message and exit code."""

from __future__ import annotations

import json
import os
import re

import numpy as np
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
    # With --no-physical none is rendered: the page said "64 spp (stochastic physical references)" even so.
    assert data["settings"]["physical_spp"] is None
    page = (out / "index.html").read_text(encoding="utf-8")
    assert "no physical references (<code>--no-physical</code>)" in page and "stochastic physical" not in page


def _front_scene(tmp_path, name, **replace):
    """A copy of the standard front scene at ``tmp_path/<name>.toml``, with lines replaced (``key=(old, new)``)."""
    from atlasgen.validate.scenes import scene_folder

    text = (scene_folder() / "front.toml").read_text()
    for old, new in replace.values():
        assert old in text
        text = text.replace(old, new)
    return _write(tmp_path / f"{name}.toml", text)


@pytest.mark.parametrize(
    "scenes, shown, size",
    [
        (["--scene", "front", "--resolution", "2x1"], "front", "2x1 frame (--resolution)"),
        (["--scene", "AWAY", "--resolution", "32x24"], "AWAY", "32x24 frame (--resolution)"),
        (["--scene", "front", "--scene", "AWAY"], "AWAY", "128x96 frame"),
    ],
    ids=["too-small-a-frame", "camera-looking-away", "second-scene-looking-away"],
)
@pytest.mark.slow
def test_a_scene_that_shows_no_pixel_of_the_material_is_refused(validation_atlas, mitsuba_rgb, gpu_device, tmp_path,  # noqa: F811
                                                                 monkeypatch, scenes, shown, size):  # fmt: skip
    """Every figure of such a scene is a mean over nothing: it was reported as "worst inf dB", linear relative RMS 0.0,
    a goal decided on nothing, or ended in an internal error (a None compared with a float in the summary). It is
    refused before any reference renders, exit 3, one line naming the scene and the material; nothing is written."""
    from atlasgen.validate import run as module

    away = _front_scene(tmp_path, "away", camera=("target = [0.0, 0.42, 0.0]", "target = [0.0, 0.42, 10.0]"))
    scenes = [str(away) if s == "AWAY" else s for s in scenes]
    shown = away.as_posix() if shown == "AWAY" else shown

    def refuse(*a, **k):
        raise AssertionError("a reference rendered before the scene was checked")

    monkeypatch.setattr(module, "render_mitsuba", refuse)
    out = tmp_path / "v"
    result = CliRunner().invoke(app, ["validate", "matte", *scenes, "--no-physical", "--atlas", str(validation_atlas),
                                      "-o", str(out), "--no-reference-cache"])  # fmt: skip
    assert result.exit_code == 3, result.output
    assert result.output == (f"atlasgen: error: scene {shown!r}: no pixel of its {size} shows material 'matte' (nothing "
                             "to compare); expected a scene in which it is visible (an object with material = '$material' "
                             "in view of the camera, covering a pixel centre)\n")  # fmt: skip
    assert not out.exists()


@pytest.mark.slow
def test_a_black_scene_meets_no_goal_and_prints_no_inf(validation_atlas, mitsuba_rgb, gpu_device, tmp_path):  # noqa: F811
    """Albedo 0 on every object: atlas and references are black on every pixel of the material, a "perfect" match
    that measures nothing. It was "all goals met ... worst inf dB"; now each comparison says it measures nothing,
    no goal is met (none missed either), the lines say "not measured" with no inf, and --strict counts it."""
    black = _front_scene(tmp_path, "black", sphere=("albedo = [1.0, 1.0, 1.0]", "albedo = [0.0, 0.0, 0.0]"),
                         plane=("albedo = [0.6, 0.6, 0.6]", "albedo = [0.0, 0.0, 0.0]"))  # fmt: skip
    args = ["validate", "matte", "--scene", str(black), "--scene", "front", "--resolution", "24x18",
            "--atlas", str(validation_atlas), "--no-reference-cache"]  # fmt: skip
    result = CliRunner().invoke(app, [*args, "-o", str(tmp_path / "v")])
    assert result.exit_code == 0, result.output
    assert "inf" not in result.stdout and "all goals met" not in result.stdout
    line = result.stdout.splitlines()[0]
    assert line.startswith("matte: not measured: model reference, look; storage 1/1 met") and (
        "not measured on black: the reference is black on every compared pixel, unlit or of albedo 0" in line
    )
    assert "not judged on black: not measured: the reference is black" in line
    assert ("2 comparison(s) measure nothing of the material: matte/black (model), matte/black (physical)"
            in result.stdout.splitlines()[-1])  # fmt: skip
    black_row, front_row = json.loads((tmp_path / "v" / "report.json").read_text())["results"]
    for ref in black_row["references"].values():
        assert ref["not_measured"] == "the reference is black on every compared pixel, unlit or of albedo 0"
        assert ref["meets_goal"] is None and ref["psnr_db"] is None and ref["linear_relative_rms"] is None
    assert black_row["look"]["meets_goal"] is None
    assert all("not_measured" not in ref for ref in front_row["references"].values())
    assert front_row["references"]["model"]["meets_goal"] is not None
    strict = CliRunner().invoke(app, [*args, "-o", str(tmp_path / "strict"), "--strict"])
    assert strict.exit_code == 6
    assert "matte on black: nothing measured against the model reference" in strict.stderr
    assert gpu_device.take_errors() == []


@pytest.mark.parametrize(
    "args, code, message",
    [
        (["nosuch"], 3, "no material 'nosuch'; known:"),
        (["mate"], 3, "no material 'mate' (did you mean 'matte'?); known:"),
        (["matte", "--scene", "sideways"], 3, "unknown validation scene; expected one of front, back"),
        (["matte", "--resolution", "big"], 2, "expected WIDTHxHEIGHT"),
        (["matte", "--spp", "0"], 2, "--spp"),
        # Mitsuba's stratified sampler rounded 2 up to 4 (a warning on stdout), and the report recorded 2.
        (
            ["matte", "--spp", "2"],
            2,
            "Invalid value for '--spp': expected a square number of samples (1, 4, 9, 16, ...; "
            "1 or 4 here), which Mitsuba's stratified sampler lays out k x k, got 2",
        ),
        # It was raised to --physical-spp in silence, and the report recorded a maximum nobody asked for.
        (
            ["matte", "--physical-spp", "64", "--max-physical-spp", "4"],
            2,
            "Invalid value for '--max-physical-spp': expected at least --physical-spp (64), got 4",
        ),
    ],
)
@pytest.mark.slow
def test_bad_input_gets_one_clear_line_and_writes_nothing(validation_atlas, tmp_path, args, code, message):  # noqa: F811
    out = tmp_path / "v"
    result = CliRunner().invoke(app, ["validate", *args, "--atlas", str(validation_atlas), "-o", str(out)])
    assert result.exit_code == code
    assert message in result.output
    assert not out.exists()


@pytest.mark.parametrize(("value", "got"), [('"glass"', "got 'glass'"), ("NaN", "got nan (not finite)"), ("0.5", "got 0.5")])
def test_a_manifest_parameter_its_model_would_refuse_is_named_before_any_reference(
    validation_atlas,  # noqa: F811
    tmp_path,
    value,
    got,
):
    """A consistent hand edit (the includes' hash lines follow the manifest) of coat's ior: "glass" reached the Fresnel
    code (an internal error, exit 1) and NaN Mitsuba's, named '<bsdf>'. Each is refused as a material file's would be,
    naming the manifest's field."""
    import hashlib
    import shutil

    from atlasgen.io.atlas import INCLUDE_HASH_PREFIX

    for f in validation_atlas.parent.glob("atlas.*"):
        shutil.copy(f, tmp_path / f.name)
    manifest = tmp_path / "atlas.json"
    data = json.loads(manifest.read_text())
    index = next(i for i, m in enumerate(data["materials"]) if m["name"] == "coat")
    data["materials"][index]["params"]["ior"] = json.loads(value, parse_constant=float)
    text = json.dumps(data, indent=2)
    manifest.write_text(text)
    digest = hashlib.sha256(text.encode()).hexdigest()
    for include in tmp_path.glob("atlas.[wgh]*sl"):
        include.write_text(f"{INCLUDE_HASH_PREFIX}{digest}\n" + include.read_text().split("\n", 1)[1])
    out = tmp_path / "v"
    result = CliRunner().invoke(app, ["validate", "coat", "--atlas", str(tmp_path / "atlas.dds"), "-o", str(out), "-q"])
    assert result.exit_code == 3, result.output
    assert result.stderr == (f"atlasgen: error: {manifest.as_posix()}: field 'materials[{index}].params.ior': expected a "
                             f"finite number >= 1.01 and <= 4, {got}\n")  # fmt: skip
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


#: Named pipes (:func:`_fifo`) that a reader blocked on.
_WAITED_ON: set = set()


def _fifo(path):
    """A named pipe at ``path``. Should a reader block on it, a writer opens and closes it after 30 s and
    records it in :data:`_WAITED_ON`, so that the test fails rather than hangs the suite."""
    import threading

    def release():
        try:
            os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))  # ENXIO where no reader waits
        except OSError:
            return
        _WAITED_ON.add(path)

    os.mkfifo(path)
    threading.Timer(30.0, release).start()
    return path


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
        # Hashed before it was parsed, a named pipe was read for ever (a hostile sweep's hang).
        (lambda tmp, folder: _fifo(tmp / "pipe.mtlx"), "expected a regular file, got a named pipe"),
        (lambda tmp, folder: _fifo(tmp / "pipe.toml"), "expected a regular file, got a named pipe"),
    ],
    ids=["missing", "changed-since-the-bake", "not-in-the-atlas", "a-named-pipe-document", "a-named-pipe-material"],
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
    assert path not in _WAITED_ON, "validate waited on a named pipe for a writer"


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
    # The merge judges the goals the runs recorded: a record that misses fails it.
    report = tmp_path / "coat" / "report.json"
    data = json.loads(report.read_text())
    model = data["results"][0]["references"]["model"]
    model["meets_goal"] = False
    report.write_text(json.dumps(data))
    result = runner.invoke(app, merge)  # a verdict its figures do not give: not what validate writes
    assert result.exit_code == 3 and "meets_goal': expected true from its figures" in result.stderr, result.stderr
    model["psnr_db"] = -1.0  # below the goal of 0 dB: the verdict follows
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
    assert environment["reference_cache"] == "../build/cache/references"  # from the report's folder, as the atlas is
    # --no-reference-cache: the default cache's render is neither read nor counted (naming another cache with it
    # is refused: tests/cli/test_options.py).
    assert runner.invoke(app, [*args, "-o", "third", "--no-reference-cache"]).exit_code == 0
    environment = json.loads((tmp_path / "third" / "report.json").read_text())["environment"]
    assert environment["reference_renders_from_cache"] == 0
    assert gpu_device.take_errors() == []


def _spoil_nan(image):
    return np.full_like(image, np.nan)


def _spoil_small(image):
    return np.ones((3, 3, 3), dtype=np.float32)


def _spoil_scaled(image):
    return image * np.float32(0.5)


@pytest.mark.mitsuba
@pytest.mark.parametrize(
    "spoil, why",
    [
        (_spoil_nan, "image has 1296 values that are not finite"),
        (_spoil_small, "image is float32 3x3x3; expected float32 18x24x3"),
        (_spoil_scaled, "image does not match its record's digest (changed since it was stored)"),
    ],
    ids=["all-nan", "another-size", "scaled"],
)
@pytest.mark.slow
def test_a_reference_cache_entry_whose_image_is_not_a_render_is_rendered_again(validation_atlas, mitsuba_rgb, gpu_device,  # noqa: F811
                                                                               tmp_path, spoil, why):  # fmt: skip
    """An entry whose image was all NaN gave made-up figures (11.8 dB, FLIP 0.684), one of another size an internal
    error, a scaled one its scaled figures: each is a miss now, rendered again with one warning naming it, and the
    figures are those of a fresh render."""
    runner = CliRunner()
    cache = tmp_path / "references"
    args = ["validate", "matte", *TINY_RUN, "--atlas", str(validation_atlas), "-q", "--reference-cache", str(cache)]
    assert runner.invoke(app, [*args, "-o", "first"]).exit_code == 0
    (entry,) = cache.glob("*.npz")
    with np.load(entry) as data:
        arrays = dict(data)
    arrays["image"] = spoil(arrays["image"])
    np.savez(entry, **arrays)
    result = runner.invoke(app, [*args, "-o", "second"])
    assert result.exit_code == 0, result.output
    assert result.stderr.splitlines() == [f"atlasgen: warning: {entry.as_posix()}: {why}; rendered again"]
    first, second = (json.loads((tmp_path / d / "report.json").read_text()) for d in ("first", "second"))
    assert second["environment"]["reference_renders_rejected"] == 1 and second["environment"]["reference_renders_stored"] == 1
    model = [d["results"][0]["references"]["model"] for d in (first, second)]
    assert model[1]["psnr_db"] == model[0]["psnr_db"] and model[1]["flip"] == model[0]["flip"]
    # The entry stored again is a render: a third run uses it and warns of nothing.
    third = runner.invoke(app, [*args, "-o", "third"])
    assert third.exit_code == 0 and third.stderr == ""
    assert json.loads((tmp_path / "third" / "report.json").read_text())["environment"]["reference_renders_from_cache"] == 1
    assert gpu_device.take_errors() == []


@pytest.mark.slow
def test_the_report_records_what_identifies_each_validated_material(validation_atlas, mitsuba_rgb, gpu_device, tmp_path):  # noqa: F811
    """report.json names the atlas and the material its figures were measured on (atlasgen.validate.identity), so
    a reader given an atlas can tell them current (atlasgen report library)."""
    from atlasgen.io.atlas import read_atlas
    from atlasgen.validate.identity import atlas_identity

    out = tmp_path / "v"
    result = CliRunner().invoke(app, ["validate", "matte", "coat", *TINY_RUN, "--atlas", str(validation_atlas), "-o", str(out),
                                      "-q", "--no-reference-cache"])  # fmt: skip
    assert result.exit_code == 0, result.output
    atlas = read_atlas(validation_atlas)
    rows = json.loads((out / "report.json").read_text())["results"]
    assert [r["material"] for r in rows] == ["matte", "coat"]
    for row in rows:
        identity = atlas_identity(atlas, atlas.material(row["material"]))
        assert row["atlas_identity"] == identity and identity["manifest_sha256"] == atlas.manifest_sha256
        assert identity["content_hash"] == atlas.material(row["material"]).content_hash
    assert rows[0]["atlas_identity"]["material_sha256"] != rows[1]["atlas_identity"]["material_sha256"]
    assert gpu_device.take_errors() == []


@pytest.mark.mitsuba
@pytest.mark.slow
def test_max_physical_spp_caps_an_environment_reference(validation_atlas, mitsuba_rgb, gpu_device, tmp_path):  # noqa: F811
    """An environment reference stopped at a fixed 4096 spp while the noise-floor warning said to raise
    --max-physical-spp, which changed nothing (so --strict could never pass there). A lambert under the
    sky is short of its floor at 64 spp: it grows to the maximum given, and no further."""
    args = ["validate", "matte", "--scene", "env-sky", "--no-physical", "--resolution", "16x12", "--no-reference-cache",
            "--atlas", str(validation_atlas)]  # fmt: skip
    result = CliRunner().invoke(app, [*args, "--max-physical-spp", "128", "-o", "v"])
    assert result.exit_code == 0, result.output
    ((row,),) = [json.loads((tmp_path / "v" / "report.json").read_text())["results"]]
    reference = row["references"]["model"]
    assert reference["spp"] == 128 and reference["noise_floor_ok"] is False
    (warning,) = [line for line in result.stderr.splitlines() if "noise floor" in line]
    assert warning.startswith("atlasgen: warning: matte on env-sky: ") and warning.endswith("raise --max-physical-spp")
    assert gpu_device.take_errors() == []


@pytest.mark.parametrize("second", ["front", "./scenes/s.toml"], ids=["standard-name", "same-file-spelled-otherwise"])
def test_a_scene_given_twice_is_a_usage_error(second, tmp_path):
    # Exit 2 before the atlas is read or anything rendered: the same option value twice, not a bad file.
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "s.toml").write_text("")
    first = "front" if second == "front" else "scenes/s.toml"
    result = CliRunner().invoke(app, ["validate", "--scene", first, "--scene", second, "--atlas", "missing.dds", "-o", "v"])
    assert result.exit_code == 2, result.output
    assert f"{second} is given twice (the first: --scene {first}); expected each scene once" in result.output
    assert not (tmp_path / "v").exists()


def test_an_input_lying_in_the_report_folder_is_refused_before_any_work(tmp_path):
    """A hostile sweep: a scene file named v3/speed_error.png (or an atlas so named) given with -o v3 was replaced by
    the report's plot, exit 0. Inputs lying in the report folder are refused before anything renders."""
    folder = tmp_path / "v3"
    folder.mkdir()
    scene = folder / "speed_error.png"
    scene.write_text("[camera]\nposition = [0, 0, 4]\ntarget = [0, 0, 0]\n")
    res = CliRunner().invoke(app, ["validate", "--atlas", str(tmp_path / "a.dds"), "--scene", str(scene), "--no-physical",
                                   "-o", str(folder), "clay"])  # fmt: skip
    assert res.exit_code == 4 and res.stderr == (
        f"atlasgen: error: {scene.as_posix()}: the scene (--scene) lies in the report folder (-o), {folder.as_posix()}, "
        "whose files the report replaces; expected the inputs outside it\n"), res.output  # fmt: skip
    assert sorted(p.name for p in folder.iterdir()) == ["speed_error.png"]
    res = CliRunner().invoke(app, ["validate", "--atlas", str(folder / "a.dds"), "--no-physical", "-o", str(folder), "clay"])
    assert res.exit_code == 4 and "the atlas (--atlas) lies in the report folder (-o)" in res.stderr, res.output


@pytest.mark.parametrize("command", [["validate"], ["report", "separable"]])
def test_a_merge_source_that_is_a_file_says_what_was_expected(tmp_path, command):
    """A hostile sweep: a material file given to --merge was read as its folder's report.json: "cannot read (Not a
    directory)", without what a source must be."""
    source = tmp_path / "red-plastic.toml"
    source.write_text('type = "lambert"\n')
    writer = "atlasgen validate" if command == ["validate"] else "atlasgen report separable"
    res = CliRunner().invoke(app, [*command, "--merge", str(source), "-o", str(tmp_path / "m")])
    assert res.exit_code == 3 and res.stderr == (f"atlasgen: error: {source.as_posix()}: a --merge source is a file; "
                                                 f"expected a report folder {writer} -o wrote, or its report.json\n")  # fmt: skip
    assert not (tmp_path / "m").exists()
