"""atlasgen.bake.quality: which baked materials warn, and the refusal of non-finite samples (issue 21)."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from atlasgen.bake.quality import ERROR_WARNING_THRESHOLD, assess_material, count_nonfinite
from atlasgen.errors import MaterialError

GOLDEN = Path(__file__).resolve().parents[1] / "resources" / "golden" / "array-srgb.json"


def _material(tolerance=0, bsdf=None):
    return SimpleNamespace(source="materials/m.toml", name="m", params={"bsdf": bsdf}, nonfinite_tolerance=tolerance)


@pytest.mark.parametrize("relative_rms, warns", [(0.996, True), (0.24, True), (0.2001, True), (0.2, False), (0.111, False)])
def test_a_fit_error_over_the_threshold_warns_as_an_unreachable_fit(relative_rms, warns):
    """Skin's fit at radius 0.01 mm (99.6%) and 10 m (24%) warn; the shipped skin (11.1%) does not."""
    warnings = assess_material(_material(), {"fit": {"from": "physical", "gloss": 0.5, "relative_rms": relative_rms}})
    assert bool(warnings) == warns
    if warns:
        (w,) = warnings
        assert w.cause == "unreachable fit" and w.figure == relative_rms
        assert str(w).startswith("materials/m.toml: material 'm': relative RMS error ")
        assert f"{100 * relative_rms:.1f}%" in str(w) and "\n" not in str(w)


def test_a_separable_materials_stored_error_is_judged_too():
    (w,) = assess_material(_material(), {"errors_8bit": {"relative_rms": 0.3}})
    assert w.cause == "unreachable fit" and "30.0% of its stored factors" in str(w)
    assert assess_material(_material(), {"errors_8bit": {"relative_rms": 0.03}}) == []


def test_accepted_anisotropy_always_warns_with_its_error():
    (w,) = assess_material(_material(), {"fit": {"relative_rms": 0.05, "anisotropic": True}})
    assert w.cause == "anisotropy" and "5.0%" in str(w) and "anisotropic" in str(w)


def test_a_dropped_delta_lobe_warns_by_its_own_fraction_not_the_fit_error():
    rows = [{"view_deg": 0.0, "fraction": 0.13}, {"view_deg": 80.0, "fraction": 0.7}]
    (w,) = assess_material(_material(), {"fit": {"relative_rms": 0.019, "dropped_delta_fraction": rows}})
    assert w.cause == "dropped delta lobe" and w.figure == 0.7 and "70.0% of the albedo at 80 degrees" in str(w)
    small = [{"view_deg": 80.0, "fraction": ERROR_WARNING_THRESHOLD}]
    assert assess_material(_material(), {"fit": {"relative_rms": 0.019, "dropped_delta_fraction": small}}) == []


def test_a_missed_budget_warns():
    (w,) = assess_material(_material(), {"errors_8bit": {"relative_rms": 0.05}, "max_error": 0.02, "max_error_met": False})
    assert w.cause == "missed budget" and "0.02" in str(w)


def test_non_finite_samples_are_an_error_unless_tolerated_then_a_warning():
    extra = {"nonfinite_samples": 1632, "nonfinite_reference": 8}
    assert count_nonfinite(extra) == 1640 and count_nonfinite({"fit": {"nonfinite_samples": 3}}) == 3
    with pytest.raises(MaterialError) as info:
        assess_material(_material(bsdf={"type": "x"}), extra)
    message = str(info.value)
    assert message.startswith("materials/m.toml: field 'bsdf': ") and "1640 non-finite" in message
    assert "nonfinite_tolerance >= 1640" in message
    with pytest.raises(MaterialError):
        assess_material(_material(tolerance=1639), extra)
    (w,) = assess_material(_material(tolerance=1640), extra)
    assert w.cause == "non-finite samples" and "1640 non-finite samples" in str(w)


def test_no_shipped_material_warns():
    """The goldens' manifest as shipped: none of its materials is over the threshold."""
    manifest = json.loads(GOLDEN.read_text())
    for entry in manifest["materials"]:
        material = SimpleNamespace(source=entry["source"], name=entry["name"], params=entry["params"], nonfinite_tolerance=0)
        assert assess_material(material, entry) == [], entry["name"]


def test_nonfinite_tolerance_is_a_checked_material_field(expect_rejected, write_material):
    from atlasgen.materials.material import read_material

    expect_rejected("lambert", "nonfinite_tolerance = -1", "nonfinite_tolerance", "expected an integer >= 0")
    assert read_material(write_material("ok", 'type = "lambert"\nnonfinite_tolerance = 5\n')).nonfinite_tolerance == 5


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ('type = "lambert"\nrgb_scale = 3e38\n', "100.0% of the texels whose RGB is above 0 are stored as 0: the slice's RGB "
                                                  "scale 3e+38 (rgb_scale = 3e+38)"),
        # F/F0 spans 40401:1 at ior 1.01: the faint face-on A falls below the least step of 8 bits.
        ('type = "fresnel"\nior = 1.01\nnormalise = true\n', "62.8% of the texels whose A is above 0 are stored as 0: "
                                                              "the slice's A scale 4.04e+04 (alpha_scale = auto)"),
        ('type = "lambert"\nrgb_scale = 100\n', None),
        ('type = "fresnel"\nior = 1.5\n', None),
    ],
)  # fmt: skip
def test_a_slice_stored_mostly_as_zero_warns(tmp_path, text, expected):
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_materials

    (tmp_path / "m.toml").write_text(text)
    warnings = [w for w in bake_atlas(read_materials([tmp_path])).material_warnings if w.cause == "lost to 8 bits"]
    if expected is None:
        assert warnings == []
    else:
        (warning,) = warnings
        assert warning.detail.startswith(expected), warning.detail


def _materialx_stand_in(name: str, spec: dict):
    """A material of lib.mtlx as assess_material reads one: the separable model over ``spec`` (params.materialx)."""
    from atlasgen.models import get_model

    return SimpleNamespace(source="lib.mtlx", name=name, params={"materialx": spec}, nonfinite_tolerance=0,
                           model=get_model("separable"))  # fmt: skip


def test_what_a_materialx_material_asks_and_no_slice_holds_warns_sharp_lobes_aside():
    """A document's emission, opacity and transmission were named only in the manifest: an invisible, emissive
    material baked as an opaque reflector without a word, --strict included. The separable model's hook lists
    them (sharp lobes are baked, and the error warning names those)."""
    from atlasgen.models import get_model

    sharp = "specular_roughness = 0.02: a lobe sharper than the renderer's sharpest"
    spec = {"not_in_table": [sharp, "emission = 1.0: emission", "opacity = [0.0, 0.0, 0.0]: opacity"],
            "sharp_lobes": [sharp]}  # fmt: skip
    material = _materialx_stand_in("glow", spec)
    (w,) = assess_material(material, {"errors_8bit": {"relative_rms": 0.03}})
    assert w.cause == "not in the table" and w.figure is None
    assert str(w) == ("lib.mtlx: material 'glow': baked without what its slices cannot hold: emission = 1.0: emission; "
                      "opacity = [0.0, 0.0, 0.0]: opacity")  # fmt: skip
    spec["not_in_table"] = [sharp]
    assert assess_material(material, {"errors_8bit": {"relative_rms": 0.03}}) == []
    assert get_model("lambert").unheld_inputs({}) == []


@pytest.mark.parametrize(("inputs", "field", "tail"), [
    ({"base_color": (0.8, 0.8, 0.8), "specular_IOR": 3e38}, "p.specular_IOR", "; got specular_IOR = 3e+38, far out of range"),
    ({"base_color": (0.8, 0.8, 0.8)}, "p", "turns into finite values"),
    # The nodedefs allow an IOR of 0, which divides by zero in the shader's Fresnel: named, not just the material.
    ({"specular_IOR": 1.5, "coat_IOR": 0.0}, "p.coat_IOR", "; got coat_IOR = 0, an index of refraction near 0"),
    ({"specular_ior": 1e-30}, "p.specular_ior", "; got specular_ior = 1e-30, an index of refraction near 0"),
])  # fmt: skip
def test_non_finite_samples_of_a_materialx_material_name_its_input_not_a_toml_field(inputs, field, tail):
    """The refusal named field 'type' and offered nonfinite_tolerance, a TOML key no document can set; it names the
    document's material and, where one is far out of range, the input (a specular_IOR of 3e38 overflows the oracle)."""
    from atlasgen.models import get_model

    spec = {"material": "p", "inputs": inputs, "not_in_table": [], "sharp_lobes": []}
    material = SimpleNamespace(source="lib.mtlx", name="p", params={"materialx": spec}, nonfinite_tolerance=0,
                               model=get_model("separable"))  # fmt: skip
    with pytest.raises(MaterialError) as info:
        assess_material(material, {"nonfinite_samples": 12})
    message = str(info.value)
    assert message.startswith(f"lib.mtlx: field '{field}': material 'p': the source gave 12 non-finite samples (NaN or "
                              "inf); expected inputs MaterialX's shader (float32 GLSL) turns into finite values")  # fmt: skip
    assert message.endswith(tail) and "nonfinite_tolerance" not in message


def test_inputs_flattened_by_the_bake_are_named_in_a_warning():
    """--flatten default baked a textured alpha as 1 and a driven emission as 0, named only in the manifest's
    materialx.flattened: the bake said nothing, --strict included."""
    from atlasgen.models import get_model

    spec = {"flattened": {"alpha": {"driven_by": "node 'c1'", "value": 1.0},
                          "base_color": {"driven_by": "nodegraph 'NG'", "value": [0.8, 0.25, 0.1]}}}  # fmt: skip
    material = _materialx_stand_in("mask", spec)
    (w,) = assess_material(material, {"errors_8bit": {"relative_rms": 0.03}})
    assert w.cause == "flattened" and w.figure is None
    assert str(w) == ("lib.mtlx: material 'mask': baked with driven inputs at one value (--flatten): alpha (driven by "
                      "node 'c1') as 1; base_color (driven by nodegraph 'NG') as 0.8, 0.25, 0.1")  # fmt: skip
    spec["flattened"] = {}
    assert assess_material(material, {"errors_8bit": {"relative_rms": 0.03}}) == []
    assert get_model("lambert").flattened_inputs({}) == []
