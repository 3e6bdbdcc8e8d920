"""The thin-film BSDF's NumPy terms: a wavelength grid shared by every lane against per-lane wavelengths."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.optics.film import spectral_grid, spectral_samples
from atlasgen.optics.thin_film import thin_film_terms

FILM = {"thickness": 420.0, "film_ior": 1.45, "base_ior": 1.8, "base_k": 0.0, "film_strength": 3.0,
        "film_split": 0.8, "backlight": 1.5, "backlight_distortion": 0.25, "backlight_power": 3.0}  # fmt: skip


def _directions(rng, n, below=False):
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2]) * (-1.0 if below else 1.0)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@pytest.mark.parametrize("energy", ["none", "coupled"])
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
