"""The thin-film BSDF's NumPy terms: a wavelength grid shared by every lane against per-lane wavelengths."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.optics.film import spectral_grid, spectral_samples
from atlasgen.optics.microfacet import ggx_distribution, smith_visibility_correlated_ggx
from atlasgen.optics.thin_film import PHYSICAL_FILM, lobe_albedo_kernel, thin_film_f_cos, thin_film_rgb_f_cos, thin_film_terms
from tests.models.test_iridescent import reflectance_by_transfer_matrix

FILM = {"thickness": 420.0, "film_ior": 1.45, "base_ior": 1.8, "base_k": 0.0, "film_strength": 3.0,
        "film_split": 0.8, "backlight": 1.5, "backlight_distortion": 0.25, "backlight_power": 3.0}  # fmt: skip


def _directions(rng, n, below=False):
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2]) * (-1.0 if below else 1.0)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@pytest.mark.parametrize("energy", ["none", "coupled", pytest.param("conserving", marks=pytest.mark.slow)])
def test_a_shared_wavelength_grid_gives_the_per_lane_lookup(energy):
    """Bilinear filtering is separable: filtering the table along the wavelength first, once
    for the shared grid, then along the cosine per lane, equals the per-lane bilinear lookup."""
    rng = np.random.default_rng(4)
    n = 400
    wi = _directions(rng, n)
    wo = _directions(rng, n)
    wo[::3] *= np.array([1.0, 1.0, -1.0])  # some lights behind: the back-light term
    grid = spectral_grid(spectral_samples(420.0, 1.45))[0]
    film = {**FILM, "energy": energy}
    shared = thin_film_terms(wi, wo, grid, film, 0.25)
    per_lane = thin_film_terms(wi, wo, np.broadcast_to(grid, (n, len(grid))), film, 0.25)
    for a, b in zip(shared, per_lane):
        assert a.shape == b.shape == (n, len(grid))
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)
    assert np.count_nonzero(shared[2]) > 20 and np.count_nonzero(shared[0]) > 100


# -- the physical film: energy, reciprocity, its lobe's albedo and its Airy term ------------------------------

#: Films the physical checks run on: dielectric bases, an absorbing base, a thick dense film, a back-light.
PHYSICAL_CASES = [
    ({"thickness": 420.0, "film_ior": 1.45, "base_ior": 1.8, "base_k": 0.0}, 0.25),
    ({"thickness": 650.0, "film_ior": 1.56, "base_ior": 1.9, "base_k": 1.2}, 0.25),
    ({"thickness": 1800.0, "film_ior": 2.6, "base_ior": 1.3, "base_k": 0.0}, 0.6),
    ({"thickness": 250.0, "film_ior": 1.33, "base_ior": 3.0, "base_k": 4.0}, 0.05),
    ({"thickness": 420.0, "film_ior": 1.45, "base_ior": 1.8, "base_k": 0.0, "backlight": 2.0,
      "backlight_distortion": 0.2, "backlight_power": 2.0}, 0.25),
]  # fmt: skip


def _cosine_directions(n: int, below: bool = False):
    """n x n stratified cosine-weighted directions (pdf cos / pi), z < 0 when ``below``."""
    u, phi = np.meshgrid((np.arange(n) + 0.5) / n, (np.arange(n) + 0.5) / n * 2.0 * np.pi, indexing="ij")
    r = np.sqrt(u)
    d = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1.0 - u)], -1).reshape(-1, 3)
    return d * np.array([1.0, 1.0, -1.0]) if below else d


def _directional_albedo(f_cos, mu: float, alpha: float, n: int = 64, below: bool = False) -> np.ndarray:
    """int f cos dl at view cosine ``mu`` by an n x n cosine grid and an n x n GGX grid (h ~ D cos theta_h,
    l reflected), combined as one sample of their half-and-half mixture (Veach's balance heuristic);
    with ``below``, plus the lower hemisphere by an n x n cosine grid."""
    v = np.array([np.sqrt(1.0 - mu * mu), 0.0, mu])
    u, phi = np.meshgrid((np.arange(n) + 0.5) / n, (np.arange(n) + 0.5) / n * 2.0 * np.pi, indexing="ij")
    tan = alpha * np.sqrt(u / (1.0 - u))
    ch = 1.0 / np.sqrt(1.0 + tan * tan)
    h = np.stack([tan * ch * np.cos(phi), tan * ch * np.sin(phi), ch], -1).reshape(-1, 3)
    lobe = 2.0 * (h @ v)[:, None] * h - v
    l = np.concatenate([_cosine_directions(n), lobe])

    def pdf(l):
        hh = l + v
        hh /= np.linalg.norm(hh, axis=1, keepdims=True)
        lobe_pdf = ggx_distribution(hh[:, 2], alpha) * hh[:, 2] / (4.0 * np.maximum(hh @ v, 1e-12))
        return 0.5 * np.maximum(l[:, 2], 0.0) / np.pi + 0.5 * lobe_pdf

    above = l[:, 2] > 0.0
    values = np.zeros((len(l), 3))
    values[above] = f_cos(l[above], np.tile(v, (above.sum(), 1))) / pdf(l[above])[:, None]
    total = values.mean(axis=0)
    if below:
        lb = _cosine_directions(n, below=True)
        total = total + np.pi * (f_cos(lb, np.tile(v, (len(lb), 1))) / -lb[:, 2:3]).mean(axis=0)
    return total


def _spectral(film, alpha, base, back=None, wavelengths=(400.0, 480.0, 550.0, 620.0, 700.0)):
    """f cos(l, v) of the per-wavelength BSDF at a few wavelengths (flat base and back-light spectra), (N, S)."""

    def f_cos(l, v):
        lam = np.broadcast_to(np.asarray(wavelengths), (len(l), len(wavelengths)))
        flat = np.full(lam.shape, base)
        return thin_film_f_cos(v, l, lam, film, alpha, flat, None if back is None else np.full(lam.shape, back))

    return f_cos


def _first3(f_cos):
    """The first three wavelengths of a spectral f cos, as the albedo helper's (N, 3)."""
    return lambda l, v: f_cos(l, v)[:, :3]


@pytest.mark.slow
def test_the_lobe_albedo_kernel_is_the_ggx_lobes_albedo():
    """With F = 1 a kernel row sums to the GGX lobe's albedo int D V cos dl, here by a fine (theta, phi) rule on l."""
    n = 600
    theta, phi = np.meshgrid((np.arange(n) + 0.5) / n * np.pi / 2, (np.arange(2 * n) + 0.5) / (2 * n) * 2 * np.pi, indexing="ij")
    l = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1).reshape(-1, 3)
    d_omega = (np.sin(theta) * (np.pi / 2 / n) * (np.pi / n)).ravel()
    for alpha in (0.25, 0.6):
        kernel = lobe_albedo_kernel(alpha)
        for i in (100, 512, 1024):
            mu = i / 1024
            v = np.array([np.sqrt(1.0 - mu * mu), 0.0, mu])
            h = l + v
            h /= np.linalg.norm(h, axis=1, keepdims=True)
            brute = (
                ggx_distribution(h[:, 2], alpha) * smith_visibility_correlated_ggx(mu, l[:, 2], alpha) * l[:, 2] * d_omega
            ).sum()
            assert kernel[i].sum() == pytest.approx(brute, rel=2e-3)


@pytest.mark.slow
@pytest.mark.parametrize("film, alpha", PHYSICAL_CASES)
def test_the_physical_film_conserves_energy_at_every_view(film, alpha):
    """Directional albedo <= 1 per wavelength at views from grazing to normal, for a white base (where the
    base takes exactly what the lobe leaves: the albedo is 1 within the quadrature's error) and, in RGB, for a
    coloured base; with a back-light, reflection plus transmission."""
    film = {**film, **PHYSICAL_FILM}
    back = film.get("backlight", 0.0) > 0.0
    gain = 2.0 * 2.0 * 0.8**2 / 4.0 if back else 0.0  # B T_B of the back-light case
    base = 1.0 - gain  # the base's reflectance plus its transmittance is 1
    for mu in (0.02, 0.1, 0.3, 0.5, 0.7, 0.9, 1.0):
        spectral = _directional_albedo(_first3(_spectral(film, alpha, base, 1.0 if back else None)), mu, alpha, below=back)
        assert np.all(spectral <= 1.0 + 3e-3), (mu, spectral)
        assert np.all(spectral >= 0.985), (mu, spectral)  # nothing lost but the quadrature's error
        # colour + B T_B back <= 1 per channel: (0.69, 0.72, 0.78) with the back-light
        rgb = _directional_albedo(lambda l, v: thin_film_rgb_f_cos(v, l, film, alpha, (0.5, 0.4, 0.2), (0.3, 0.5, 0.9)),
                                  mu, alpha, below=back)  # fmt: skip
        assert np.all(rgb <= 1.0 + 3e-3), (mu, rgb)


@pytest.mark.slow
@pytest.mark.parametrize("film, alpha", PHYSICAL_CASES)
def test_the_physical_film_is_reciprocal(film, alpha):
    """|f(l, v) - f(v, l)| / mean f <= 1e-3 over random pairs, per wavelength and in RGB; for light through
    the film, f(l, v) = f(v', l') with both mirrored through the surface (the same film on both sides)."""
    film = {**film, **PHYSICAL_FILM}
    rng = np.random.default_rng(11)
    l, v = _directions(rng, 2000), _directions(rng, 2000)
    lam = np.broadcast_to(rng.uniform(380.0, 780.0, size=(2000, 1)), (2000, 3))
    flat = np.full(lam.shape, 0.6)
    for f_cos in (lambda l, v: thin_film_f_cos(v, l, np.ascontiguousarray(lam), film, alpha, flat, flat),
                  lambda l, v: thin_film_rgb_f_cos(v, l, film, alpha, (0.6, 0.3, 0.1), (0.2, 0.4, 0.8))):  # fmt: skip
        forward = f_cos(l, v) / l[:, 2:3]
        backward = f_cos(v, l) / v[:, 2:3]
        assert np.abs(forward - backward).max() / forward.mean() <= 1e-3
        if film.get("backlight", 0.0) > 0.0:
            flip = np.array([1.0, 1.0, -1.0])
            through = f_cos(l * flip, v) / l[:, 2:3]
            reverse = f_cos(v * flip, l) / v[:, 2:3]
            assert through.mean() > 0.0
            assert np.abs(through - reverse).max() / through.mean() <= 1e-3


@pytest.mark.slow
def test_the_stylised_film_breaks_what_the_physical_one_keeps():
    """The iridescent model's stylisation (strength 3, split 0.8) reflects more than it receives at grazing
    and is far from reciprocal: what the physical checks above would catch."""
    film = {**PHYSICAL_CASES[0][0], "film_strength": 3.0, "film_split": 0.8, "energy": "coupled"}
    albedo = _directional_albedo(_first3(_spectral(film, 0.25, 0.0)), 0.05, 0.25)
    assert np.any(albedo > 1.5)
    rng = np.random.default_rng(12)
    l, v = _directions(rng, 500), _directions(rng, 500)
    forward = thin_film_rgb_f_cos(v, l, film, 0.25, (0.0, 0.0, 0.0)) / l[:, 2:3]
    backward = thin_film_rgb_f_cos(l, v, film, 0.25, (0.0, 0.0, 0.0)) / v[:, 2:3]
    assert np.median(np.abs(forward - backward).max(1) / forward.mean()) > 0.1


@pytest.mark.slow
@pytest.mark.parametrize("film", [c[0] for c in PHYSICAL_CASES[:4]])
def test_the_physical_films_lobe_is_the_transfer_matrix_film_at_the_half_vector(film):
    """With no base, f cos = D(h) V R(w_i.h, lambda) cos theta_o, R the characteristic-matrix film of
    tests/models/test_iridescent.py (Macleod): the Airy term inside the BSDF, at pairs whose w_i.h and
    wavelength are nodes of its table (1/1024 in cos, 1 nm), where the table's filtering adds nothing."""
    rng = np.random.default_rng(13)
    n = 40
    cos_d = rng.integers(700, 1024, size=n) / 1024.0
    h = _directions(rng, n) + np.array([0.0, 0.0, 4.0])  # near the normal: both directions above the surface
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    t = np.cross(h, rng.normal(size=(n, 3)))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    wi = cos_d[:, None] * h + np.sqrt(1.0 - cos_d**2)[:, None] * t
    wo = 2.0 * cos_d[:, None] * h - wi
    assert np.all(wi[:, 2] > 0.0) and np.all(wo[:, 2] > 0.0)
    lam = rng.integers(380, 780, size=(n, 1)).astype(np.float64)
    got = thin_film_f_cos(wi, wo, lam, {**film, **PHYSICAL_FILM}, 0.3, np.zeros((n, 1)))[:, 0]
    stack = (film["thickness"], film["film_ior"], film["base_ior"], film["base_k"])
    r = np.array([reflectance_by_transfer_matrix(c, w, *stack) for c, w in zip(cos_d, lam[:, 0])])
    lobe = ggx_distribution(h[:, 2], 0.3) * smith_visibility_correlated_ggx(wi[:, 2], wo[:, 2], 0.3) * wo[:, 2]
    np.testing.assert_allclose(got, lobe * r, rtol=1e-6)
