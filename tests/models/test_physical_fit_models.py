"""from = "physical" for the iridescent and backlit models: their own fits (Model.fit_physical) to
the NumPy functions their Mitsuba plugins evaluate (issue 11)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from atlasgen.bake.adaptive import bake_material
from atlasgen.contract import texel_centres
from atlasgen.errors import MaterialError
from atlasgen.materials.material import read_material
from atlasgen.models import get_model
from atlasgen.models.backlit import thin_sheet_f_cos
from atlasgen.models.physical_fit import slice_relative_rms
from atlasgen.optics.film import XYZ_TO_LINEAR_SRGB, d65, spectral_grid, spectral_samples, spectrum_to_rgb
from atlasgen.optics.fresnel import fresnel_dielectric
from atlasgen.optics.microfacet import ggx_distribution, smith_visibility_correlated_ggx
from atlasgen.optics.thin_film import thin_film_f_cos, thin_film_rgb_f_cos

MATERIALS = Path(__file__).resolve().parents[2] / "materials"


def _directions(rng, n, below=False):
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.05
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    if below:
        d[:, 2] *= -1.0
    return d


def _closed_form_text(name: str) -> str:
    """A shipped material's file without its ``from``/``fit_gloss`` lines: baked from its closed form."""
    lines = (MATERIALS / f"{name}.toml").read_text().splitlines(keepends=True)
    return "".join(line for line in lines if not line.startswith(("from ", "fit_gloss ")))


def _values(type_name, path=None, **overrides):
    model = get_model(type_name)
    values = {p.name: p.default for p in model.params}
    if path is not None:
        import tomllib

        values.update(
            {
                k: v
                for k, v in tomllib.loads(Path(path).read_text()).items()
                if k not in ("type", "description", "from", "fit_gloss")
            }
        )
    values.update(overrides)
    return model, values


@pytest.fixture
def mitsuba_spectral(mitsuba_llvm):
    """Mitsuba set to ``llvm_ad_spectral`` for one test, then back to the session's variant."""
    mi = mitsuba_llvm
    previous = mi.variant()
    try:
        mi.set_variant("llvm_ad_spectral")
    except Exception as exc:  # the variant is not built in
        pytest.skip(f"Mitsuba 3 llvm_ad_spectral is unavailable: {exc}")
    yield mi
    mi.set_variant(previous)


def _vector(mi, a):
    return mi.Vector3f(*[mi.Float(np.ascontiguousarray(a[:, k], np.float32)) for k in range(a.shape[1])])


@pytest.mark.parametrize("tint", [None, (0.6, 0.3, 0.9)])
@pytest.mark.parametrize("below", [False, True])
@pytest.mark.slow
def test_thin_film_plugin_eval_equals_the_numpy_function(mitsuba_spectral, below, tint):
    """The ``atlasgen_thinfilm`` plugin's eval at random (w_i, w_o) and wavelengths is
    :func:`thin_film_f_cos` with the colours upsampled as Mitsuba upsamples them (Jakob &
    Hanika 2019's sigmoid polynomials); ``below`` puts the light behind the film (the back-light);
    a ``tint`` (a separable material's albedo) scales all of it."""
    import drjit as dr

    from atlasgen.models.mitsuba_bsdfs import register_bsdfs

    mi = mitsuba_spectral
    register_bsdfs(mi)
    model, values = _values("iridescent", MATERIALS / "iridescent-backlit.toml")
    ref = model.physical_reference(values, gloss=0.5)
    if tint is not None:
        ref.bsdf.update({f"tint_{c}": t for c, t in zip("rgb", tint)})
    bsdf = mi.load_dict(ref.bsdf)
    rng = np.random.default_rng(3)
    n = 200
    wi, wo = _directions(rng, n), _directions(rng, n, below)
    lam = rng.uniform(380.0, 780.0, size=(n, 4)).astype(np.float32).astype(np.float64)
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = _vector(mi, wi)
    si.n = mi.Vector3f(0.0, 0.0, 1.0)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    si.wavelengths = mi.Spectrum(*[mi.Float(np.ascontiguousarray(lam[:, k], np.float32)) for k in range(4)])
    value = bsdf.eval(mi.BSDFContext(), si, _vector(mi, wo))
    theirs = np.stack([np.asarray(value[k], np.float64) for k in range(4)], -1)

    def upsampled(name):
        coeff = mi.srgb_model_fetch(mi.ScalarColor3f(*[ref.bsdf[f"{name}_{c}"] for c in "rgb"]))
        coeff = mi.Vector3f(*[float(c) for c in coeff])
        spectrum = mi.srgb_model_eval(coeff, si.wavelengths)
        return np.stack([np.asarray(spectrum[k], np.float64) for k in range(4)], -1)

    ours = thin_film_f_cos(wi, wo, lam, json.loads(ref.bsdf["film"]), ref.bsdf["alpha"], upsampled("colour"),
                           upsampled("backlight"))  # fmt: skip
    if tint is not None:
        ours = ours * upsampled("tint")
    assert ours.shape == theirs.shape == (n, 4)
    assert (theirs > 1e-3).sum() > n  # most lanes carry light, above and below
    np.testing.assert_allclose(theirs, ours, rtol=2e-5, atol=1e-7)


@pytest.mark.parametrize("below", [False, True])
def test_thin_sheet_plugin_eval_equals_the_numpy_function(mitsuba_llvm, below):
    """The atlasgen_thinsheet plugin's eval is thin_sheet_f_cos, and the backlit model's physical_f_cos."""
    import drjit as dr

    from atlasgen.models.mitsuba_bsdfs import register_bsdfs

    mi = mitsuba_llvm
    register_bsdfs(mi)
    model, values = _values("backlit", MATERIALS / "leaf.toml")
    ref = model.physical_reference(values, gloss=0.5)
    bsdf = mi.load_dict(ref.bsdf)
    rng = np.random.default_rng(4)
    n = 200
    wi, wo = _directions(rng, n), _directions(rng, n, below)
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = _vector(mi, wi)
    si.n = mi.Vector3f(0.0, 0.0, 1.0)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    value = bsdf.eval(mi.BSDFContext(), si, _vector(mi, wo))
    theirs = np.stack([np.asarray(value[k], np.float64) for k in range(3)], -1)
    r = [ref.bsdf[f"reflectance_{c}"] for c in "rgb"]
    t = [ref.bsdf[f"transmittance_{c}"] for c in "rgb"]
    ours = thin_sheet_f_cos(wi, wo, np.array(r), np.array(t), ref.bsdf["specular"], ref.bsdf["alpha"])
    assert (theirs > 0.0).all()  # reflection and transmission are diffuse: every pair carries light
    np.testing.assert_allclose(theirs, ours, rtol=2e-5, atol=1e-7)
    # The model's physical_f_cos(l, v) is the same plugin, with w_i = v and w_o = l.
    physical = model.physical_f_cos(values, 0.5)
    assert physical.transmits and physical.source is None and "separable" in physical.no_source
    assert physical.alpha == ref.bsdf["alpha"]
    np.testing.assert_allclose(physical.f_cos(wo, wi), theirs, rtol=2e-5, atol=1e-7)


@pytest.mark.parametrize("illuminant", ["E", "D65"])
def test_the_colour_integral_maps_a_flat_spectrum_to_white(illuminant):
    for samples in (64, 96, 160):
        rgb, y = spectrum_to_rgb(np.ones(samples), samples, illuminant)
        np.testing.assert_allclose(rgb, 1.0, rtol=1e-12)
        assert y == pytest.approx(1.0, rel=1e-12)


def test_d65_is_the_cie_table():
    """Entries of CIE S 014-2 (D65 at 5 nm, 100 at 560 nm), and linear between them."""
    table = {360.0: 46.6383, 380.0: 49.9755, 460.0: 117.812, 560.0: 100.0, 700.0: 71.6091, 830.0: 60.3125}
    np.testing.assert_allclose(d65(list(table)), list(table.values()), rtol=1e-9)
    assert d65(562.5) == pytest.approx(0.5 * (100.0 + 98.1671))
    assert d65(300.0) == 0.0


@pytest.mark.slow
def test_the_d65_colour_integral_is_mitsubas(mitsuba_spectral):
    """Against Mitsuba's own pipeline for a white light (CIE 1931 tables times its D65, to XYZ,
    through the sRGB matrix, Y of D65 = 1) on film spectra: within a few 1e-3 relative RMS,
    the Wyman et al. fit's error; the equal-energy white errs several times more."""
    mi = mitsuba_spectral
    lam = np.arange(360.0, 830.5, 1.0)
    grid = mi.Float(lam.astype(np.float32))
    cmf = np.stack([np.asarray(c, np.float64) for c in mi.cie1931_xyz(grid)])
    power = np.asarray(mi.cie_d65(grid), np.float64)
    theirs_w = XYZ_TO_LINEAR_SRGB @ (cmf * power) / (cmf[1] * power).sum()
    rng = np.random.default_rng(12)
    n = 500
    wi, wo = _directions(rng, n), _directions(rng, n)
    film = {"thickness": 650.0, "film_ior": 1.56, "base_ior": 1.9, "base_k": 1.2}
    theirs = thin_film_f_cos(wi, wo, np.broadcast_to(lam, (n, lam.size)), film, 0.25, np.zeros((n, lam.size))) @ theirs_w.T
    ours = thin_film_rgb_f_cos(wi, wo, film, 0.25, (0.0, 0.0, 0.0))
    samples = spectral_samples(650.0, 1.56)
    flat_e = thin_film_f_cos(wi, wo, np.broadcast_to(spectral_grid(samples)[0], (n, samples)), film, 0.25, np.zeros((n, samples)))

    def rel(x):
        return np.sqrt(((x - theirs) ** 2).sum() / (theirs**2).sum())

    assert rel(ours) < 5e-3
    assert rel(spectrum_to_rgb(flat_e, samples, "E")[0]) > 5 * rel(ours)


def test_a_film_of_zero_thickness_integrates_to_the_bases_fresnel():
    """At d = 0 the Airy reflectance is the bare base's Fresnel for every wavelength (the index is
    constant over wavelength), so the RGB integral must give it on every channel: the lobe
    k D V F(w_i.h) cos, the rough part k s F(c_i) cos / pi and the coupled-free base
    colour (1 - F(c_o)) (1 - F(c_i)) cos / pi, with F the dielectric Fresnel of ``base_ior``."""
    rng = np.random.default_rng(8)
    n = 400
    wi, wo = _directions(rng, n), _directions(rng, n)
    alpha, ior, k, s = 0.3, 1.6, 1.3, 0.25
    film = {"thickness": 0.0, "film_ior": 1.4, "base_ior": ior, "base_k": 0.0, "film_strength": k, "film_split": s}
    colour = np.array([0.2, 0.5, 0.8])
    rgb = thin_film_rgb_f_cos(wi, wo, film, alpha, colour, chunk=97)  # chunks that do not divide n
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=1, keepdims=True)
    ci, co = wi[:, 2], wo[:, 2]
    f = lambda c: fresnel_dielectric(c, ior)  # noqa: E731
    lobe = k * (1 - s) * ggx_distribution(h[:, 2], alpha) * smith_visibility_correlated_ggx(ci, co, alpha) * f((wi * h).sum(1))
    grey = (lobe + k * s * f(ci) / np.pi) * co
    expected = grey[:, None] + colour * ((1 - f(co)) * (1 - f(ci)) * co / np.pi)[:, None]
    np.testing.assert_allclose(rgb, expected, rtol=2e-4, atol=1e-9)


def test_the_rgb_integral_is_the_per_wavelength_function_on_the_models_grid():
    """thin_film_rgb_f_cos integrates thin_film_f_cos (flat colours) with the model's weights."""
    rng = np.random.default_rng(9)
    n = 50
    wi, wo = _directions(rng, n), _directions(rng, n, below=True)
    wo[::2, 2] *= -1.0  # half the lights in front
    film = {"thickness": 420.0, "film_ior": 1.45, "base_ior": 1.8, "base_k": 0.0, "backlight": 1.5,
            "backlight_distortion": 0.25, "backlight_power": 3.0, "film_split": 0.8, "film_strength": 3.0}  # fmt: skip
    samples = spectral_samples(420.0, 1.45)
    lam = np.broadcast_to(spectral_grid(samples)[0], (n, samples))
    for colour, back in (((1.0, 1.0, 1.0), (0.0, 0.0, 0.0)), ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))):
        flat = thin_film_f_cos(wi, wo, lam, film, 0.3, np.full((n, samples), colour[0]), np.full((n, samples), back[0]))
        np.testing.assert_allclose(thin_film_rgb_f_cos(wi, wo, film, 0.3, colour, back), spectrum_to_rgb(flat, samples, "D65")[0],
                                   rtol=1e-12, atol=1e-15)  # fmt: skip


@pytest.mark.slow
def test_backlit_from_physical_is_the_sheet_itself(write_material):
    """The renderer's equation holds the thin sheet exactly at texel centres: RGB = T |N.L| where
    the light is behind (N.L < 0, the back-light), R N.L in front, A = specular."""
    text = _closed_form_text("leaf") + 'from = "physical"\n'
    material = read_material(write_material("leaf", text))
    slices = bake_material(material)
    table = slices.values[0]
    model, values = _values("backlit", MATERIALS / "leaf.toml")
    bsdf = model.physical_reference(values, gloss=0.5).bsdf
    reflectance = np.array([bsdf[f"reflectance_{c}"] for c in "rgb"])
    transmittance = np.array([bsdf[f"transmittance_{c}"] for c in "rgb"])
    nl, nv = texel_centres()
    # Where l or v is the normal (N.L = 1, N.V = 1) the lobe has no azimuth dependence either, so
    # RGB and A are interchangeable there; at N.V = 0 (the grazing limit) the lobe is nearly 0.
    rows = (nv >= 0.05) & (nv < 0.99)
    cols = nl < 0.99
    expected = np.where(nl[cols, None] < 0.0, -nl[cols, None] * transmittance, nl[cols, None] * reflectance)
    got = table[rows][:, cols]
    np.testing.assert_allclose(got[..., :3], np.broadcast_to(expected, got[..., :3].shape), atol=3e-3)
    lit = nl[cols] > 0.05
    # Near N.V = 1 the lobe barely varies over the azimuth, so A and RGB trade a little there.
    np.testing.assert_allclose(got[:, lit, 3], values["specular"], atol=4e-3)
    assert np.median(np.abs(got[:, lit, 3] - values["specular"])) < 3e-4  # about one 8-bit step of A
    fit = slices.extra["fit"]
    assert fit["from"] == "physical" and fit["gloss"] == 0.5 and "thin sheet" in fit["reference"]
    assert fit["relative_rms"] < 0.05 < 0.3 < fit["model_relative_rms"]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["beetle-shell", "iridescent-backlit"])
def test_iridescent_from_physical_beats_the_model_against_the_thin_film(write_material, name):
    """Baked from the shipped material with ``from = "physical"``, the slice's f cos is closer to the
    thin-film BSDF (in the uniform (l, v) measure) than the model's own slice is."""
    text = _closed_form_text(name)
    physical = bake_material(read_material(write_material(f"{name}-p", text + 'from = "physical"\n')))
    own = bake_material(read_material(write_material(name, text)))
    model, values = _values("iridescent", MATERIALS / f"{name}.toml")
    ref = model.physical_reference(values, gloss=0.5)
    film = json.loads(ref.bsdf["film"])
    colour = [ref.bsdf[f"colour_{c}"] for c in "rgb"]
    back = [ref.bsdf[f"backlight_{c}"] for c in "rgb"]

    def f_cos(l, v):
        return thin_film_rgb_f_cos(v, l, film, ref.bsdf["alpha"], colour, back)

    fitted = slice_relative_rms(physical.values[0], f_cos, 0.5, azimuths=32)
    modelled = slice_relative_rms(own.values[0], f_cos, 0.5, azimuths=32)
    assert fitted < modelled
    fit = physical.extra["fit"]
    assert (
        fit["from"] == "physical"
        and fit["gloss"] == 0.5
        and fit["wavelengths"] == spectral_samples(values["thickness"], values["film_ior"])
    )
    assert fit["relative_rms"] < fit["model_relative_rms"]
    assert np.isfinite(physical.values).all() and (physical.values >= 0.0).all()


def test_iridescent_from_physical_refuses_normalise(write_material):
    with pytest.raises(MaterialError, match=r"\bfrom\b.*normalise"):
        read_material(write_material("m", 'type = "iridescent"\nnormalise = true\nfrom = "physical"\n'))


@pytest.mark.slow
def test_the_backlit_fit_fits_its_physical_f_cos():
    """fit_physical projects exactly the function physical_f_cos returns (the report's reference)."""
    from atlasgen.models.physical_fit import fit_slice

    model, values = _values("backlit", MATERIALS / "leaf.toml")
    baked = model.fit_physical(values, 0.5).values[0]
    rgba, _ = fit_slice(model.physical_f_cos(values, 0.5).f_cos, 0.5)
    np.testing.assert_array_equal(baked, rgba)


@pytest.mark.parametrize("name", ["beetle-shell", "iridescent-backlit"])
def test_the_iridescent_physical_f_cos_is_the_thin_film(name):
    """physical_f_cos is thin_film_rgb_f_cos of the reference's parameters (w_i = v, w_o = l) and the
    separable thin_film source it names, back-light included; without a back-light it is 0 below
    the surface."""
    from atlasgen.io.fields import validate_params
    from atlasgen.models.separable import Separable
    from atlasgen.separable.source import make_source

    model, values = _values("iridescent", MATERIALS / f"{name}.toml")
    ref = model.physical_reference(values, gloss=0.5)
    physical = model.physical_f_cos(values, 0.5)
    rng = np.random.default_rng(6)
    v, l = _directions(rng, 64), np.concatenate([_directions(rng, 32), _directions(rng, 32, True)])
    film = json.loads(ref.bsdf["film"])
    colour = [ref.bsdf[f"colour_{c}"] for c in "rgb"]
    back = [ref.bsdf[f"backlight_{c}"] for c in "rgb"]
    got = physical.f_cos(l, v)
    np.testing.assert_array_equal(got, thin_film_rgb_f_cos(v, l, film, ref.bsdf["alpha"], colour, back))
    assert physical.alpha == ref.bsdf["alpha"]
    if values["backlight"] > 0.0:
        assert physical.transmits and (got[32:] > 0.0).all()
    else:
        assert not physical.transmits and (got[32:] == 0.0).all()
    params = validate_params(Separable.params, physical.source, "<test>")
    Separable().check(params, "<test>")
    source = make_source(params)
    assert source.transmits == physical.transmits
    np.testing.assert_allclose(source.f_cos(l, v), got, rtol=1e-12, atol=0.0)
