"""The per-material summary lines and the goals ``validate --strict`` checks, from report dicts."""

from __future__ import annotations

import pytest

from atlasgen.reports.validation import describe_materials, missed_goals, summary_line

GOALS = {"psnr_db": 45.0, "flip": 0.01}


def _lut(material, scene, psnr, flip):
    meets = (psnr is None or psnr >= GOALS["psnr_db"]) and flip <= GOALS["flip"]
    return {"material": material, "type": "lambert", "scene": scene,
            "references": {"model": {"psnr_db": psnr, "flip": flip, "meets_goal": meets}}}  # fmt: skip


def _separable(material, scene, claimed, budget, measured):
    return {"material": material, "type": "separable", "scene": scene,
            "references": {"model": {"psnr_db": 30.0, "flip": 0.2, "meets_goal": None}},
            "claimed_errors": {"relative_rms_8bit": claimed, "error_budget": budget,
                               "measured_relative_rms_atlas_vs_source": measured}}  # fmt: skip


def _report(*rows):
    lut = [r["references"]["model"] for r in rows if r["type"] != "separable"]
    summary = {"lut_results": len(lut), "lut_meeting_goals": sum(1 for m in lut if m["meets_goal"])}
    return {"settings": {"goals": GOALS}, "results": list(rows), "summary": summary, "total_seconds": 2.0}


def test_a_lut_material_counts_its_scenes_and_names_the_worst_figures():
    data = _report(_lut("clay", "front", 52.04, 0.004), _lut("clay", "back", 44.5, 0.0123), _lut("snow", "front", None, 0.0))
    assert describe_materials(data) == [
        "clay: 1/2 LUT goals met (PSNR >= 45 dB, FLIP <= 0.01); worst PSNR 44.5 dB, FLIP 0.0123",
        "snow: 1/1 LUT goals met (PSNR >= 45 dB, FLIP <= 0.01); worst PSNR inf dB, FLIP 0.0000",
    ]
    assert missed_goals(data) == ["clay on back: PSNR 44.5 dB, FLIP 0.0123 (PSNR >= 45 dB, FLIP <= 0.01)"]


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
    assert describe_materials(data) == [
        f"gold: no LUT goals apply; separable error 1.75% (8-bit, claimed; {verdict}), 3.40% measured in the scenes "
        f"(worst, atlas against source)"
    ]
    assert missed_goals(data) == missed
    assert summary_line(data, "v/index.html") == "v/index.html (2 material/scene results, no LUT goals apply, 2.0 s)"


def test_the_summary_line_counts_lut_results_only_when_there_are_some():
    data = _report(_lut("clay", "front", 50.0, 0.005), _separable("gold", "front", 0.02, None, 0.02))
    assert summary_line(data, "v/index.html") == "v/index.html (2 material/scene results, 1/1 LUT results meet the goals, 2.0 s)"
