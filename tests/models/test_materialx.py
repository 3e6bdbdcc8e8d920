"""MaterialX materials in the separable model: their physical stand-in, and what representation = "auto" chooses."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.models.materialx import artistic_ior, materialx_mitsuba_bsdf

GOLD = {"base": 1.0, "base_color": [0.944, 0.776, 0.373], "metalness": 1.0, "specular_color": [0.998, 0.981, 0.751],
        "specular_roughness": 0.25}  # fmt: skip


def _spec(inputs, category="standard_surface"):
    return {"document": "x.mtlx", "material": "M", "category": category, "inputs": inputs, "oracle_inputs": inputs}


def test_artistic_ior_reproduces_its_reflectivity_at_normal_incidence():
    r = np.array([0.944, 0.776, 0.373])
    n, k = artistic_ior(r, np.array([0.998, 0.981, 0.751]))
    np.testing.assert_allclose(((n - 1) ** 2 + k**2) / ((n + 1) ** 2 + k**2), r, rtol=1e-12)


def test_a_metal_gets_roughconductor_and_a_plain_dielectric_roughplastic():
    bsdf, description = materialx_mitsuba_bsdf(_spec(GOLD), albedo=(0.5, 1.0, 1.0))
    assert bsdf["type"] == "roughconductor" and bsdf["alpha"] == pytest.approx(0.0625)
    assert bsdf["specular_reflectance"]["value"] == [0.5, 1.0, 1.0] and "roughconductor" in description
    bsdf, _ = materialx_mitsuba_bsdf(_spec({"base_color": [0.5, 0.1, 0.1], "specular_IOR": 1.4}))
    assert bsdf["type"] == "roughplastic" and bsdf["int_ior"] == pytest.approx(1.4)
    assert bsdf["diffuse_reflectance"]["value"] == pytest.approx([0.5, 0.1, 0.1])


@pytest.mark.parametrize(
    ("inputs", "category"),
    [({**GOLD, "coat": 1.0}, "standard_surface"), ({**GOLD, "sheen": 0.5}, "standard_surface"),
     ({"metalness": 0.5}, "standard_surface"), ({"specular_color": [1.0, 0.5, 0.5]}, "standard_surface"),
     ({}, "open_pbr_surface")],
)  # fmt: skip
def test_no_stand_in_where_mitsuba_has_no_faithful_bsdf(inputs, category):
    assert materialx_mitsuba_bsdf(_spec(inputs, category)) is None


def _directions(rng, n):
    z = rng.uniform(0.2, 1.0, n)
    phi = 2.0 * np.pi * rng.random(n)
    s = np.sqrt(1.0 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], -1)


@pytest.mark.slow
def test_the_oracle_over_roughconductor_is_materialx_s_g2_and_energy_compensation():
    """MaterialX's metal differs from Mitsuba's roughconductor (same n, k, alpha) by exactly its
    height-correlated G2 over Mitsuba's separable G1 G1, and Turquin's energy compensation."""
    pytest.importorskip("MaterialX")
    pytest.importorskip("mitsuba")
    from atlasgen.models.physical_fit import mitsuba_f_cos
    from atlasgen.separable.source import make_source

    rng = np.random.default_rng(7)
    l, v = _directions(rng, 4096), _directions(rng, 4096)
    spec = {**_spec(GOLD), "alpha": 0.0625}
    oracle = make_source({"source": "materialx", "materialx": spec}).f_cos(l, v)
    bsdf, _ = materialx_mitsuba_bsdf(spec)
    mitsuba = mitsuba_f_cos(bsdf)(l, v)
    keep = (mitsuba > 1e-3).all(1)
    a = 0.0625
    nl, nv = l[:, 2], v[:, 2]
    h = (l + v) / np.linalg.norm(l + v, axis=-1, keepdims=True)
    lam = lambda c: np.sqrt(a * a + (1 - a * a) * c * c)  # noqa: E731
    g2 = 2 * nl * nv / (nv * lam(nl) + nl * lam(nv))
    g1 = lambda c: 2 * c / (c + lam(c))  # noqa: E731
    # with the tests' own analytic directional albedo and conductor Fresnel (tests/separable/test_materialx_oracle.py)
    from tests.separable.test_materialx_oracle import _dir_albedo, _fresnel_conductor

    n, k = artistic_ior(np.array(GOLD["base_color"]), np.array(GOLD["specular_color"]))
    f = _fresnel_conductor(np.sum(v * h, -1), n, k)
    ess = _dir_albedo(nv, a)
    expected = (g2 / (g1(nl) * g1(nv)))[:, None] * (1.0 + f * ((1.0 - ess) / ess)[:, None])
    np.testing.assert_allclose((oracle / mitsuba)[keep], expected[keep], rtol=2e-3)


def _auto(inputs, category="standard_surface"):
    from atlasgen.models import get_model

    model = get_model("separable")
    params = {p.name: p.default for p in model.params}
    params.update(source="materialx", materialx={**_spec(inputs, category), "alpha": 0.0625}, representation="auto",
                  max_error=0.03)  # fmt: skip
    model.check(params, "x.mtlx")
    return model.bake(params)


@pytest.mark.slow
def test_auto_draws_a_lambertian_as_one_slice():
    pytest.importorskip("MaterialX")
    slices = _auto({"base_color": [0.5, 0.5, 0.5], "specular": 0.0})
    rep = slices.extra["representation"]
    assert rep["kind"] == "lut" and rep["reconstruction_error"] < 0.01 and slices.values.shape[0] == 1


@pytest.mark.slow
def test_auto_sees_that_gold_s_coloured_highlight_needs_separable_terms():
    """A is a scalar: one slice cannot hold a highlight whose colour changes with the angle."""
    pytest.importorskip("MaterialX")
    slices = _auto(GOLD)
    rep = slices.extra["representation"]
    errors = {c["representation"]: c["error"] for c in rep["auto"]["candidates"]}
    assert rep["kind"] == "separable" and errors["lut"] > 0.1 > min(e for k, e in errors.items() if k != "lut")


@pytest.mark.slow
def test_auto_judged_as_the_scenes_show_it_weighs_nmf_and_reports_on_another_sample():
    """A MaterialX document's budget is in relative log RMS: the search weighs SVD and NMF terms, stops at the
    first K that meets it, chooses on the selection sample and reports the chosen one on the report sample."""
    pytest.importorskip("MaterialX")
    from atlasgen.models import get_model
    from atlasgen.separable.error import ERROR_SEED, SELECTION_SEED, upper_bound

    model = get_model("separable")
    params = {p.name: p.default for p in model.params}
    params.update(source="materialx", representation="auto", max_error=0.04, grid=32,
                  materialx={**_spec(GOLD), "alpha": 0.0625, "error_measure": "relative_log_rms"})  # fmt: skip
    model.check(params, "x.mtlx")
    slices = model.bake(params)
    rep = slices.extra["representation"]
    auto = rep["auto"]
    assert auto["error_measure"] == "relative_log_rms" and (auto["seed"], auto["report_seed"]) == (SELECTION_SEED, ERROR_SEED)
    terms = [c for c in auto["candidates"] if c["representation"] != "lut"]
    assert {c["factorization"] for c in terms} == {"svd", "nmf"}
    last = max(int(c["representation"].split(":")[1]) for c in terms)
    meeting = [c for c in terms if c["meets_budget"]]
    # The search stops at the first K with a candidate meeting the budget, and that K is chosen.
    assert meeting and all(c["representation"] == f"separable:{last}" for c in meeting)
    assert auto["chosen"] == f"separable:{last}" == f"separable:{rep['terms']}"
    chosen = min(meeting, key=lambda c: c["upper_bound"])
    assert slices.extra["factorization"] == chosen["factorization"] and rep["target"] == chosen["target"]
    # The reported figure is measured anew on the report sample: close to the selection's, not the same number.
    reported = auto["reported"]
    assert reported["error"] != chosen["error"] and abs(reported["error"] - chosen["error"]) < 5 * chosen["error_se"]
    assert rep["meets_budget"] == (upper_bound({"e": reported["error"], "e_se": reported["error_se"]}, "e") <= 0.04)
    # The gold's coloured highlight: the LUT cannot meet it.
    assert not auto["candidates"][0]["meets_budget"]


def test_a_log_measured_auto_claims_its_log_error_against_the_budget_not_the_relative_rms():
    """Validation's strict check compares the claimed relative RMS with error_budget: a budget in another measure
    must not be compared with it, and the figure it bounds is claimed beside it."""
    from types import SimpleNamespace

    from atlasgen.io.manifest import SeparableRepresentation
    from atlasgen.models import get_model

    def entry(auto):
        rep = SeparableRepresentation(terms=6, sampling_grid=32, target="f_cos", error_budget=0.04, estimated_error_8bit=0.05,
                                      meets_budget=True, candidates=[], auto=auto)  # fmt: skip
        errors = SimpleNamespace(relative_rms=0.05, relative_rms_se=0.001)
        factors = SimpleNamespace(errors_8bit=errors, errors=None, terms=6)
        return SimpleNamespace(representation=rep, factors=factors)

    model = get_model("separable")
    plain = model.claimed_errors(entry({"error_budget": 0.04}))
    assert (plain["relative_rms_8bit"], plain["error_budget"]) == (0.05, 0.04) and "relative_log_rms_8bit" not in plain
    logged = model.claimed_errors(entry({"error_budget": 0.04, "error_measure": "relative_log_rms",
                                         "reported": {"error": 0.035, "error_se": 0.0004, "seed": 1}}))  # fmt: skip
    assert logged["relative_rms_8bit"] == 0.05 and logged["error_budget"] is None
    assert (logged["relative_log_rms_8bit"], logged["relative_log_rms_8bit_se"], logged["relative_log_rms_budget"]) == (
        0.035,
        0.0004,
        0.04,
    )


_SPEC = ('type = "separable"\nsource = "materialx"\nterms = 1\n[materialx]\ndocument = "x.mtlx"\nmaterial = "M"\n'
         'category = "standard_surface"\n')  # fmt: skip


@pytest.mark.parametrize(("table", "field", "expected"), [
    # Found by a hostile-input hunt: a hand-written table ended in an internal error (a struct.pack or float()
    # failure, exit 1), or baked the nodedef's defaults while the manifest claimed the inputs given.
    ("oracle_inputs = { base_color = [1.0, 2.0] }", "materialx.oracle_inputs.base_color",
     "expected 3 finite numbers (color3, the nodedef's type), got [1.0, 2.0]"),
    ('oracle_inputs = { base_color = "red" }', "materialx.oracle_inputs.base_color", "got 'red'"),
    ("oracle_inputs = { base_colour = [1.0, 0.0, 0.0] }", "materialx.oracle_inputs.base_colour",
     "unknown input of standard_surface (did you mean 'base_color'?)"),
    ("oracle_inputs = { base = 1e300 }", "materialx.oracle_inputs.base", "expected float within 0 .. 1"),
    ('oracle_inputs = { base = 0.5 }\nalpha = "zz"', "materialx.alpha", "expected a finite number > 0, got 'zz'"),
    ("oracle_inputs = {}\nsharp_lobes = \"abc\"", "materialx.sharp_lobes", "expected a list of input names"),
])  # fmt: skip
def test_a_hand_written_materialx_table_is_checked_against_its_nodedef(tmp_path, table, field, expected):
    pytest.importorskip("MaterialX")
    from atlasgen.errors import MaterialError
    from atlasgen.materials.material import read_material

    path = tmp_path / "m.toml"
    path.write_text(_SPEC + table + "\n")
    with pytest.raises(MaterialError) as info:
        read_material(path)
    message = str(info.value)
    assert message.startswith(f"{path.as_posix()}: field '{field}': ") and expected in message, message
    path.write_text(_SPEC + "oracle_inputs = { base = 0.5, base_color = [1.0, 0.0, 0.0] }\n")
    assert read_material(path).name == "m"  # the same table, well formed, reads


def test_the_module_s_doctests_pass():
    import doctest

    from atlasgen.models import materialx

    result = doctest.testmod(materialx)
    assert result.attempted >= 1 and result.failed == 0
