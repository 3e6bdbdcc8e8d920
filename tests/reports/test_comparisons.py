"""Pairs of figures that measure the same thing two ways: what each pair reads, and that it says why they differ."""

from __future__ import annotations

from atlasgen.reports.comparisons import SEPARABLE_WHY, SEPARABLE_WHY_LOWER, manifest_pairs, validation_pairs


def _row(material, scene, claimed=None, measured=None):
    claims = (
        None if claimed is None else {"relative_rms_8bit": claimed, "terms": 3, "measured_relative_rms_atlas_vs_source": measured}
    )
    return {"material": material, "scene": scene, "claimed_errors": claims}


def test_a_separable_claim_is_set_beside_the_worst_scene_with_why():
    data = {"results": [_row("sharp", "front", 0.0258, 0.1232), _row("sharp", "back", 0.0258, 0.0811), _row("clay", "front")]}
    pairs = validation_pairs(data)
    assert len(pairs) == 1
    p = pairs[0]
    assert (p["material"], p["first"], p["second"]) == ("sharp", "2.58%", "12.32%")  # the worst scene
    assert "K=3" in p["first_label"] and p["why"] == SEPARABLE_WHY and "alike" in p["why"]


def test_a_scene_figure_below_the_claim_gets_the_reason_that_way_round():
    """The one reason ('a glossy lobe's peak dominates the image figure') was given where the scenes measured less
    than the claim, too (mx_gold 2.90% claimed, 1.84% in the scenes): a reason for the wrong direction."""
    pairs = validation_pairs({"results": [_row("gold", "front", 0.0290, 0.0184), _row("gold", "back", 0.0290, 0.0120)]})
    assert [(p["first"], p["second"], p["why"]) for p in pairs] == [("2.90%", "1.84%", SEPARABLE_WHY_LOWER)]
    assert "the image figure is the lower" in SEPARABLE_WHY_LOWER


def test_a_claim_without_a_scene_measure_has_no_pair():
    assert validation_pairs({"results": [_row("sharp", "front", 0.0258, None)]}) == []


def test_fits_give_their_two_measures_and_skin_its_in_and_out_of_sample_scores():
    film = {"relative_rms": 0.185, "fit_psnr_db": 35.17, "fit_psnr_se_db": 0.15, "model_relative_rms": 0.796,
            "model_psnr_db": 26.42, "model_psnr_se_db": 0.08}  # fmt: skip
    pairs = manifest_pairs("beetle-shell", film)
    assert [(p["first"], p["second"]) for p in pairs] == [("18.50%", "35.17 ± 0.15 dB"), ("79.60%", "26.42 ± 0.08 dB")]
    skin = {"relative_rms": 0.1363, "fit_radii": [0.35, 0.7],
            "out_of_sample": {"validation_sphere": {"radius": 0.5, "relative_rms": 0.1029}, "flat": {"radius": 20.0, "relative_rms": 0.2556}}}  # fmt: skip
    pairs = manifest_pairs("skin", skin)
    assert [(p["first"], p["second"]) for p in pairs] == [("13.63%", "10.29%"), ("13.63%", "25.56%")]
    assert all("0.35, 0.7" in p["first_label"] and p["why"] for p in pairs)
    assert manifest_pairs("clay", None) == []
    separable = manifest_pairs("sharp", None, {"results": [_row("sharp", "front", 0.0258, 0.1232)]})
    assert [p["second"] for p in separable] == ["12.32%"]


def _materialx_row(scene, pixel):
    ratio = {"reference": "Mitsuba roughconductor", "pairs": 12000, "bsdf_p1_p50_p99": [0.999, 1.010, 1.035],
             "bsdf_min_max": [0.998, 1.039], "pixel_p1_p50_p99": pixel}  # fmt: skip
    return {"material": "gold", "scene": scene, "claimed_errors": None, "materialx": {"oracle_over_physical": ratio}}


def test_a_materialx_gold_sets_its_ratio_to_roughconductor_over_pairs_beside_the_pixels():
    pairs = validation_pairs(
        {"results": [_materialx_row("front", [0.999, 1.0, 1.001]), _materialx_row("back", [1.012, 1.024, 1.041])]}
    )
    assert len(pairs) == 1
    p = pairs[0]
    assert "roughconductor" in p["measures"] and "12000" in p["first_label"]
    assert (p["first"], p["second"]) == ("1.010 (0.999 to 1.035)", "1.000 (0.999 to 1.041)")  # the second: over both scenes
    assert validation_pairs({"results": [{"material": "gold", "scene": "front", "materialx": {}}]}) == []
