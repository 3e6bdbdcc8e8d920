"""The separable model's ``source = "thin_film"``: the iridescent model's physical thin film, factored
so its coloured highlight survives (issue 11: A is a scalar in a table slice)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from atlasgen.bake.adaptive import bake_material
from atlasgen.errors import MaterialError
from atlasgen.materials.material import read_material
from atlasgen.models import get_model
from atlasgen.models.physical_fit import fit_slice
from atlasgen.models.separable import FILM_KEYS
from atlasgen.optics.thin_film import FILM_DEFAULTS, thin_film_rgb_f_cos
from atlasgen.separable.source import make_source

FILM = 'film = { thickness = 650.0, film_ior = 1.56, base_ior = 1.9, base_k = 1.2, film_split = 0.0 }'


def _directions(rng, n):
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.05
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_the_source_is_the_thin_films_rgb_on_the_upper_hemispheres():
    film = {"thickness": 420.0, "film_ior": 1.45, "base_ior": 1.8, "base_k": 0.0, "film_split": 0.3}
    source = make_source({"source": "thin_film", "film": film, "alpha": 0.2, "diffuse": (0.1, 0.2, 0.3)})
    rng = np.random.default_rng(1)
    l, v = _directions(rng, 64), _directions(rng, 64)
    np.testing.assert_allclose(source.f_cos(l, v), thin_film_rgb_f_cos(v, l, film, 0.2, (0.1, 0.2, 0.3)), rtol=1e-12)
    below = l * np.array([1.0, 1.0, -1.0])
    assert (source.f_cos(below, v) == 0.0).all()
    # Grid-shaped pairs keep their shape.
    assert source.f_cos(l.reshape(8, 8, 3), v.reshape(8, 8, 3)).shape == (8, 8, 3)


@pytest.mark.parametrize(
    "body, field, expected",
    [
        ("", "film", "missing"),
        ('film = { thickness = 420.0, film_ior = 1.45 }', "film.base_ior", "missing"),
        ('film = { thickness = 420.0, film_ior = 1.45, base_ior = 1.8, backlight = 1.0 }', "film.backlight", "unknown"),
        ('film = { thickness = 420.0, film_ior = 0.5, base_ior = 1.8 }', "film.film_ior", "expected"),
        ('film = { thickness = 420.0, film_ior = 1.45, base_ior = 1.8, energy = "some" }', "film.energy", "expected one of"),
        ('film = 3.0', "film", "expected a table"),
    ],
)
def test_a_thin_film_source_needs_a_valid_film(expect_rejected, body, field, expected):
    expect_rejected("separable", f'source = "thin_film"\nterms = 1\n{body}', field, expected)


def test_a_film_is_refused_with_another_source(expect_rejected):
    expect_rejected("separable", f'source = "ggx"\nterms = 1\n{FILM}', "film", "only used with source = 'thin_film'")


def test_the_physical_reference_is_the_spectral_thin_film(write_material):
    material = read_material(write_material("f", f'type = "separable"\nsource = "thin_film"\nalpha = 0.3\n'
                                                 f'diffuse = [0.2, 0.1, 0.0]\nterms = 2\n{FILM}\n'))  # fmt: skip
    model = get_model("separable")
    ref = model.physical_reference(material.params, albedo=(0.5, 0.5, 0.5))
    assert ref.variant == "llvm_ad_spectral" and ref.stochastic and ref.bsdf["type"] == "atlasgen_thinfilm"
    # Keys the table leaves out take the iridescent model's defaults (energy = "coupled").
    assert json.loads(ref.bsdf["film"]) == {**FILM_DEFAULTS, "thickness": 650.0, "film_ior": 1.56, "base_ior": 1.9,
                                           "base_k": 1.2, "film_split": 0.0, "film_strength": 1.0,
                                           "energy": "coupled"}  # fmt: skip
    assert ref.bsdf["alpha"] == 0.3
    # The renderer draws albedo * f cos: the albedo tints the whole film, not only its base.
    assert [ref.bsdf[f"colour_{c}"] for c in "rgb"] == pytest.approx([0.2, 0.1, 0.0])
    assert [ref.bsdf[f"tint_{c}"] for c in "rgb"] == pytest.approx([0.5, 0.5, 0.5])
    ggx = read_material(write_material("g", 'type = "separable"\nsource = "ggx"\nterms = 1\n'))
    assert model.physical_reference(ggx.params) is None


@pytest.mark.slow
def test_separable_terms_carry_the_coloured_highlight_a_table_cannot(write_material):
    """A film whose reflection is all in the lobe (film_split = 0): its hue varies with l.h over the
    azimuth, which a table's scalar A cannot follow. Four separable terms (8-bit, as claimed in
    the manifest) err less than the best table fit to the same BSDF."""
    material = read_material(write_material("f", f'type = "separable"\nsource = "thin_film"\nalpha = 0.25\n'
                                                 f'terms = 4\n{FILM}\n'))  # fmt: skip
    slices = bake_material(material)
    extra = slices.extra
    assert extra["brdf_source"] == "thin_film" and extra["terms"] == 4
    claimed = next(e["relative_rms"] for e in extra["errors"]["estimated_8bit_srgb_by_terms"][extra["target"]]
                   if e["terms"] == 4)  # fmt: skip
    source = make_source(material.params)
    _, table = fit_slice(lambda l, v: source.f_cos(l, v), 0.5, azimuths=32)
    assert claimed < 0.5 * table["relative_rms"]


def test_a_film_without_its_optional_keys_gets_the_iridescent_defaults(write_material):
    """base_k, film_strength, film_split and energy may be left out; every user of the film (the
    source, the reference, the manifest) then reads the iridescent model's defaults."""
    material = read_material(write_material("f", 'type = "separable"\nsource = "thin_film"\nterms = 1\n'
                                                 'film = { thickness = 420.0, film_ior = 1.45, base_ior = 1.8 }\n'))  # fmt: skip
    film = material.params["film"]
    defaults = {p.name: p.default for p in get_model("iridescent").params if p.name in FILM_KEYS}
    assert film == {**defaults, "thickness": 420.0, "film_ior": 1.45, "base_ior": 1.8}
    rng = np.random.default_rng(2)
    l, v = _directions(rng, 16), _directions(rng, 16)
    np.testing.assert_allclose(make_source(material.params).f_cos(l, v),
                               thin_film_rgb_f_cos(v, l, FILM_DEFAULTS | film, 0.2, (0.0, 0.0, 0.0)), rtol=1e-12)
