"""The per-material summary lines and the goals ``validate --strict`` checks, from report dicts."""

from __future__ import annotations

import pytest

from atlasgen.reports.validation import describe_materials, look_verdict, missed_goals, summary_line

GOALS = {"psnr_db": 45.0, "flip": 0.01, "look_psnr_db": 30.0, "look_flip": 0.05}
LOOK = {"psnr_db": 30.0, "flip": 0.05}


def _lut(material, scene, psnr, flip):
    meets = (psnr is None or psnr >= GOALS["psnr_db"]) and flip <= GOALS["flip"]
    return {"material": material, "type": "lambert", "scene": scene,
            "references": {"model": {"psnr_db": psnr, "flip": flip, "meets_goal": meets}}}  # fmt: skip


def _separable(material, scene, claimed, budget, measured):
    return {"material": material, "type": "separable", "scene": scene,
            "references": {"model": {"psnr_db": 30.0, "flip": 0.2, "meets_goal": None}},
            "claimed_errors": {"relative_rms_8bit": claimed, "error_budget": budget,
                               "measured_relative_rms_atlas_vs_source": measured}}  # fmt: skip


def _with_look(row, psnr, flip, compared="the Mitsuba roughplastic it was fitted from", goal=LOOK, **figures):
    """``row`` with a physical reference of these figures and its look goal, judged as report_dict judges it."""
    ref = {"psnr_db": psnr, "flip": flip, "meets_goal": None, "clipped_pixels": 0, "spp": 1, **figures}
    look = {"reference": "physical", "compared": compared, "goal": dict(goal),
            "goal_source": "default" if goal == LOOK else "material"}  # fmt: skip
    look.update(look_verdict(look, ref))
    return {**row, "references": {**row["references"], "physical": ref}, "look": look}


def _no_physical(row, why="an artistic model"):
    return {**row, "look": {"reference": None, "compared": None, "goal": dict(LOOK), "why_none": why,
                            "meets_goal": None, "not_judged": None}}  # fmt: skip


def _report(*rows):
    return {"settings": {"goals": GOALS}, "results": list(rows), "total_seconds": 2.0}


def test_a_lut_material_counts_its_scenes_and_names_the_worst_figures():
    data = _report(_lut("clay", "front", 52.04, 0.004), _lut("clay", "back", 44.5, 0.0123), _lut("snow", "front", None, 0.0))
    assert describe_materials(data) == [
        "clay: goals missed: storage; storage 1/2 met (PSNR >= 45 dB, FLIP <= 0.01; worst 44.5 dB, FLIP 0.0123)",
        "snow: storage goals met; storage 1/1 met (PSNR >= 45 dB, FLIP <= 0.01; worst inf dB, FLIP 0.0000)",
    ]
    assert missed_goals(data) == ["clay on back: PSNR 44.5 dB, FLIP 0.0123 (PSNR >= 45 dB, FLIP <= 0.01)"]


def test_an_environment_map_s_own_goal_is_given_with_its_own_worst_figure():
    """With --environment the line gave the default goal beside an environment's worst figure: "storage 4/4 met
    (PSNR >= 45 dB, FLIP <= 0.01; worst 41.4 dB, FLIP 0.0818)", met yet below the goal it stated (a hostile sweep)."""
    sky = {**_lut("clay", "env-sky", 41.4, 0.0818), "goal_psnr_db": 35.0}
    sky["references"]["model"]["meets_goal"] = True  # its own goal: PSNR >= 35 dB
    data = _report(_lut("clay", "front", 52.04, 0.0031), sky)
    assert describe_materials(data) == ["clay: storage goals met; storage 2/2 met (PSNR >= 45 dB, FLIP <= 0.01; worst "
                                        "52.0 dB, FLIP 0.0031; env-sky: PSNR >= 35 dB; worst 41.4 dB)"]  # fmt: skip


@pytest.mark.parametrize(
    "budget, verdict, missed",
    [
        (None, "budget none", []),
        (0.03, "budget 3.00%, met", []),
        (0.01, "budget 1.00%, missed", ["gold: separable error 1.75% over its budget 1.00%"]),
    ],
)
def test_a_separable_material_gives_its_error_and_budget_instead_of_goals(budget, verdict, missed):
    data = _report(_separable("gold", "front", 0.0175, budget, 0.021), _separable("gold", "back", 0.0175, budget, 0.034))
    head = "goals missed: separable budget" if missed else "no LUT goals apply"
    assert describe_materials(data) == [
        f"gold: {head}; separable error 1.75% (8-bit, claimed; {verdict}), 3.40% measured in the scenes "
        f"(worst, atlas against source)"
    ]
    assert missed_goals(data) == missed
    assert summary_line(data, "v/index.html") == "v/index.html (2 material/scene results, no LUT goals apply, 2.0 s)"


def test_the_summary_line_counts_lut_results_only_when_there_are_some():
    data = _report(_lut("clay", "front", 50.0, 0.005), _separable("gold", "front", 0.02, None, 0.02))
    assert (summary_line(data, "v/index.html")
            == "v/index.html (2 material/scene results, 1/1 LUT results meet the storage goals, 2.0 s)")  # fmt: skip


def test_the_line_names_what_the_look_was_compared_with_and_its_figures():
    data = _report(_with_look(_lut("red", "front", 52.0, 0.004), 44.1, 0.021),
                   _with_look(_lut("red", "back", 51.0, 0.005), 44.2, 0.030))  # fmt: skip
    assert describe_materials(data) == [
        "red: all goals met; storage 2/2 met (PSNR >= 45 dB, FLIP <= 0.01; worst 51.0 dB, FLIP 0.0050); "
        "look against the Mitsuba roughplastic it was fitted from: 44.1 / 44.2 dB, FLIP 0.021 / 0.030 "
        "(goal >= 30 dB, FLIP <= 0.05): met"
    ]
    assert missed_goals(data) == []
    assert summary_line(data, "v/index.html") == ("v/index.html (2 material/scene results, 2/2 LUT results meet the storage "
                                                  "goals, 2/2 looks meet their goal against physics, 2.0 s)")  # fmt: skip


def test_goals_met_never_appears_for_a_material_whose_look_misses():
    """The velvet of issue 21: storage perfect (73.7 dB), its BSDF 36.5 / 29.3 dB and FLIP 0.058 / 0.087."""
    data = _report(_with_look(_lut("velvet", "front", 73.7, 0.001), 36.5, 0.058, compared="the Mitsuba principled it was fitted from"),
                   _with_look(_lut("velvet", "back", 74.0, 0.001), 29.3, 0.087, compared="the Mitsuba principled it was fitted from"))  # fmt: skip
    (line,) = describe_materials(data)
    assert "goals met" not in line and line.startswith("velvet: goals missed: look; ")
    assert "look against the Mitsuba principled it was fitted from: 36.5 / 29.3 dB, FLIP 0.058 / 0.087" in line
    assert line.endswith("missed on front, back")
    missed = missed_goals(data)
    assert len(missed) == 2 and missed[1].startswith(
        "velvet on back: look against the Mitsuba principled it was fitted from: PSNR 29.3 dB"
    )
    assert "0/2 looks meet their goal against physics" in summary_line(data, "v/index.html")


def test_a_material_goal_overrides_the_default_and_says_so():
    row = _with_look(_lut("velvet", "front", 73.7, 0.001), 29.3, 0.087, goal={"psnr_db": 28.0, "flip": 0.1})
    (line,) = describe_materials(_report(row))
    assert line.startswith("velvet: all goals met; ") and "(goal >= 28 dB, FLIP <= 0.1, the material's own): met" in line


def test_a_noisy_reference_leaves_a_look_below_its_goal_not_judged_and_names_its_samples_and_floor():
    row = _with_look(_lut("skin", "front", 50.0, 0.005), 28.0, 0.02, noise_floor_db=31.3, noise_floor_ok=False, spp=1024)
    data = _report(row)
    (line,) = describe_materials(data)
    assert line.startswith("skin: look not judged; ") and line.endswith(
        "not judged on front: reference at 1024 spp, floor 31.3 dB"
    )
    assert "goals met" not in line
    text = summary_line(data, "v/index.html")
    assert "0/0 looks meet their goal against physics (1 not judged)" in text
    assert "1 reference(s) short of their noise floor: skin/front (physical, 1024 spp, floor 31.3 dB)" in text
    assert any("noise floor 31.3 dB" in m for m in missed_goals(data))  # --strict fails on it


def test_a_look_that_meets_its_goal_against_a_noisy_reference_is_met_as_a_lower_bound():
    # The reference's noise only adds error, so 38 dB against it is at least 38 dB against the converged one.
    row = _with_look(_lut("skin", "front", 50.0, 0.005), 38.0, 0.02, noise_floor_db=41.3, noise_floor_ok=False, spp=16)
    data = _report(row)
    (line,) = describe_materials(data)
    assert line.endswith(": met (front: a lower bound: reference at 16 spp, floor 41.3 dB)"), line
    assert "1/1 looks meet their goal against physics" in summary_line(data, "v/index.html")
    # Convergence is still reported, and --strict still counts the unconverged reference.
    assert any("noise floor 41.3 dB" in m for m in missed_goals(data))


def test_clipped_pixels_cannot_hide_a_miss():
    ok = _with_look(_lut("snow", "front", 50.0, 0.005), 40.0, 0.02, clipped_pixels=0, unclipped_psnr_db=25.0)
    hidden = _with_look(_lut("snow", "front", 50.0, 0.005), 40.0, 0.02, clipped_pixels=12, unclipped_psnr_db=25.0)
    assert ok["look"]["meets_goal"] is True and hidden["look"]["meets_goal"] is False


def test_a_material_without_a_physical_reference_says_so():
    data = _report(_no_physical(_lut("cel", "front", 50.0, 0.005)), _no_physical(_lut("cel", "back", 50.0, 0.005)))
    (line,) = describe_materials(data)
    assert line == ("cel: storage goals met; storage 2/2 met (PSNR >= 45 dB, FLIP <= 0.01; worst 50.0 dB, "
                    "FLIP 0.0050); no physical reference (an artistic model)")  # fmt: skip
    assert "no physical reference: cel" in summary_line(data, "v/index.html")


def test_the_report_module_s_doctests_pass():
    """The verdict rules (_storage_met, _unmeasured_verdict, look_verdict) by their worked examples."""
    import doctest

    from atlasgen.reports import validation

    result = doctest.testmod(validation)
    assert result.attempted > 0 and result.failed == 0
