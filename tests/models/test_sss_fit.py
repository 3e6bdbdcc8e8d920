"""from = "physical" for sss: the slice fitted to volpath renders of a sphere of skin (issue 11)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from atlasgen.contract import HEIGHT, WIDTH, texel_centres
from atlasgen.models import sss_fit
from atlasgen.models.sss_fit import (
    FIT_STRATA,
    MIN_N_DOT_V,
    bilinear_stencil,
    fit_texels,
    local_directions,
    sample_configurations,
    sphere_rays,
)  # fmt: skip
from atlasgen.optics.interpolation import sample_slice


def _samples(passes=2):
    nl, nv, phi = sample_configurations(passes)
    return nl, nv, phi


def test_configurations_are_stratified_over_the_whole_domain_and_deterministic():
    passes = 3
    nl, nv, phi = sample_configurations(passes)
    a, b, c = FIT_STRATA
    assert len(nl) == passes * a * b * c
    # Exactly `passes` samples in every (N.L, N.V, phi) stratum.
    cells = (np.floor((nl + 1.0) / 2.0 * a) * b + np.floor((nv - MIN_N_DOT_V) / (1 - MIN_N_DOT_V) * b)) * c
    cells += np.floor(phi / np.pi * c)
    counts = np.bincount(cells.astype(int), minlength=a * b * c)
    assert counts.min() == passes and counts.max() == passes
    assert nl.min() >= -1.0 and nl.max() <= 1.0 and nv.min() >= MIN_N_DOT_V and nv.max() <= 1.0
    assert phi.min() >= 0.0 and phi.max() <= np.pi
    # Every texel is reached by many samples (the bilinear weight it gets in total).
    index, weight = bilinear_stencil(nl, nv)
    reach = np.bincount(index.ravel(), weight.ravel(), minlength=WIDTH * HEIGHT)
    assert reach.min() > 0.2 * reach.mean()
    again = sample_configurations(passes)
    assert all(np.array_equal(x, y) for x, y in zip((nl, nv, phi), again))


def test_sphere_rays_see_each_configuration():
    nl, nv, phi = sample_configurations(1)
    origins, directions = sphere_rays(nl, nv, phi)
    v = -directions
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-12)
    # The first hit of origin + t d with the sphere |x| = R is at t = 1 (the point p = R n).
    r = sss_fit.OBJECT_RADIUS
    b = (origins * directions).sum(1)
    c = (origins * origins).sum(1) - r * r
    t_first = -b - np.sqrt(b * b - c)
    np.testing.assert_allclose(t_first, 1.0, atol=1e-9)
    n = (origins + directions) / r
    light = np.array([0.0, 0.0, 1.0])  # the directional light arrives from +z
    np.testing.assert_allclose(n @ light, nl, atol=1e-12)
    np.testing.assert_allclose((n * v).sum(1), nv, atol=1e-12)
    # The shading frame's l and v have the same mutual angle as in the world.
    l_loc, v_loc, _, _ = local_directions(nl, nv, phi)
    np.testing.assert_allclose((l_loc * v_loc).sum(1), v @ light, atol=1e-12)


def test_bilinear_stencil_is_the_renderers_lookup():
    rng = np.random.default_rng(3)
    table = rng.random((HEIGHT, WIDTH, 2))
    nl, nv = rng.uniform(-1, 1, 500), rng.uniform(0, 1, 500)
    index, weight = bilinear_stencil(nl, nv)
    mine = (table.reshape(-1, 2)[index] * weight[..., None]).sum(1)
    np.testing.assert_allclose(mine, sample_slice(table, nl, nv), atol=1e-12)


@pytest.mark.slow
def test_fit_gives_back_a_bilinear_slice_exactly():
    # A bilinear function of (N.L, N.V) is a slice exactly, and the smoothness penalty (second
    # differences) vanishes on it: the fit must return it to rounding.
    nl, nv, _ = _samples()
    nl_c, nv_c = texel_centres()
    truth = np.stack([(0.2 + 0.3 * (nl_c[None, :] + 1.0)) * (0.5 + nv_c[:, None]),
                      np.broadcast_to(0.7 - 0.2 * nl_c[None, :], (HEIGHT, WIDTH))], -1)  # fmt: skip
    y = sample_slice(truth, nl, nv)
    np.testing.assert_allclose(fit_texels(nl, nv, y), truth, atol=1e-9)


@pytest.mark.slow
def test_fit_gives_back_lambert():
    # RGB = colour * max(N.L, 0): exact on texels away from the kink at N.L = 0 (which lies
    # between two texel centres), non-negative everywhere.
    nl, nv, _ = _samples()
    colour = np.array([0.8, 0.4, 0.1])
    fitted = fit_texels(nl, nv, np.maximum(nl, 0.0)[:, None] * colour)
    nl_c, _ = texel_centres()
    expected = np.maximum(nl_c, 0.0)[None, :, None] * colour
    away = np.abs(nl_c) > 3.0 * 2.0 / (WIDTH - 1)
    np.testing.assert_allclose(fitted[:, away], np.broadcast_to(expected, fitted.shape)[:, away], atol=2e-3)
    assert (fitted >= 0.0).all()
    assert np.abs(fitted - expected).max() < 0.02


@pytest.mark.slow
def test_fit_is_non_negative_and_least_squares_where_free():
    nl, nv, _ = _samples(1)
    rng = np.random.default_rng(5)
    y = np.where(nl < 0.0, -0.05, 0.3)[:, None] + 0.01 * rng.standard_normal((len(nl), 1))
    fitted = fit_texels(nl, nv, y)
    nl_c, _ = texel_centres()
    assert (fitted >= 0.0).all()
    assert np.all(fitted[:, nl_c < -0.1] == 0.0)  # data below 0: clamped, not negative
    np.testing.assert_allclose(fitted[:, nl_c > 0.1], 0.3, atol=0.01)


def test_sss_from_physical_is_accepted(write_material):
    from atlasgen.materials.material import read_material

    material = read_material(write_material("m", 'type = "sss"\nfrom = "physical"\n'))
    assert material.fit_from == "physical"


def _skin_reference():
    from atlasgen.models import get_model

    model = get_model("sss")
    ref = model.physical_reference({p.name: p.default for p in model.params})
    return ref.interior, dict(ref.integrator, type="volpathmis")


@pytest.mark.slow
def test_sphere_renders_are_deterministic_and_lit_from_the_light(mitsuba_llvm):
    medium, integrator = _skin_reference()
    nl = np.repeat([1.0, -1.0], 2048)
    nv, phi = np.full(4096, 1.0), np.zeros(4096)
    origins, directions = sphere_rays(nl, nv, phi)
    a = sss_fit.render_sphere_samples(medium, integrator, origins, directions, seed=0)
    assert a.tobytes() == sss_fit.render_sphere_samples(medium, integrator, origins, directions, seed=0).tobytes()
    other = sss_fit.render_sphere_samples(medium, integrator, origins, directions, seed=1)
    assert not np.array_equal(a, other)
    # Head-on, white skin returns a good part of the light; through a 10 mm ball almost none.
    front, back = a[:2048].mean(0), a[2048:].mean(0)
    assert (front > 0.1).all() and (back < 0.1 * front).all() and (a >= 0.0).all()


@pytest.mark.slow
def test_fit_is_deterministic_and_reports_its_noise(mitsuba_llvm):
    medium, integrator = _skin_reference()
    a, info, _ = sss_fit.fit_sss_slice(medium, integrator, 0.028, 0.5, passes=1)
    b, again, _ = sss_fit.fit_sss_slice(medium, integrator, 0.028, 0.5, passes=1)
    assert a.tobytes() == b.tobytes() and info == again
    assert a.shape == (HEIGHT, WIDTH, 4) and (a >= 0.0).all() and np.all(a[..., 3] == 0.028)
    assert info["rays"] == len(sss_fit.FIT_RADII) * np.prod(FIT_STRATA) and info["light_directions"] == 1
    assert 0.0 < info["noise_relative_rms"] < info["seed_disagreement_relative_rms"]
    # Fitted on spheres other than the validation sphere, and scored there and on a flat part, out of sample.
    assert sss_fit.OBJECT_RADIUS not in info["fit_radii"]
    scored = info["out_of_sample"]
    assert set(scored) == {"validation_sphere", "flat"} and scored["validation_sphere"]["radius"] == sss_fit.OBJECT_RADIUS
    assert all(s["rays"] == np.prod(FIT_STRATA) and 0.0 <= s["relative_rms"] < 1.0 for s in scored.values()), scored
    # Flat skin lit from behind (N.L < 0) is dark, unlike a sphere's wrap: the flat part scores worst.
    assert scored["flat"]["relative_rms"] > scored["validation_sphere"]["relative_rms"]
    # Skin lit head-on returns light (a few tenths of its colour), and almost none from behind.
    assert a[HEIGHT // 2, -1, 0] > 0.2 and a[HEIGHT // 2, 0, :3].max() < 0.05


SKIN = 'type = "sss"\nradius = 12.0\ncolour = [0.625, 0.385, 0.241]\n'


def _sphere_only(scene: str, folder):
    """The standard validation scene without its plane (the reference is a slab of skin there,
    flat, which no sphere fit is meant to match)."""
    from importlib.resources import files

    text = (files("atlasgen") / "data" / "validation" / f"{scene}.toml").read_text()
    path = folder / f"{scene}-sphere.toml"
    path.write_text(text[: text.rindex("[[objects]]")])
    assert text.count("[[objects]]") == 2 and 'shape = "plane"' in text[text.rindex("[[objects]]") :]
    return str(path)


@pytest.mark.slow
def test_fitted_skin_beats_the_closed_form_against_volpath(mitsuba_llvm, gpu_context, tmp_path, shipped_library_cache):
    """The shipped skin's two slices on the validation sphere, against the volpath reference."""
    import json
    import shutil

    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.materials.material import read_materials
    from atlasgen.validate.run import validate_atlas

    shipped = (Path(__file__).resolve().parents[2] / "materials" / "skin.toml").read_text()
    assert 'from = "physical"\n' in shipped
    folder = tmp_path / "materials"
    folder.mkdir()
    (folder / "closed.toml").write_text(shipped.replace('from = "physical"\n', ""))
    # The shipped file itself, whose fit (volpath renders: a minute of CPU) the session's bake cache holds.
    (folder / "fitted.toml").write_text(shipped)
    cache = tmp_path / "cache"
    cache.mkdir()
    shutil.copy(shipped_library_cache / "skin.npz", cache / "fitted.npz")
    dds = tmp_path / "atlas.dds"
    write_bake(bake_atlas(read_materials([folder]), cache_dir=cache), dds)
    scenes = [_sphere_only(s, tmp_path) for s in ("front", "back")]
    # 32x24: the volpath references are most of the test's CPU, and each PSNR here came within
    # 0.5 dB of 64x48's (2026-12-02), several dB clear of both bounds: PSNR is a mean over pixels.
    run = validate_atlas(dds, scenes=scenes, resolution=(32, 24), physical_spp=256, max_physical_spp=256)
    psnr = {(r.material, r.scene): r.references["physical"].metrics.psnr for r in run.runs}
    for scene in {r.scene for r in run.runs}:
        # With the reference's own noise in both (a floor near 35 dB at this spp).
        assert psnr[("fitted", scene)] >= 30.0 and psnr[("fitted", scene)] > psnr[("closed", scene)] + 1.0, psnr
    entries = json.loads(dds.with_suffix(".json").read_text())["materials"]
    entry = next(e for e in (entries if isinstance(entries, list) else entries.values()) if e["name"] == "fitted")
    info = entry["fit"]
    assert info["from"] == "physical" and info["gloss"] == 0.5 and info["spp"] == 1
    # The fit's noise is well below its error (10 dB: a factor sqrt(10) in RMS).
    assert info["noise_relative_rms"] * np.sqrt(10.0) < info["relative_rms"] < info["model_relative_rms"]


def test_the_golden_skin_fit_is_fitted_on_spheres_other_than_the_validation_one():
    """The manifest's in-sample radii are the fit's own, and the validation sphere is not one of them (its score is
    out of sample; docs/materials.md's table quotes both, written by atlasgen.reports.measured_docs)."""
    import json

    root = Path(__file__).resolve().parents[2]
    manifest = json.loads((root / "tests" / "resources" / "golden" / "array-srgb.json").read_text())
    fit = next(m for m in manifest["materials"] if m["name"] == "skin")["fit"]
    assert fit["fit_radii"] == list(sss_fit.FIT_RADII) and sss_fit.OBJECT_RADIUS not in fit["fit_radii"]
