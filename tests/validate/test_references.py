"""Model references: the renderer's equation without the atlas, as NumPy and as a Mitsuba BSDF;
and validation asking each model for its references."""

from __future__ import annotations

import json

import numpy as np
import pytest

from atlasgen.errors import InputError
from atlasgen.io.manifest import MaterialEntry
from atlasgen.models import get_model, model_types
from atlasgen.models.base import Model
from atlasgen.validate.references import model_reference, physical_reference

#: The shipped models whose slice is an (N.L, N.V) table.
TABLE_TYPES = ("lambert", "fresnel", "iridescent", "sss", "backlit", "toon")


def _entry(type_name: str, params: dict, name: str = "m") -> MaterialEntry:
    return MaterialEntry(name=name, id=0, constant="MATERIAL_M", first_slice=0, type=type_name, params=params)


def _defaults(type_name: str) -> dict:
    return {p.name: p.default for p in get_model(type_name).params}


class _SpecularOnly(Model):
    """A stand-in model: RGB 0, A = 1 everywhere (isolates the specular lobe)."""

    def evaluate(self, values, n_dot_l, n_dot_v):
        nl = np.asarray(n_dot_l)
        out = np.zeros(nl.shape + (4,))
        out[..., 3] = 1.0
        return out


def _hemisphere(n=400):
    """Midpoint rule over (theta, phi) of the upper hemisphere: directions and solid-angle weights."""
    t = (np.arange(n) + 0.5) * (0.5 * np.pi / n)
    p = (np.arange(2 * n) + 0.5) * (np.pi / n)
    tt, pp = np.meshgrid(t, p, indexing="ij")
    d = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1)
    w = np.sin(tt) * (0.5 * np.pi / n) * (np.pi / n)
    return d.reshape(-1, 3), w.ravel()


def test_lambert_reference_is_albedo_times_colour_over_pi_times_cos():
    values = {"colour": (0.8, 0.5, 0.3)}
    nl = np.linspace(-1, 1, 9)
    got = get_model("lambert").renderer_f_cos(values, (0.5, 1.0, 0.25), 0.7, nl, np.full(9, 0.6), np.full(9, 0.9))
    expected = np.array([0.4, 0.5, 0.075]) / np.pi * np.maximum(nl, 0.0)[:, None]
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("gloss", [0.0, 0.3, 0.6])
def test_specular_lobe_is_the_renderers_ggx_lobe(gloss):
    """The reference's lobe (A = 1) integrates over the light like the renderer's GGX lobe: at
    alpha = 1 (gloss 0) and normal view to 1 - ln 2 exactly (D = 1 / pi, V = 0.5 / (1 + N.L)),
    otherwise to the albedo tests/optics/test_specular.py checks, below 1."""
    l, w = _hemisphere()
    v = np.array([0.0, 0.0, 1.0])
    h = l + v
    nh = h[:, 2] / np.linalg.norm(h, axis=1)
    f_cos = _SpecularOnly().renderer_f_cos({}, (1, 1, 1), gloss, l[:, 2], np.ones(len(l)), nh)
    albedo = (f_cos[:, 0] * w).sum()
    if gloss == 0.0:
        assert albedo == pytest.approx(1.0 - np.log(2.0), rel=1e-4)
    assert 0.3 < albedo < 1.0


def test_specular_is_zero_below_the_horizon_and_for_degenerate_half_vectors():
    f = _SpecularOnly().renderer_f_cos({}, (1, 1, 1), 0.5, np.array([-0.2, 0.5]), np.array([0.5, 0.5]),
                                       np.array([1.0, 1.0]), lv_degenerate=np.array([False, True]))  # fmt: skip
    assert np.all(f == 0.0)


def test_every_table_type_and_separable_has_a_model_reference_and_unknown_types_do_not():
    assert set(TABLE_TYPES) | {"separable"} <= set(model_types())
    for kind in TABLE_TYPES:
        ref = model_reference(_entry(kind, {}), (0.5, 1, 1), 0.25)
        assert ref.bsdf["type"] == "atlasgen_model"
        assert json.loads(ref.bsdf["material"]) == {"type": kind, "params": {}, "albedo": [0.5, 1.0, 1.0], "gloss": 0.25}
        assert ref.description == f"{kind} model, exact, in the renderer's equation"
    sep = model_reference(_entry("separable", {"source": "mitsuba", "bsdf": {"type": "diffuse"}}, "s"), (0.5, 1, 1))
    assert sep.bsdf["type"] == "atlasgen_brdf"
    assert json.loads(sep.bsdf["material"]) == {
        "params": {"source": "mitsuba", "bsdf": {"type": "diffuse"}},
        "albedo": [0.5, 1.0, 1.0],
    }
    assert sep.description == "source BSDF (mitsuba): {'type': 'diffuse'}"
    with pytest.raises(InputError, match="'mystery'.*no reference for model type 'hologram'"):
        model_reference(_entry("hologram", {}, "mystery"))


def test_a_model_without_a_model_reference_is_refused(monkeypatch):
    monkeypatch.setattr(type(get_model("toon")), "model_reference", lambda self, values, albedo=None, gloss=None: None)
    with pytest.raises(InputError, match="'m'.*'toon' model has no model reference"):
        model_reference(_entry("toon", _defaults("toon")))


@pytest.mark.slow
def test_physical_references_exist_only_where_physics_does():
    for kind in ("toon", "separable"):
        assert physical_reference(_entry(kind, _defaults(kind))) is None
        assert get_model(kind).no_physical_reference
    ref = physical_reference(_entry("lambert", {"colour": (0.8, 0.5, 0.3)}), albedo=(0.5, 1, 1))
    assert ref.bsdf == {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.4, 0.5, 0.3]}}
    assert (ref.variant, ref.integrator, ref.interior, ref.stochastic) == ("llvm_ad_rgb", None, None, False)
    fresnel = physical_reference(_entry("fresnel", _defaults("fresnel")), gloss=0.5)
    assert fresnel.bsdf["type"] == "roughplastic" and fresnel.bsdf["alpha"] == pytest.approx(0.25)
    assert fresnel.bsdf["distribution"] == "ggx"  # the renderer's lobe: GGX, alpha = (1 - gloss)^2
    sss = physical_reference(_entry("sss", _defaults("sss")))
    assert sss.integrator["type"] == "volpathmis" and sss.interior["type"] == "homogeneous"
    assert sss.stochastic and sss.builtin_only
    film = physical_reference(_entry("iridescent", {**_defaults("iridescent"), "colour": (0.5, 0.5, 0.5)}), albedo=(0.5, 1, 1))
    assert film.variant == "llvm_ad_spectral" and film.bsdf["type"] == "atlasgen_thinfilm"
    assert film.stochastic  # wavelengths are sampled per sample
    assert (film.bsdf["colour_r"], film.bsdf["colour_g"]) == (0.25, 0.5)
    sheet = physical_reference(_entry("backlit", {**_defaults("backlit"), "colour": (0.4, 0.2, 0.1)}), albedo=(0.5, 1, 1))
    assert sheet.bsdf["type"] == "atlasgen_thinsheet" and not sheet.stochastic
    assert (sheet.bsdf["reflectance_r"], sheet.bsdf["reflectance_g"]) == (0.2, 0.2)


def _interaction(mi, dr, wi, n_geo):
    si = dr.zeros(mi.SurfaceInteraction3f, len(wi))
    si.wi = mi.Vector3f(*[mi.Float(np.ascontiguousarray(wi[:, k], np.float32)) for k in range(3)])
    si.n = mi.Normal3f(*[mi.Float(np.full(len(wi), c, np.float32)) for c in n_geo])
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    return si


def _random_directions(rng, n, upper=True):
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    if upper:
        d[:, 2] = np.abs(d[:, 2])
    return d


def test_mitsuba_model_reference_evaluates_the_numpy_equation(mitsuba_rgb):
    import drjit as dr

    from atlasgen.validate.references import register_references

    mi = mitsuba_rgb
    register_references(mi)
    values = {"colour": (0.2, 0.35, 0.6), "fresnel": "exact", "ior": 1.5, "specular": 1.0, "normalise": True, "energy": "coupled"}
    bsdf = mi.load_dict(model_reference(_entry("fresnel", values, "coat"), (0.9, 0.8, 0.7), 0.4).bsdf)
    rng = np.random.default_rng(5)
    wi, wo = _random_directions(rng, 256), _random_directions(rng, 256, upper=False)
    with dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, False):
        got = bsdf.eval(mi.BSDFContext(), _interaction(mi, dr, wi, (0, 0, 1)),
                        mi.Vector3f(*[mi.Float(np.ascontiguousarray(wo[:, k], np.float32)) for k in range(3)]))  # fmt: skip
    got = np.stack([np.asarray(c) for c in (got.x, got.y, got.z)], -1)
    h = wi + wo
    nh = h[:, 2] / np.linalg.norm(h, axis=1)
    expected = get_model("fresnel").renderer_f_cos(values, (0.9, 0.8, 0.7), 0.4, wo[:, 2], wi[:, 2], nh)
    np.testing.assert_allclose(got, expected, rtol=2e-4, atol=2e-5)


def test_mitsuba_model_reference_of_lambert_equals_mitsubas_own_diffuse(mitsuba_rgb):
    """Two implementations that share no code: atlasgen's lambert in the renderer's equation, Mitsuba's diffuse."""
    import drjit as dr

    from atlasgen.validate.references import register_references

    mi = mitsuba_rgb
    register_references(mi)
    ours = mi.load_dict(model_reference(_entry("lambert", {"colour": [0.8, 0.5, 0.3]}), (0.5, 1, 1), 0.5).bsdf)
    theirs = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.4, 0.5, 0.3]}})
    rng = np.random.default_rng(9)
    wi, wo = _random_directions(rng, 128), _random_directions(rng, 128)
    si = _interaction(mi, dr, wi, (0, 0, 1))
    w = mi.Vector3f(*[mi.Float(np.ascontiguousarray(wo[:, k], np.float32)) for k in range(3)])
    with dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, False):
        a, b = ours.eval(mi.BSDFContext(), si, w), theirs.eval(mi.BSDFContext(), si, w)
    for ca, cb in zip((a.x, a.y, a.z), (b.x, b.y, b.z)):
        np.testing.assert_allclose(np.asarray(ca), np.asarray(cb), rtol=1e-5, atol=1e-7)


def test_back_faces_are_shaded_with_the_flipped_normal_like_the_gbuffer(mitsuba_rgb):
    import drjit as dr

    from atlasgen.validate.references import register_references

    mi = mitsuba_rgb
    register_references(mi)
    bsdf = mi.load_dict(model_reference(_entry("lambert", {"colour": [1, 1, 1]})).bsdf)
    wi = np.array([[0.0, 0.6, -0.8]])
    wo = mi.Vector3f(0.0, 0.0, -1.0)
    with dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, False):
        back = bsdf.eval(mi.BSDFContext(), _interaction(mi, dr, wi, (0, 0, 1)), wo)  # geometric normal faces away from the eye
    assert np.asarray(back.x)[0] == pytest.approx(1.0 / np.pi, rel=1e-6)
