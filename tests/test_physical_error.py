"""Error against the physical reference of every candidate representation, and ``representation = "auto"``'s LUT.

The materials here are separable materials with NumPy sources (no Mitsuba): their source is
their physical reference (atlasgen/models/physical_error.py).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from atlasgen.io.fields import validate_params
from atlasgen.models import get_model
from atlasgen.models.physical_error import physical_brdf, physical_candidates
from atlasgen.models.physical_lut import fit_lut, slice_f_cos, stored_slice
from atlasgen.models.separable import Separable
from atlasgen.separable.approximate import reference_values
from atlasgen.separable.auto import choose_representation, read_lighting_cost
from atlasgen.separable.error import sample_error_pairs, weighted_errors

#: A broad, low-contrast BRDF: a Blinn-Phong sheen over a Lambertian base (one LUT slice fits it to ~2%).
BROAD = {"source": "blinn_phong", "exponent": 4.0, "specular": [0.2, 0.2, 0.2], "diffuse": [0.5, 0.35, 0.25]}
#: A rough Beckmann metal (the shipped separable-rough-metal).
ROUGH_METAL = {"source": "beckmann", "alpha": 0.5, "fresnel": "schlick", "f0": [0.56, 0.57, 0.58], "terms": 4}
#: The LUTs fitted from physics, in the candidates' order: point-sampled, the footprint's mean, fitted over the footprint.
FITTED_LUTS = ("lut: fitted from physics", "lut: fitted from physics, 8-bit", "lut: fitted from physics, 4x4 supersampled",
               "lut: fitted from physics, 4x4 supersampled, 8-bit", "lut: fitted from physics over the 4x4 footprint",
               "lut: fitted from physics over the 4x4 footprint, 8-bit")  # fmt: skip


def _values(raw: dict) -> dict:
    return validate_params(Separable.params, raw, "<test>")


@pytest.fixture(scope="module")
def metal_candidates():
    return physical_candidates(Separable(), _values(ROUGH_METAL))


@pytest.mark.slow
def test_lut_error_agrees_with_a_dense_uniform_estimate(metal_candidates):
    """The importance-sampled LUT error (100 000 pairs) against 2 000 000 uniform pairs, within 3 combined SE."""
    values = _values(ROUGH_METAL)
    brdf = physical_brdf(Separable(), values)
    rgba, info = fit_lut(brdf.params)
    dense = sample_error_pairs(2_000_000, 7, None)
    reference, _ = reference_values(brdf.source(), dense)
    brute = weighted_errors(reference, slice_f_cos(stored_slice(rgba), info["gloss"], dense.l, dense.v), dense.weight, log=False)
    got = next(c for c in metal_candidates["candidates"] if c["representation"] == "lut: fitted from physics, 8-bit")
    assert got["error"] > 0.05  # a real error, not a trivially small one
    assert abs(got["error"] - brute["relative_rms"]) < 3.0 * np.hypot(got["error_se"], brute["relative_rms_se"])
    assert got["gloss"] == info["gloss"] and got["cost"] == read_lighting_cost().cost("lut")


@pytest.mark.slow
def test_candidates_cover_every_representation(metal_candidates):
    labels = [c["representation"] for c in metal_candidates["candidates"]]
    assert labels == [*FITTED_LUTS, *[f"separable:{k}" for k in range(1, 9)], "analytic:beckmann"]
    assert metal_candidates["skipped"] == [] and metal_candidates["sphere"] is False
    table = read_lighting_cost()
    for c in metal_candidates["candidates"]:
        assert c["cost"] == table.cost(c["cost_key"])
        assert c["error"] >= 0.0 and c["error_se"] >= 0.0
    assert metal_candidates["candidates"][-1]["error"] == 0.0  # the shader's own closed form
    assert metal_candidates["cost_device"] == table.device and metal_candidates["seed"] == 20260101
    # The separable errors shrink with K (the same estimator, so within noise).
    errors = [c["error"] for c in metal_candidates["candidates"] if c["representation"].startswith("separable:")]
    assert all(b <= a * 1.02 for a, b in zip(errors, errors[1:]))
    # Deterministic: the same inputs give the same figures.
    again = physical_candidates(Separable(), _values(ROUGH_METAL))
    assert json.dumps(again, sort_keys=True) == json.dumps(metal_candidates, sort_keys=True)


def test_models_without_a_projectable_reference_say_why():
    toon = get_model("toon")
    values = validate_params(toon.params, {}, "<test>")
    result = physical_candidates(toon, values)
    assert result["reference"] is None and "toon" in result["reason"]


def _auto(budget: float):
    return Separable().bake(_values({**BROAD, "representation": "auto", "max_error": budget}))


@pytest.mark.slow
def test_auto_bakes_a_broad_brdf_as_one_lut_slice_within_a_loose_budget():
    loose = _auto(0.05)
    assert loose.values.shape[0] == 1
    rep, fit = loose.extra["representation"], loose.extra["fit"]
    auto = rep["auto"]
    assert rep["kind"] == "lut" and rep["meets_budget"] and auto["chosen"] == "lut"
    lut = next(c for c in auto["candidates"] if c["representation"] == "lut")
    assert lut["error"] <= 0.05 and lut["error_se"] > 0.0 and rep["reconstruction_error"] == lut["error"]
    assert auto["cost_device"] == read_lighting_cost().device and auto["cost_unit"] == read_lighting_cost().unit
    assert {c["representation"] for c in auto["candidates"]} == {"lut", *[f"separable:{k}" for k in range(1, 9)]}
    assert fit["from"] == "auto" and fit["gloss"] == lut["gloss"]
    # The slice is the fitted one; a tight budget picks a costlier, closer candidate.
    tight = _auto(lut["error"] / 2)
    chosen = tight.extra["representation"]["auto"]["chosen"]
    assert chosen.startswith("separable:")
    closer = next(c for c in tight.extra["representation"]["auto"]["candidates"] if c["representation"] == chosen)
    assert closer["error"] < lut["error"] and closer["cost"] > lut["cost"]
    # Monotone: over the recorded candidates, a tighter budget never gives a larger error nor a lower cost.
    picks = [auto["candidates"][choose_representation(auto["candidates"], b)[0]] for b in (0.5, 0.05, 0.02, 0.01, 0.004, 1e-4)]
    assert [p["error"] for p in picks] == sorted((p["error"] for p in picks), reverse=True)
    assert [p["cost"] for p in picks] == sorted(p["cost"] for p in picks)


@pytest.mark.slow
def test_auto_lut_is_drawn_as_a_plain_slice_at_the_fitted_gloss(tmp_path, write_material):
    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.materials.material import read_materials
    from atlasgen.render.lighting import material_dispatch_wgsl

    write_material("sheen", 'type = "separable"\nsource = "blinn_phong"\nexponent = 4.0\nspecular = [0.2, 0.2, 0.2]\n'
                            'diffuse = [0.5, 0.35, 0.25]\nrepresentation = "auto"\nerror_budget = 0.05\n')  # fmt: skip
    path = tmp_path / "atlas.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), path)
    manifest = json.loads(path.with_suffix(".json").read_text())
    entry = manifest["materials"][0]
    assert entry["slice_count"] == 1 and entry["representation"]["kind"] == "lut"
    assert entry["representation"]["auto"]["chosen"] == "lut" and entry["fit"]["from"] == "auto" and "gloss" in entry["fit"]
    from atlasgen.io.manifest import read_manifest

    typed = read_manifest(path.with_suffix(".json")).materials[0]
    glue = material_dispatch_wgsl(read_manifest(path.with_suffix(".json")))
    assert "lut_slice_f_cos(atlas, samp, 0u, n, l, v, " in glue
    assert "fn lut_slice_f_cos(" in path.with_suffix(".wgsl").read_text()
    # Validation's rebuild draws the stored slice at the fitted gloss, times the albedo: at a
    # mirror pair it equals the renderer's equation with that gloss, not the g-buffer's.
    rebuild = Separable().radiance_rebuilds(typed, path)["8bit"].radiance
    n = np.array([[0.0, 0.0, 1.0]])
    l = np.array([[0.6, 0.0, 0.8]])
    v = np.array([[-0.6, 0.0, 0.8]])
    albedo = np.array([0.5, 1.0, 1.0])
    a = rebuild(n, l, v, albedo, 0.5, np.ones(3))
    b = rebuild(n, l, v, albedo, 0.9, np.ones(3))
    np.testing.assert_array_equal(a, b)  # the g-buffer gloss plays no part
    from atlasgen.io.atlas import read_atlas

    table = read_atlas(path).decode_slice(0)
    expected = albedo * slice_f_cos(table, entry["fit"]["gloss"], l, v)
    np.testing.assert_allclose(a, expected, rtol=1e-12)


def test_analytic_twin_of_a_mitsuba_bsdf():
    from atlasgen.models.physical_error import analytic_twin

    diffuse = {"source": "mitsuba", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.2, 0.3, 0.4]}}}
    twin = analytic_twin(diffuse)
    assert twin["source"] == "lambert" and list(twin["diffuse"]) == [0.2, 0.3, 0.4]
    assert list(analytic_twin({"source": "mitsuba", "bsdf": {"type": "diffuse"}})["diffuse"]) == [0.5, 0.5, 0.5]
    assert analytic_twin({"source": "mitsuba", "bsdf": {"type": "roughplastic"}}) is None
    assert analytic_twin({"source": "ggx"}) is None


@pytest.mark.slow
def test_a_lambert_material_is_exact_as_its_model_and_its_analytic_twin(mitsuba_llvm):
    """terracotta's physical reference is Mitsuba's diffuse: the model's closed form and the shader's
    Lambert match it to rounding; its 8-bit slices do not (the quantisation's error)."""
    from atlasgen.bake.adaptive import bake_supersampled

    lambert = get_model("lambert")
    values = validate_params(lambert.params, {"colour": [0.7, 0.4, 0.2]}, "<test>")
    result = physical_candidates(lambert, values, bake_supersampled)
    by = {c["representation"]: c for c in result["candidates"]}
    assert by["lut: model closed form (no texels)"]["error"] < 1e-5
    assert by["analytic:lambert"]["error"] < 1e-5 and by["analytic:lambert"]["cost"] == read_lighting_cost().cost(
        "analytic:lambert"
    )
    assert 1e-3 < by["lut: model, point-sampled, 8-bit"]["error"] < 1e-2


def _leaf():
    from atlasgen.materials.material import read_material
    from tests.models.test_physical_fit_models import MATERIALS

    material = read_material(MATERIALS / "leaf.toml")
    return material.model, material.params


@pytest.fixture(scope="module")
def leaf_candidates():
    from atlasgen.bake.adaptive import bake_supersampled

    model, values = _leaf()
    return physical_candidates(model, values, bake_supersampled, gloss=0.5)


@pytest.mark.slow
def test_a_thin_sheet_is_measured_over_the_sphere_with_no_separable_candidate(leaf_candidates):
    """leaf's reference (the thin sheet) transmits: l covers the sphere; LUT candidates only, each
    skipped representation with its reason; the fit from physics is the shipped bake's slice."""
    result = leaf_candidates
    assert result["sphere"] and result["estimator"] == "defensive-ggx-mixture-sphere" and result["gloss"] == 0.5
    labels = [c["representation"] for c in result["candidates"]]
    assert labels[:2] == ["lut: model closed form (no texels)", "lut: model, point-sampled, 8-bit"]
    assert labels[2:] == list(FITTED_LUTS)
    assert {k["representation"]: bool(k["reason"]) for k in result["skipped"]} == {"separable": True, "analytic": True}
    by = {c["representation"]: c for c in result["candidates"]}
    # The model's azimuth-dependent back-light against the sheet's diffuse transmission: far apart;
    # the fit from physics within a few percent.
    assert by["lut: fitted from physics, 8-bit"]["error"] < 0.1 < by["lut: model, point-sampled, 8-bit"]["error"]


@pytest.mark.slow
def test_the_sphere_estimate_of_a_transmitting_reference_agrees_with_a_dense_uniform_one(leaf_candidates):
    """The importance-sampled error of leaf's 8-bit fitted slice (100 000 pairs over the sphere) against
    1 000 000 uniform pairs (l uniform over the sphere), within 3 combined SE. For the model's own
    slice, whose back-light is the azimuth-averaged real-time term, the sphere estimate differs from
    the reflection-only one (upper hemisphere): light from behind is counted."""
    from atlasgen.models.physical_fit import fit_slice

    model, values = _leaf()
    physical = model.physical_f_cos(values, 0.5)
    rgba, _ = fit_slice(physical.f_cos, 0.5)
    stored = stored_slice(rgba)
    dense = sample_error_pairs(1_000_000, 7, None, sphere=True)
    brute = weighted_errors(physical.f_cos(dense.l, dense.v), slice_f_cos(stored, 0.5, dense.l, dense.v), dense.weight, log=False)
    got = next(c for c in leaf_candidates["candidates"] if c["representation"] == "lut: fitted from physics, 8-bit")
    assert abs(got["error"] - brute["relative_rms"]) < 3.0 * np.hypot(got["error_se"], brute["relative_rms_se"])
    own = stored_slice(model.bake(values).values[0])
    sphere = weighted_errors(physical.f_cos(dense.l, dense.v), slice_f_cos(own, 0.5, dense.l, dense.v), dense.weight, log=False)
    upper = sample_error_pairs(1_000_000, 7, None)
    reflection = weighted_errors(
        physical.f_cos(upper.l, upper.v), slice_f_cos(own, 0.5, upper.l, upper.v), upper.weight, log=False
    )
    assert abs(reflection["relative_rms"] - sphere["relative_rms"]) > 3.0 * np.hypot(
        reflection["relative_rms_se"], sphere["relative_rms_se"]
    )


@pytest.mark.slow
def test_skin_says_plainly_it_is_lut_only():
    model = get_model("sss")
    values = validate_params(model.params, {}, "<test>")
    result = physical_candidates(model, values)
    assert result["reference"] is None and result["reason"].startswith("LUT only") and "not a BRDF" in result["reason"]


@pytest.mark.slow
def test_a_thin_film_without_back_light_has_separable_candidates():
    """beetle-shell's reference is the separable thin_film source: K = 1..8 measured, on the upper hemisphere."""
    from atlasgen.bake.adaptive import bake_supersampled
    from atlasgen.materials.material import read_material
    from tests.models.test_physical_fit_models import MATERIALS

    material = read_material(MATERIALS / "beetle-shell.toml")
    result = physical_candidates(material.model, material.params, bake_supersampled, gloss=0.5)
    labels = [c["representation"] for c in result["candidates"]]
    assert [f"separable:{k}" for k in range(1, 9)] == [x for x in labels if x.startswith("separable:")]
    assert set(FITTED_LUTS) <= set(labels)
    assert not result["sphere"] and [k["representation"] for k in result["skipped"]] == ["analytic"]


@pytest.mark.slow
def test_a_back_lit_film_has_separable_candidates_measured_over_the_sphere():
    """iridescent-backlit's film transmits: its separable candidates are the terms plus the transmission
    slice, measured with l over the whole sphere. K = 8's figure agrees with 10^6 uniform sphere pairs
    of the same 8-bit rebuild within 3 combined SE; without the slice it would miss the back-light."""
    from dataclasses import replace

    from atlasgen.bake.adaptive import bake_supersampled
    from atlasgen.materials.material import read_material
    from atlasgen.models.separable import stored_factors
    from atlasgen.separable.rebuild import evaluate_factors
    from tests.models.test_physical_fit_models import MATERIALS

    material = read_material(MATERIALS / "iridescent-backlit.toml")
    result = physical_candidates(material.model, material.params, bake_supersampled, gloss=0.5)
    assert result["sphere"] and [k["representation"] for k in result["skipped"]] == ["analytic"]
    by = {c["representation"]: c for c in result["candidates"]}
    assert [f"separable:{k}" for k in range(1, 9)] == [x for x in by if x.startswith("separable:")]
    k8 = by["separable:8"]
    physical = material.model.physical_f_cos(material.params, 0.5)
    params = validate_params(Separable.params, physical.source, "<test>")
    baked = Separable().bake({**params, "terms": None, "max_error": 1e-9})
    factors = stored_factors(baked)
    dense = sample_error_pairs(1_000_000, 8, None, sphere=True)
    reference = physical.f_cos(dense.l, dense.v)
    brute = weighted_errors(reference, evaluate_factors(factors, None, dense.l, dense.v), dense.weight, log=False)
    assert abs(k8["error"] - brute["relative_rms"]) < 3.0 * np.hypot(k8["error_se"], brute["relative_rms_se"])
    without = weighted_errors(reference, evaluate_factors(replace(factors, transmission=None), None, dense.l, dense.v),
                              dense.weight, log=False)  # fmt: skip
    assert without["relative_rms"] > k8["error"] + 3.0 * np.hypot(k8["error_se"], without["relative_rms_se"])
