"""A comparison that measures nothing of the material (no pixel, or a black reference) meets no goal and shows no inf."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from atlasgen.reports.validation import (
    _goal,
    _summary,
    describe_materials,
    look_verdict,
    missed_goals,
    summary_line,
)
from atlasgen.validate.metrics import BLACK_REFERENCE, NO_PIXELS, compare_images

GOALS = {"psnr_db": 45.0, "flip": 0.01, "look_psnr_db": 30.0, "look_flip": 0.05}
LOOK = {"reference": "physical", "compared": "its physical reference, Mitsuba diffuse", "goal": {"psnr_db": 30.0, "flip": 0.05}}


def _images(reference_value, test_value, shape=(12, 16, 3)):
    rng = np.random.default_rng(3)
    base = rng.uniform(0.2, 0.6, size=shape).astype(np.float32)
    return (base * np.float32(reference_value)), (base * np.float32(test_value))


def test_no_pixel_compared_gives_no_figure_at_all():
    """The finding: psnr_db null but linear_relative_rms 0.0, a relative error of nothing."""
    ref, test = _images(1.0, 0.9)
    m = compare_images(ref, test, mask=np.ones(ref.shape[:2], dtype=bool))
    d = m.as_dict()
    assert m.not_measured == NO_PIXELS and d["not_measured"] == NO_PIXELS
    for key in ("rmse", "psnr_db", "flip", "linear_rmse", "linear_relative_rms", "unclipped_psnr_db"):
        assert d[key] is None, key
    assert d["coverage"] == 0.0


def test_a_black_reference_is_not_measured_whatever_the_atlas_shows():
    black, same = _images(0.0, 0.0)
    m = compare_images(black, same)
    assert m.not_measured == BLACK_REFERENCE and math.isinf(m.psnr)
    assert m.as_dict()["psnr_db"] is None and m.as_dict()["linear_relative_rms"] is None
    black, bright = _images(0.0, 1.0)
    m = compare_images(black, bright)
    assert m.not_measured == BLACK_REFERENCE and math.isfinite(m.psnr) and m.psnr < 20.0  # a real error, measured
    ref, test = _images(1.0, 1.0)
    assert compare_images(ref, test).not_measured is None


def _run_goal(metrics):
    run = SimpleNamespace(goals=True, goal_psnr_db=None)
    return _goal(run, SimpleNamespace(kind="model", metrics=metrics), GOALS)


def test_the_storage_goal_is_never_met_on_nothing_but_a_visible_error_misses():
    black, same = _images(0.0, 0.0)
    assert _run_goal(compare_images(black, same)) is None  # was True: "met", inf dB
    ref, test = _images(1.0, 0.5)
    assert _run_goal(compare_images(ref, test, mask=np.ones(ref.shape[:2], dtype=bool))) is None  # was False on NaN
    black, bright = _images(0.0, 1.0)
    assert _run_goal(compare_images(black, bright)) is False  # the atlas shows light the reference does not
    ref, test = _images(1.0, 1.0)
    assert _run_goal(compare_images(ref, test)) is True


def test_the_look_is_not_judged_on_nothing_but_a_visible_error_misses():
    nothing = {"psnr_db": None, "flip": 0.0, "clipped_pixels": 0, "coverage": 0.4, "not_measured": BLACK_REFERENCE}
    assert look_verdict(LOOK, nothing) == {"meets_goal": None, "not_judged": f"not measured: {BLACK_REFERENCE}"}
    glowing = {**nothing, "psnr_db": 12.0, "flip": 0.4}
    assert look_verdict(LOOK, glowing) == {"meets_goal": False, "not_judged": None}
    # A report written before the field: a coverage of 0 says no pixel was compared.
    empty = {"psnr_db": None, "flip": None, "clipped_pixels": 0, "coverage": 0.0}
    assert look_verdict(LOOK, empty) == {"meets_goal": None, "not_judged": f"not measured: {NO_PIXELS}"}


def _row(scene, model, physical=None):
    row = {"material": "clay", "type": "lambert", "scene": scene, "references": {"model": model}}
    if physical is not None:
        row["references"]["physical"] = physical
        row["look"] = {**LOOK, "goal_source": "default", **look_verdict(LOOK, physical)}
    return row


MEASURED = {"psnr_db": 52.0, "flip": 0.004, "meets_goal": True, "coverage": 0.5}
NOTHING = {"psnr_db": None, "flip": None, "meets_goal": None, "coverage": 0.0, "not_measured": NO_PIXELS}
BLACK = {"psnr_db": None, "flip": 0.0, "meets_goal": None, "coverage": 0.5, "not_measured": BLACK_REFERENCE}


def test_a_result_of_nothing_beside_a_measured_one_sums_up_without_an_error():
    """The finding: '>' not supported between 'NoneType' and 'float' in _summary (two scenes, one showing nothing)."""
    rows = [_row("front", MEASURED), _row("away", NOTHING)]
    s = _summary(rows)
    assert s["worst_lut_flip"] == 0.004 and s["worst_lut_psnr_db"] == 52.0
    assert s["lut_results"] == 1 and s["not_measured"] == ["clay/away (model)"]
    assert _summary([_row("away", NOTHING), _row("black", BLACK)])["worst_lut_flip"] is None


def test_the_lines_say_not_measured_never_inf_or_met():
    data = {"settings": {"goals": GOALS}, "total_seconds": 1.0,
            "results": [_row("front", MEASURED, {**MEASURED, "meets_goal": None}), _row("black", BLACK, dict(BLACK))]}  # fmt: skip
    (line,) = describe_materials(data)
    assert "inf" not in line and "all goals met" not in line and ": met" not in line
    assert line == (
        "clay: not measured: model reference, look; storage 1/1 met (PSNR >= 45 dB, FLIP <= 0.01; worst 52.0 dB, "
        f"FLIP 0.0040), not measured on black: {BLACK_REFERENCE}; look against its physical reference, Mitsuba "
        f"diffuse: 52.0 / n/a dB, FLIP 0.004 / n/a (goal >= 30 dB, FLIP <= 0.05): not judged on black: not measured: "
        f"{BLACK_REFERENCE}"
    )
    assert summary_line(data, "v/index.html") == (
        "v/index.html (2 material/scene results, 1/1 LUT results meet the storage goals, 1/1 looks meet their goal "
        "against physics (1 not judged), 2 comparison(s) measure nothing of the material: clay/black (model), "
        "clay/black (physical), 1.0 s)"
    )
    # --strict: no goal is met on nothing.
    assert missed_goals(data) == [
        f"clay on black: nothing measured against the model reference ({BLACK_REFERENCE})",
        f"clay on black: nothing measured against the physical reference ({BLACK_REFERENCE})",
    ]
    only = {**data, "results": [_row("black", BLACK)]}
    assert describe_materials(only) == [
        f"clay: not measured: model reference; nothing measured against its model reference on black: {BLACK_REFERENCE}"
    ]
    assert "no LUT goal judged" in summary_line(only, "v/index.html")


def test_an_object_out_of_view_gets_no_verdict_of_its_own():
    """A part (an object showing the material) with no pixel: its figures are null, and it neither meets nor
    misses the look goal, nor falls short of a noise floor."""
    parts = {"sphere": {"psnr_db": 42.0, "flip": 0.02, "pixels": 120}, "flat part": {"psnr_db": None, "flip": None,
                                                                                    "pixels": 0}}  # fmt: skip
    v = look_verdict(LOOK, {"psnr_db": 42.0, "flip": 0.02, "parts": parts})
    assert v["meets_goal"] is True and v["parts"]["flat part"] == {"meets_goal": None, "not_judged": None}


def test_a_reference_is_not_short_of_its_floor_on_nothing():
    """A stochastic reference's floor has no error to clear where nothing is measured, nor on an object out of view
    (its floor over no pixel is NaN): it was "short of its noise floor", grown to the cap and failing --strict."""
    from atlasgen.validate.run import ReferenceRender

    def ref(metrics, floor, part_floors):
        image = np.zeros((2, 2, 3), np.float32)
        return ReferenceRender("physical", "volpathmis", image, 1.0, 64, "llvm_ad_rgb", metrics=metrics, second_image=image,
                               noise_floor_db=floor, part_floors=part_floors)  # fmt: skip

    parts = {"sphere": {"psnr_db": 40.0, "pixels": 120}, "flat part": {"psnr_db": None, "pixels": 0}}
    measured = SimpleNamespace(psnr=40.0, parts=parts, not_measured=None)
    assert ref(measured, 55.0, {"sphere": 55.0, "flat part": math.nan}).noise_floor_ok is True
    assert ref(measured, 55.0, {"sphere": 45.0, "flat part": math.nan}).noise_floor_ok is False
    nothing = SimpleNamespace(psnr=math.nan, parts={}, not_measured=NO_PIXELS)
    assert ref(nothing, math.nan, {}).noise_floor_ok is None
