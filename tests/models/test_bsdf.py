"""type = "bsdf" and from = "physical": slices fitted to Mitsuba BSDFs by projection."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from atlasgen.bake.adaptive import bake_material
from atlasgen.contract import texel_centres
from atlasgen.errors import MaterialError
from atlasgen.materials.material import read_material
from atlasgen.models.physical_fit import azimuth_pairs

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "bsdf-roughplastic.toml"


@pytest.mark.slow
def test_bsdf_roughplastic_bakes_and_recovers_its_diffuse_part(mitsuba_llvm):
    """roughplastic's diffuse term depends on (N.L, N.V) only, so the slice's RGB should be
    it: pi f_d cos, read from the same BSDF with its specular reflectance set to 0."""
    from atlasgen.separable.mitsuba_source import evaluate_mitsuba_f_cos, load_mitsuba_bsdf

    material = read_material(EXAMPLE)
    slices = bake_material(material)
    table = slices.values[0]
    assert table.shape == (32, 64, 4) and np.isfinite(table).all() and (table >= 0.0).all()
    fit = slices.extra["fit"]
    assert fit["from"] == "bsdf" and 0.0 <= fit["gloss"] <= 1.0 and fit["relative_rms"] < 0.2

    diffuse_only = dict(material.params["bsdf"], specular_reflectance={"type": "rgb", "value": [0.0, 0.0, 0.0]})
    nl, nv = texel_centres()
    l, v, _, _ = azimuth_pairs(nl, nv, 1)
    truth = np.pi * evaluate_mitsuba_f_cos(load_mitsuba_bsdf(diffuse_only, "test"), l.reshape(-1, 3), v.reshape(-1, 3))
    truth = truth.reshape(table.shape[:2] + (3,))
    inside = (nl[None, :] >= 0.3) & (nv[:, None] >= 0.3)
    relative = np.abs(table[..., :3] - truth)[inside] / truth[inside].max(axis=-1, keepdims=True)
    assert np.median(relative) < 0.05 and np.quantile(relative, 0.9) < 0.1
    assert table[..., 3].max() > 0.1  # the specular lobe went to A


@pytest.mark.slow
def test_from_physical_lambert_gives_back_the_lambertian_slice(mitsuba_llvm, write_material):
    material = read_material(write_material("m", 'type = "lambert"\ncolour = [0.8, 0.4, 0.1]\nfrom = "physical"\n'))
    slices = bake_material(material)
    nl, _ = texel_centres()
    expected = np.maximum(nl, 0.0)[None, :, None] * np.array([0.8, 0.4, 0.1])
    np.testing.assert_allclose(slices.values[0, :, :, :3], np.broadcast_to(expected, (32, 64, 3)), atol=4e-3)
    assert slices.extra["fit"]["from"] == "physical" and slices.extra["fit"]["gloss"] == 0.5


@pytest.mark.slow
def test_fit_gloss_sets_the_gloss_a_physical_fit_is_made_for(mitsuba_llvm, write_material):
    text = 'type = "fresnel"\ncolour = [0.6, 0.1, 0.1]\nfrom = "physical"\n'
    default = read_material(write_material("a", text))
    chosen = read_material(write_material("b", text + "fit_gloss = 0.3\n"))
    assert (default.fit_gloss, chosen.fit_gloss) == (0.5, 0.3)
    fit = bake_material(chosen).extra["fit"]
    # The roughplastic reference is the one of the fit's gloss (alpha (1 - 0.3)^2 = 0.49).
    assert fit["gloss"] == 0.3 and "alpha" not in fit
    assert not np.allclose(bake_material(default).values, bake_material(chosen).values, atol=1e-3)


@pytest.mark.parametrize("text, expected", [
    ('type = "fresnel"\nfit_gloss = 0.3\n', "fit_gloss.*expected no fit_gloss without from = 'physical'"),
    ('type = "lambert"\nfrom = "physical"\nfit_gloss = 1.5\n', "fit_gloss.*expected a finite number >= 0 and <= 1, got 1.5"),
])  # fmt: skip
def test_fit_gloss_is_checked(write_material, text, expected):
    with pytest.raises(MaterialError, match=expected):
        read_material(write_material("m", text))


@pytest.mark.slow
def test_from_physical_fresnel_bakes_from_roughplastic(mitsuba_llvm, write_material):
    """The fitted slice, drawn by the renderer's equation (A.rgb / pi + A.a D V max(N.L, 0) at the
    fit's gloss), gives back the roughplastic's f cos averaged over the azimuth: the projection's
    weights are uniform in the azimuth and the diffuse basis is constant along it, so at a texel
    where no bound is active the residual's azimuthal mean is zero."""
    from atlasgen.models.physical_fit import AZIMUTHS, FIT_GLOSS, plain_bsdf_reference
    from atlasgen.models.physical_lut import slice_f_cos
    from atlasgen.separable.mitsuba_source import evaluate_mitsuba_f_cos, load_mitsuba_bsdf

    material = read_material(write_material("m", 'type = "fresnel"\ncolour = [0.6, 0.1, 0.1]\nfrom = "physical"\n'))
    baked = bake_material(material)
    table = baked.values[0]
    assert np.isfinite(table).all() and (table >= 0.0).all() and table[..., 3].max() > 0.0
    reference = plain_bsdf_reference(material.model, material.params, FIT_GLOSS)
    assert reference.bsdf["type"] == "roughplastic"
    bsdf = load_mitsuba_bsdf(reference.bsdf, "<roughplastic>")
    nl, nv = texel_centres()
    for row, column in [(8, 44), (16, 52), (24, 60), (28, 40)]:
        l, v, _, _ = azimuth_pairs(nl[[column]], nv[[row]], AZIMUTHS)
        l, v = l.reshape(-1, 3), v.reshape(-1, 3)
        physical = evaluate_mitsuba_f_cos(bsdf, l, v).mean(axis=0)
        drawn = slice_f_cos(table, FIT_GLOSS, l, v).mean(axis=0)
        # Within the 8-bit rounding the fit respects (A to 1/255 of its scale).
        np.testing.assert_allclose(drawn, physical, rtol=0.01, err_msg=f"N.L {nl[column]:.3f}, N.V {nv[row]:.3f}")


@pytest.mark.parametrize("type_name", ["toon"])
def test_from_physical_refused_where_the_reference_is_no_plain_bsdf(write_material, type_name):
    with pytest.raises(MaterialError, match=r"\bfrom\b"):
        read_material(write_material("m", f'type = "{type_name}"\nfrom = "physical"\n'))


def test_from_must_be_model_or_physical(write_material):
    with pytest.raises(MaterialError, match="from.*expected one of 'model', 'physical'"):
        read_material(write_material("m", 'type = "lambert"\nfrom = "closed-form"\n'))


def test_bsdf_needs_its_dict(write_material):
    with pytest.raises(MaterialError, match="bsdf.*missing"):
        read_material(write_material("m", 'type = "bsdf"\n'))


@pytest.mark.parametrize("bsdf, field, consent", [
    ('{ type = "roughconductor", alpha_u = 0.1, alpha_v = 0.4 }', "bsdf.alpha_v", "accept_anisotropy = true"),
    ('{ type = "principled", anisotropic = 0.5, roughness = 0.3 }', "bsdf.anisotropic", "accept_anisotropy = true"),
    ('{ type = "plastic", diffuse_reflectance = 0.3 }', "bsdf.type", "rough_only = true"),
    ('{ type = "blendbsdf", weight = 0.5, a = { type = "conductor" }, b = { type = "diffuse" } }', "bsdf.a.type",
     "rough_only = true"),
])  # fmt: skip
def test_what_a_slice_cannot_hold_is_refused_unless_consented(
    mitsuba_llvm, expect_rejected, write_material, bsdf, field, consent
):
    """An anisotropic BSDF, or one with a smooth (delta) lobe beside its rough ones, is refused naming the field
    and the consent; with the consent the same file reads (issue 21)."""
    message = expect_rejected("bsdf", f"bsdf = {bsdf}", field, "expected ")
    assert consent in message, message
    read_material(write_material("ok", f'type = "bsdf"\nbsdf = {bsdf}\n{consent}\n'))


@pytest.mark.parametrize("bsdf, field", [
    ('{ type = "roughconductor", alpha_u = 0.1, alpha_v = 0.4 }', "bsdf.alpha_v"),
    ('{ type = "plastic" }', "bsdf.type"),
])  # fmt: skip
def test_a_separable_material_refuses_them_and_points_to_the_bsdf_model(mitsuba_llvm, expect_rejected, bsdf, field):
    message = expect_rejected("separable", f'source = "mitsuba"\nterms = 1\nbsdf = {bsdf}', field, "expected ")
    assert 'type = "bsdf" with' in message, message


@pytest.mark.slow
@pytest.mark.parametrize(("bsdf", "clause"), [
    ('{ type = "roughconductor", alpha = 0.0001 }', "bsdf.alpha = 0.0001: a lobe sharper than the renderer's sharpest "
                                                    "(alpha 0.002), whose highlight falls between the fit's samples"),
    ('{ type = "principled", roughness = 0.01 }', "bsdf.roughness = 0.01: a lobe sharper than the renderer's sharpest"),
    ('{ type = "mask", opacity = 0.5, material = { type = "roughconductor", alpha = 0.2 } }',
     "bsdf.opacity = 0.5: the light a mask lets through, which no slice holds (an object's opacity is the scene's)"),
    # Found by a hostile sweep, each baked without a word: a mirror at exactly 0, a sharpness given as a texture,
    # and light transmitted (3 % of a blend; a principled spec_trans).
    ('{ type = "principled", roughness = 0.0, metallic = 1.0 }', "bsdf.roughness = 0: a lobe sharper than the renderer's"),
    ('{ type = "roughconductor", alpha = { type = "checkerboard", color0 = 0.0001, color1 = 0.0001 } }',
     "bsdf.alpha = a texture: a lobe whose sharpness is read at uv (0.5, 0.5) and not checked"),
    ('{ type = "blendbsdf", weight = 0.03, a = { type = "diffuse" }, b = { type = "roughdielectric", alpha = 0.3 } }',
     "bsdf.b.type = 'roughdielectric': the light it transmits, which no slice holds (the reflection that remains is baked)"),
    ('{ type = "principled", spec_trans = 0.02, roughness = 0.5 }', "bsdf.type = 'principled': the light it transmits"),
])  # fmt: skip
def test_what_the_fit_cannot_see_is_warned_of_not_baked_silently(mitsuba_llvm, write_material, bsdf, clause):
    """A near-mirror lobe baked as exact (fit.relative_rms 3.7e-8: its highlight fell between the fit's samples, into a
    diffuse RGB scaled by 2.5e7 that clipped on screen) and a mask's see-through light dropped, both without a word."""
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_materials

    path = write_material("m", f'type = "bsdf"\ngloss = 0.5\nbsdf = {bsdf}\n')
    (warning,) = [w for w in bake_atlas(read_materials([path])).material_warnings if w.cause == "not in the table"]
    assert clause in str(warning), str(warning)


@pytest.mark.slow
def test_an_ordinary_bsdf_bakes_without_a_warning(mitsuba_llvm, write_material):
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_materials

    path = write_material("m", 'type = "bsdf"\ngloss = 0.5\nbsdf = { type = "roughconductor", alpha = 0.2 }\n')
    assert bake_atlas(read_materials([path])).material_warnings == []
