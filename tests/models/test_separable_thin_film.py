"""The separable model's ``source = "thin_film"``: the iridescent model's physical thin film, factored
so its coloured highlight survives (issue 11: A is a scalar in a table slice)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from atlasgen.bake.adaptive import bake_material
from atlasgen.materials.material import read_material
from atlasgen.models import get_model
from atlasgen.models.physical_fit import fit_slice
from atlasgen.models.separable import FILM_KEYS
from atlasgen.optics.thin_film import FILM_DEFAULTS, thin_film_rgb_f_cos
from atlasgen.separable.source import make_source

FILM = "film = { thickness = 650.0, film_ior = 1.56, base_ior = 1.9, base_k = 1.2, film_split = 0.0 }"


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
        ("film = { thickness = 420.0, film_ior = 1.45 }", "film.base_ior", "missing"),
        (
            'film = { thickness = 420.0, film_ior = 1.45, base_ior = 1.8, backlight_view = "average" }',
            "film.backlight_view",
            "unknown",
        ),
        ("film = { thickness = 420.0, film_ior = 1.45, base_ior = 1.8, backlight = -1.0 }", "film.backlight", "expected"),
        ("film = { thickness = 420.0, film_ior = 0.5, base_ior = 1.8 }", "film.film_ior", "expected"),
        ('film = { thickness = 420.0, film_ior = 1.45, base_ior = 1.8, energy = "some" }', "film.energy", "expected one of"),
        ("film = 3.0", "film", "expected a table"),
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
    np.testing.assert_allclose(
        make_source(material.params).f_cos(l, v),
        thin_film_rgb_f_cos(v, l, FILM_DEFAULTS | film, 0.2, (0.0, 0.0, 0.0)),
        rtol=1e-12,
    )


BACKLIT_FILM = (
    "film = { thickness = 420.0, film_ior = 1.45, base_ior = 1.8, film_split = 0.8, backlight = 1.5, "
    "backlight_colour = [0.55, 0.75, 1.0], backlight_distortion = 0.25, backlight_power = 3.0 }"
)


@pytest.fixture(scope="module")
def backlit_film_atlas(tmp_path_factory):
    """A thin film with a back-light, K = 2 terms, baked and written (sRGB)."""
    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.materials.material import read_materials

    folder = tmp_path_factory.mktemp("backlit_film")
    (folder / "m").mkdir()
    (folder / "m" / "film.toml").write_text(f'type = "separable"\nsource = "thin_film"\nalpha = 0.25\n'
                                            f'diffuse = [0.02, 0.01, 0.04]\nterms = 2\n{BACKLIT_FILM}\n')  # fmt: skip
    result = bake_atlas(read_materials([folder / "m"]))
    path = folder / "atlas.dds"
    write_bake(result, path)
    return path, result


def _transmitted(film, v_cos, l_cos):
    """The film's back-light in closed form: B T_B colour |N.L| (1 - R_rgb(N.V)) / pi, T_B = 2 (1 - delta)^p / (p + 2)."""
    from atlasgen.models.iridescent import Iridescent

    t_b = 2.0 * (1.0 - film["backlight_distortion"]) ** film["backlight_power"] / (film["backlight_power"] + 2.0)
    r_rgb, _ = Iridescent.film_colour(film, v_cos)
    return (film["backlight"] * t_b * np.asarray(film["backlight_colour"]) * (1.0 - r_rgb)
            * np.abs(l_cos)[..., None] / np.pi)  # fmt: skip


@pytest.mark.slow
def test_a_back_light_bakes_a_transmission_slice_after_the_terms(backlit_film_atlas):
    """K terms, then one table slice whose RGB / pi is the film's closed-form transmission at the texel
    centres (to 8-bit); the manifest and the separable table say where it is and how it is scaled."""
    from atlasgen.contract import texel_grid
    from atlasgen.io.atlas import read_atlas
    from atlasgen.optics.quantize import dequantize_rgba
    from atlasgen.shaders.separable import separable_table

    path, result = backlit_film_atlas
    entry = result.manifest.entry_named("film")
    assert entry.slice_count == 3 and entry.factors.term_slices == 2 and entry.factors.transmission.slice == 2
    assert len(entry.factors.factor_scale) == 2 and entry.bias[2] == [0.0, 0.0]
    atlas = read_atlas(path)
    decoded = dequantize_rgba(np.asarray(atlas.image.levels[0])[entry.first_slice + 2], atlas.srgb)
    rgb = decoded[..., :3] * entry.scale[2][0]
    nl, nv = texel_grid()
    expected = np.pi * _transmitted(entry.params["film"], nv, np.minimum(nl, 0.0))
    peak = expected.max()
    assert abs(entry.scale[2][0] - peak) < 2e-3 * peak  # the slice's peak: every 8-bit code is used
    np.testing.assert_allclose(rgb, expected, atol=0.01 * peak)  # sRGB codes near the peak are ~0.9% apart
    assert (decoded[nl > 0.0] == 0.0).all()
    directory = separable_table([entry])[1]
    assert directory.tolist() == [entry.first_slice, 2.0, 2.0, np.float32(entry.scale[2][0])]


@pytest.mark.slow
def test_the_rebuild_reads_the_terms_above_and_the_transmission_slice_below(backlit_film_atlas):
    """evaluate_separable from the files: light from below is the slice's bilinear rgb / pi, within a
    few 8-bit steps of the film's closed form; from above, the terms alone (the slice changes nothing)."""
    from dataclasses import replace

    from atlasgen.separable.rebuild import evaluate_factors, evaluate_separable, read_separable_factors

    path, result = backlit_film_atlas
    entry = result.manifest.entry_named("film")
    rng = np.random.default_rng(5)
    v = _directions(rng, 400)
    l = _directions(rng, 400) * np.array([1.0, 1.0, -1.0])
    n = np.broadcast_to([0.0, 0.0, 1.0], v.shape)
    below = evaluate_separable(path, "film", n, l, v, cosine=True)
    expected = _transmitted(entry.params["film"], v[:, 2], l[:, 2])
    assert np.abs(below - expected).max() < 0.02 * expected.max()
    np.testing.assert_allclose(below, make_source(entry.params).f_cos(l, v), atol=0.02 * expected.max())
    above = _directions(rng, 400)
    factors = read_separable_factors(path, "film")
    assert factors.transmission is not None
    np.testing.assert_array_equal(
        evaluate_separable(path, "film", n, above, v, cosine=True),
        evaluate_factors(replace(factors, transmission=None), n, above, v, cosine=True),
    )
    # The manifest's figure over the whole sphere: terms and slice against the film, with its SE.
    sphere = entry.factors.transmission.errors_8bit_sphere
    assert sphere.relative_rms_se > 0.0 and sphere.relative_rms < 0.5


def test_auto_is_refused_with_a_back_light(expect_rejected):
    expect_rejected(
        "separable", f'source = "thin_film"\nrepresentation = "auto"\n{BACKLIT_FILM}', "representation", "film.backlight"
    )


def test_the_physical_reference_has_the_back_light_and_the_material_one_slice_more(write_material):
    material = read_material(write_material("f", f'type = "separable"\nsource = "thin_film"\nterms = 1\n{BACKLIT_FILM}\n'))
    ref = get_model("separable").physical_reference(material.params, albedo=(0.5, 0.5, 0.5))
    assert [ref.bsdf[f"backlight_{c}"] for c in "rgb"] == [0.55, 0.75, 1.0]
    assert json.loads(ref.bsdf["film"])["backlight"] == 1.5 and "backlight_colour" not in json.loads(ref.bsdf["film"])
    assert get_model("separable").slice_count(material.params) == 2


@pytest.mark.slow
def test_the_gpu_include_reads_the_transmission_slice_as_the_rebuild_does(gpu_device, backlit_film_atlas):
    """The generated include on lavapipe against evaluate_separable, with normals anywhere and l on
    both sides: the terms above the surface and the transmission slice below agree to the GPU's
    filtering precision (1% of the largest value, as for the terms alone)."""
    from atlasgen.io.dds import read_dds
    from atlasgen.separable.rebuild import evaluate_separable
    from tests.separable.separable_helpers import random_frames
    from tests.shaders.test_separable import _run

    path, result = backlit_film_atlas
    dds = read_dds(path)
    n, l, v = random_frames(3000, seed=12)
    entry = result.manifest.entry_named("film")
    gpu = _run(gpu_device, np.asarray(dds.levels[0]), dds.dxgi_format == 29, result.include, n, l, v, entry.first_slice)
    cpu = evaluate_separable(path, "film", n, l, v, cosine=True)
    below = (np.sum(n * l, 1) < -0.02) & (np.sum(n * v, 1) > 0.02)
    assert below.sum() > 200 and (cpu[below] > 0.0).all()
    scale = np.abs(cpu).max()
    assert np.abs(gpu - cpu).max() <= 0.01 * scale
    assert np.abs(gpu[below] - cpu[below]).max() <= 0.01 * np.abs(cpu[below]).max()
