"""Thin-film iridescence: the Airy sum against a transfer-matrix solution, closed forms, and the d -> 0 limit."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from atlasgen.contract import texel_grid
from atlasgen.io.fields import validate_params
from atlasgen.models import get_model
from atlasgen.models.backlit import translucency
from atlasgen.models.iridescent import (
    MIN_SAMPLES,
    XYZ_TO_LINEAR_SRGB,
    cie_xyz_cmfs,
    film_reflectance,
    film_reflectance_on_grid,
    spectral_grid,
    spectral_samples,
    spectrum_to_rgb,
)
from atlasgen.optics.fresnel import fresnel_dielectric

MODEL = get_model("iridescent")
WAVELENGTHS = spectral_grid(MIN_SAMPLES)[0]
DEFAULTS = validate_params(MODEL.params, {}, "test")


def reflectance_by_transfer_matrix(cos0, wavelength, thickness, n_film, n_base, k_base):
    """Characteristic-matrix thin-film reflectance (Macleod, Thin-Film Optical Filters, ch. 2).

    Macleod's convention: N = n - ik, tilted admittances eta_s = N cos, eta_p = N / cos.
    """
    sin2 = 1.0 - cos0**2
    total = 0.0
    for pol in ("s", "p"):

        def admittance(n):
            n_cos = np.sqrt(complex(n) ** 2 - sin2)
            return n_cos if pol == "s" else complex(n) ** 2 / n_cos

        eta0, eta1, eta2 = admittance(1.0), admittance(n_film), admittance(complex(n_base, -k_base))
        delta = 2 * np.pi * thickness * np.sqrt(n_film**2 - sin2) / wavelength
        b = np.cos(delta) + 1j * np.sin(delta) / eta1 * eta2
        c = 1j * eta1 * np.sin(delta) + np.cos(delta) * eta2
        r = (eta0 * b - c) / (eta0 * b + c)
        total += abs(r) ** 2
    return total / 2


def conductor_fresnel(cos_theta, n, k):
    """Unpolarised Fresnel reflectance of a conductor, in the a^2, b^2 form (e.g. Cook & Torrance 1982)."""
    s2 = 1.0 - cos_theta**2
    t = n * n - k * k - s2
    root = np.sqrt(t * t + 4 * n * n * k * k)
    a = np.sqrt((root + t) / 2)
    b2 = (root - t) / 2
    rs = (a * a + b2 - 2 * a * cos_theta + cos_theta**2) / (a * a + b2 + 2 * a * cos_theta + cos_theta**2)
    tan_sin = s2 / cos_theta
    rp = rs * (a * a + b2 - 2 * a * tan_sin + tan_sin**2) / (a * a + b2 + 2 * a * tan_sin + tan_sin**2)
    return (rs + rp) / 2


@given(
    cos0=st.floats(1e-3, 1.0),  # at 0 the matrix is singular for a film of index 1
    wavelength=st.floats(380.0, 780.0),
    thickness=st.floats(0.0, 2000.0),
    n_film=st.floats(1.0, 3.0),
    n_base=st.floats(0.05, 5.0),
    k_base=st.floats(0.0, 10.0),
)
@settings(max_examples=200, deadline=None)
@pytest.mark.slow
def test_airy_sum_matches_the_transfer_matrix(cos0, wavelength, thickness, n_film, n_base, k_base):
    got = film_reflectance(np.array([cos0]), np.array([wavelength]), thickness, n_film, n_base, k_base)[0, 0]
    expected = reflectance_by_transfer_matrix(cos0, wavelength, thickness, n_film, n_base, k_base)
    assert got == pytest.approx(expected, rel=1e-9, abs=1e-12)


@given(
    thickness=st.floats(0.0, 2000.0),
    n_film=st.floats(1.0, 3.0),
    n_base=st.one_of(st.floats(0.05, 0.98), st.floats(1.02, 5.0), st.just(1.0)),
    k_base=st.floats(0.0, 10.0),
)
@pytest.mark.slow
def test_grazing_light_is_fully_reflected(thickness, n_film, n_base, k_base):
    assume(n_film != 1.0 or n_base != 1.0 or k_base > 0.0)  # air on air has no interface
    r = film_reflectance(np.array([0.0]), WAVELENGTHS, thickness, n_film, n_base, k_base)
    np.testing.assert_allclose(r, 1.0, rtol=1e-12)


def test_quarter_and_half_wave_layers_at_normal_incidence():
    lam = np.array([550.0])
    for n_film, n_base in [(1.38, 1.52), (2.3, 1.5), (1.2247, 1.5)]:
        quarter = film_reflectance(np.array([1.0]), lam, 550.0 / (4 * n_film), n_film, n_base)[0, 0]
        assert quarter == pytest.approx(((n_base - n_film**2) / (n_base + n_film**2)) ** 2, rel=1e-12, abs=1e-15)
        half = film_reflectance(np.array([1.0]), lam, 550.0 / (2 * n_film), n_film, n_base)[0, 0]
        assert half == pytest.approx(((n_base - 1) / (n_base + 1)) ** 2, rel=1e-12)  # an absentee layer


@given(film_ior=st.floats(1.0, 3.0), base_ior=st.floats(1.01, 5.0))
@settings(max_examples=50, deadline=None)
@pytest.mark.slow
def test_zero_thickness_is_exactly_the_base_fresnel(film_ior, base_ior):
    params = {**DEFAULTS, "thickness": 0.0, "film_ior": film_ior, "base_ior": base_ior}
    cos_theta = np.linspace(0.0, 1.0, 101)
    rgb, lum = MODEL.film_colour(params, cos_theta)
    f = fresnel_dielectric(cos_theta, base_ior)
    np.testing.assert_allclose(rgb, np.repeat(f[:, None], 3, axis=1), rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(lum, f, rtol=1e-13, atol=1e-15)


@given(film_ior=st.floats(1.0, 3.0), base_ior=st.floats(0.05, 5.0), base_k=st.floats(0.1, 10.0))
@settings(max_examples=50, deadline=None)
@pytest.mark.slow
def test_zero_thickness_over_a_conductor_is_the_conductor_fresnel(film_ior, base_ior, base_k):
    cos_theta = np.linspace(0.01, 1.0, 50)
    params = {**DEFAULTS, "thickness": 0.0, "film_ior": film_ior, "base_ior": base_ior, "base_k": base_k}
    _, lum = MODEL.film_colour(params, cos_theta)
    np.testing.assert_allclose(lum, conductor_fresnel(cos_theta, base_ior, base_k), rtol=1e-11)


@pytest.mark.parametrize("thickness", [120.0, 850.0])
def test_an_index_matched_film_is_invisible(thickness):
    cos_theta = np.linspace(0.0, 1.0, 33)
    air_film = film_reflectance(cos_theta, WAVELENGTHS, thickness, 1.0, 1.6)
    np.testing.assert_allclose(air_film, np.repeat(fresnel_dielectric(cos_theta, 1.6)[:, None], WAVELENGTHS.size, 1), rtol=1e-12)
    matched = film_reflectance(cos_theta, WAVELENGTHS, thickness, 1.6, 1.6)
    np.testing.assert_allclose(matched, np.repeat(fresnel_dielectric(cos_theta, 1.6)[:, None], WAVELENGTHS.size, 1), rtol=1e-12)


def test_zero_thickness_model_equals_the_fresnel_model():
    fresnel = get_model("fresnel")
    nl, nv = texel_grid()
    rng = np.random.default_rng(7)
    points = (rng.uniform(-1, 1, 500), rng.uniform(0, 1, 500))
    for energy in ("coupled", "none"):
        for normalise in (True, False):
            common = {"colour": (0.7, 0.3, 0.1), "normalise": normalise, "energy": energy}
            iri = {**DEFAULTS, **common, "thickness": 0.0, "base_ior": 1.7, "film_strength": 0.8, "film_split": 0.0}
            ref = {"fresnel": "exact", "ior": 1.7, "specular": 0.8, **common}
            for n_dot_l, n_dot_v in [(nl, nv), points]:
                np.testing.assert_allclose(
                    MODEL.evaluate(iri, n_dot_l, n_dot_v), fresnel.evaluate(ref, n_dot_l, n_dot_v), rtol=1e-12, atol=1e-15
                )


@pytest.mark.parametrize("thickness, base", [(380.0, (1.5, 0.0)), (900.0, (2.0, 0.0)), (520.0, (1.9, 1.2))])
@pytest.mark.slow
def test_white_coupled_film_conserves_energy_when_all_colour_goes_to_rgb(thickness, base):
    # With film_split = 1 the film's reflection is all in RGB: the renderer's albedo * RGB / pi
    # reflects 2 int_0^1 RGB(c, v) dc over the light directions, which must be
    # (1 - R(v)) from the coupled diffuse plus R(v) from the film: 1 in every channel.
    params = {**DEFAULTS, "colour": (1.0, 1.0, 1.0), "thickness": thickness, "base_ior": base[0], "base_k": base[1]}
    params.update(film_split=1.0, film_strength=1.0)
    for n_dot_v in (0.15, 0.6, 1.0):
        albedo = [
            quad(lambda c: 2 * MODEL.evaluate(params, c, n_dot_v)[channel], 0, 1, epsabs=1e-12, limit=200)[0]
            for channel in range(3)
        ]
        np.testing.assert_allclose(albedo, 1.0, atol=1e-6)


def test_flat_spectrum_is_white_and_srgb_matrix_maps_d65_to_white():
    rgb, lum = spectrum_to_rgb(np.full(WAVELENGTHS.size, 0.37), MIN_SAMPLES)
    np.testing.assert_allclose(rgb, 0.37, rtol=1e-14)
    assert lum == pytest.approx(0.37, rel=1e-14)
    np.testing.assert_allclose(XYZ_TO_LINEAR_SRGB @ [0.95047, 1.0, 1.08883], 1.0, atol=3e-4)


def test_cmf_fit_is_close_to_the_cie_1931_table():
    # CIE 1931 2-degree observer (CIE 015:2018 table), at 450, 500, 550, 600, 650 nm.
    table = np.array(
        [
            [0.3362, 0.0049, 0.4334, 1.0622, 0.2835],
            [0.0380, 0.3230, 0.9950, 0.6310, 0.1070],
            [1.7721, 0.2720, 0.0087, 0.0008, 0.0000],
        ]
    )
    np.testing.assert_allclose(cie_xyz_cmfs([450, 500, 550, 600, 650]), table, atol=0.01)


@pytest.mark.parametrize("base", [(1.5, 0.0), (0.6, 0.0), (2.0, 3.0)], ids=["dielectric", "tir", "absorbing"])
def test_the_chosen_spectral_sampling_has_converged(base):
    fine = np.arange(360.0, 830.0 + 0.05, 0.1)  # a plain 0.1 nm rule in wavelength
    xyz = cie_xyz_cmfs(fine)
    weights = XYZ_TO_LINEAR_SRGB @ xyz
    weights /= weights.sum(axis=1, keepdims=True)
    cos_theta = np.array([1.0, 0.7, 0.3, 0.0])
    counts = set()
    for thickness in (0.0, 80.0, 250.0, 600.0, 1100.0, 2000.0):
        for n_film in (1.0, 1.45, 2.2, 3.0):
            samples = spectral_samples(thickness, n_film)
            counts.add(samples)
            spectra = film_reflectance_on_grid(cos_theta, samples, thickness, n_film, *base)
            coarse, _ = spectrum_to_rgb(spectra, samples)
            reference = film_reflectance(cos_theta, fine, thickness, n_film, *base) @ weights.T
            np.testing.assert_allclose(coarse, reference, atol=1e-4, err_msg=f"d={thickness}, n2={n_film}, N={samples}")
    assert min(counts) == MIN_SAMPLES and max(counts) >= 4 * MIN_SAMPLES  # thin and thick films both covered


@given(
    cos0=st.floats(0.0, 1.0),
    thickness=st.floats(0.0, 2000.0),
    n_film=st.floats(1.0, 3.0),
    n_base=st.floats(0.05, 5.0),
    k_base=st.floats(0.0, 10.0),
)
@settings(max_examples=50, deadline=None)
def test_grid_recurrence_matches_direct_phases(cos0, thickness, n_film, n_base, k_base):
    samples = spectral_samples(thickness, n_film)
    fast = film_reflectance_on_grid(np.array([cos0]), samples, thickness, n_film, n_base, k_base)
    direct = film_reflectance(np.array([cos0]), spectral_grid(samples)[0], thickness, n_film, n_base, k_base)
    np.testing.assert_allclose(fast, direct, rtol=1e-9, atol=1e-12)


def test_film_colour_is_chromatic_and_shifts_with_angle():
    params = {**DEFAULTS, "thickness": 300.0, "film_ior": 1.33, "base_ior": 1.5}
    rgb, _ = MODEL.film_colour(params, np.array([1.0, 0.5]))
    assert np.ptp(rgb[0]) > 0.01  # not grey
    chroma = rgb / rgb.sum(axis=1, keepdims=True)
    assert np.abs(chroma[0] - chroma[1]).max() > 0.05  # the hue moves with the view angle


def test_rgb_and_alpha_follow_the_documented_formula():
    params = {
        **DEFAULTS,
        "colour": (0.2, 0.1, 0.05),
        "thickness": 420.0,
        "film_strength": 3.0,
        "film_split": 0.25,
        "normalise": True,
        "backlight": 2.0,
        "backlight_colour": (0.3, 1.0, 0.6),
    }
    nl = np.linspace(-1, 1, 13)[:, None]
    nv = np.linspace(0, 1, 7)[None, :]
    out = MODEL.evaluate(params, nl, nv)
    rgb_v, lum_v = MODEL.film_colour(params, np.broadcast_to(nv, (13, 7)))
    rgb_l, _ = MODEL.film_colour(params, np.broadcast_to(np.clip(nl, 0, 1), (13, 7)))
    rgb_avg = [quad(lambda c: 2 * c * MODEL.film_colour(params, c)[0][ch], 0, 1, epsabs=1e-13)[0] for ch in range(3)]
    lit = np.clip(nl, 0, None)[..., None]
    t = translucency(nl, nv, 0.2, 4.0, "average")[..., None]
    diffuse = (0.2, 0.1, 0.05) * (1 - rgb_l) * (1 - rgb_v) / (1 - np.array(rgb_avg))
    expected = lit * (diffuse + 3.0 * 0.25 * rgb_v) + 2.0 * t * (0.3, 1.0, 0.6) * (1 - rgb_v)
    np.testing.assert_allclose(out[..., :3], expected, rtol=1e-9, atol=1e-15)
    # A: the film's luminance at L.H where the renderer's lobe peaks, cos((theta_l + theta_v) / 2).
    peak = np.cos(0.5 * (np.arccos(np.clip(nl, 0, 1)) + np.arccos(nv)))
    _, lum_peak = MODEL.film_colour(params, peak)
    np.testing.assert_allclose(out[..., 3], 3.0 * 0.75 * lum_peak / 0.04, rtol=1e-9)


params_strategy = st.fixed_dictionaries(
    {
        "colour": st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
        "thickness": st.floats(0.0, 2000.0),
        "film_ior": st.floats(1.0, 3.0),
        "base_ior": st.one_of(st.floats(1.03, 5.0), st.floats(0.05, 0.97)),
        "base_k": st.floats(0.0, 10.0),
        "film_strength": st.floats(0.0, 64.0),
        "film_split": st.floats(0.0, 1.0),
        "normalise": st.booleans(),
        "energy": st.sampled_from(["coupled", "none"]),
        "backlight": st.floats(0.0, 16.0),
        "backlight_colour": st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
        "backlight_distortion": st.floats(0.0, 1.0),
        "backlight_power": st.floats(0.0, 64.0, exclude_min=True, width=32),  # valid: > 0 in float32 too
        "backlight_view": st.sampled_from(["average", "coplanar"]),
    }
)


@given(raw=params_strategy)
@settings(max_examples=40, deadline=None)
@pytest.mark.slow
def test_random_valid_parameters_give_finite_non_negative_slices(raw, valid_slice):
    params = validate_params(MODEL.params, raw, "hypothesis")
    MODEL.check(params, "hypothesis")
    valid_slice(MODEL, params)


@pytest.mark.parametrize(
    "body, field, expected",
    [
        ("thickness = -1", "thickness", "expected a finite number >= 0 and <= 2000, got -1"),
        ("thickness = nan", "thickness", "got nan"),
        ("film_ior = inf", "film_ior", "got inf"),
        ("base_ior = 1.0", "base_ior", "expected a base reflecting at least 1e-4 at normal incidence"),
        ('backlight_view = "front"', "backlight_view", "one of 'average', 'coplanar'"),
        ("thicknes = 300", "thicknes", "did you mean 'thickness'?"),
    ],
)
def test_bad_parameters_are_rejected(expect_rejected, body, field, expected):
    expect_rejected("iridescent", body, field, expected)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["beetle-shell", "iridescent-backlit"])
def test_the_shipped_films_physical_references_conserve_energy_and_are_reciprocal(name):
    """The physical f cos of each shipped iridescent material (the function its from = "physical" fit and
    validation's Mitsuba reference evaluate): directional albedo <= 1 at views from grazing to normal
    (64 x 64 quadrature, reflection and, with a back-light, transmission), and |f(l, v) - f(v, l)| / mean
    <= 1e-3; its film is the material's stack, with none of the model's strength or split."""
    import json
    import tomllib
    from pathlib import Path

    from tests.optics.test_thin_film import _directional_albedo, _directions

    path = Path(__file__).resolve().parents[2] / "atlasgen" / "data" / "materials" / f"{name}.toml"
    raw = {k: v for k, v in tomllib.loads(path.read_text()).items() if k not in ("type", "description", "from")}
    values = validate_params(MODEL.params, raw, name)
    physical = MODEL.physical_f_cos(values, 0.5)
    film = json.loads(MODEL.physical_reference(values).bsdf["film"])
    assert {k: film[k] for k in ("thickness", "film_ior", "base_ior", "base_k")} == {
        k: values[k] for k in ("thickness", "film_ior", "base_ior", "base_k")}  # fmt: skip
    assert film["film_strength"] == 1.0 and film["film_split"] == 0.0 and film["energy"] == "conserving"
    for mu in (0.02, 0.1, 0.3, 0.5, 0.7, 0.9, 1.0):
        albedo = _directional_albedo(physical.f_cos, mu, physical.alpha, below=physical.transmits)
        assert np.all(albedo <= 1.0), (mu, albedo)
    rng = np.random.default_rng(21)
    l, v = _directions(rng, 4000), _directions(rng, 4000)
    forward, backward = physical.f_cos(l, v) / l[:, 2:3], physical.f_cos(v, l) / v[:, 2:3]
    assert np.abs(forward - backward).max() / forward.mean() <= 1e-3
