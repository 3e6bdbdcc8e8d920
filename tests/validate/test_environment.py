"""The environment breakdown on the CPU (atlasgen/validate/environment.py) and the mask its metrics use.

The g-buffer here is a sphere's, computed in closed form (ray-sphere intersection), so no GPU is needed.
"""

import math
import textwrap
import tomllib

import numpy as np
import pytest

from atlasgen.materials.scene import parse_scene
from atlasgen.render.camera import pixel_rays
from atlasgen.render.environment import EnvironmentData
from atlasgen.validate.environment import break_down_environment, environment_parts
from atlasgen.validate.metrics import compare_images
from atlasgen.validate.rebuild import material_mask
from tests.render.atlas_fixture import GLOSSY, LAMBERT, build_fixture_atlas

SPHERE = """
{environment}
[camera]
position = [0, 0.3, 3]
target = [0, 0, 0]
fov = 30
[image]
width = {width}
height = {height}
[[objects]]
shape = "sphere"
material = "m"
"""


def _scene(environment, width=20, height=16):
    text = SPHERE.format(environment=environment, width=width, height=height)
    return parse_scene(tomllib.loads(textwrap.dedent(text)), "test.toml", None)


#: The CPU breakdown integrates the whole environment at every pixel: a smaller image than the
#: GPU tests' (80 pixels, every one on the sphere, against the 50 asked for) is as good a test, and cheaper.
SMALL = (10, 8)


def _sphere_aovs(scene, slot: int, gloss: float = 0.6):
    """The g-buffer of a unit sphere at the origin: depth, normal, albedo, gloss and id per pixel."""
    rays = pixel_rays(scene.camera, scene.width, scene.height)
    o = np.asarray(scene.camera.position, dtype=np.float64)
    d = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    b = d @ o
    disc = b * b - (o @ o - 1.0)
    hit = disc > 0
    t = np.where(hit, -b - np.sqrt(np.maximum(disc, 0.0)), 0.0)
    depth = t * np.linalg.norm(rays, axis=-1)  # along the unnormalised ray, as the rebuilds read it
    normal = o + d * t[..., None]
    albedo = np.broadcast_to([0.8, 0.6, 0.4], hit.shape + (3,))
    return {"depth": depth, "normal": normal, "albedo": albedo, "gloss": np.full(hit.shape, gloss),
            "id": np.where(hit, slot, 0xFFFF)}  # fmt: skip


@pytest.fixture(scope="module")
def atlas():
    return build_fixture_atlas()


@pytest.mark.slow
def test_the_parts_sum_to_the_total_cpu_error_and_a_uniform_environment_is_exact_for_the_diffuse_term(atlas):
    entry = atlas.manifest.materials[GLOSSY]
    for environment in ('environment = "sky"', "environment = [0.5, 1.0, 2.0]"):
        scene = _scene(environment, *SMALL)
        aovs = _sphere_aovs(scene, GLOSSY)
        parts = environment_parts(atlas.levels, atlas.srgb, entry, scene, aovs, EnvironmentData.of(scene.environment))
        assert parts.mask.sum() > 50
        sh_error = parts.diffuse_sh - parts.diffuse_exact
        split_error = parts.specular_split_sum - parts.specular_exact
        np.testing.assert_allclose(sh_error + split_error, parts.approx - parts.exact, atol=1e-12)
        assert np.abs(parts.specular_exact).max() > 1e-3 and np.abs(parts.diffuse_exact).max() > 1e-2
        figures = break_down_environment(parts)
        assert figures["pixels"] == int(parts.mask.sum())
        if "sky" in environment:  # both approximations cost something under a sun
            assert 20.0 < figures["sh_band_limit"]["psnr_db"] < 80.0 and 20.0 < figures["split_sum"]["psnr_db"] < 80.0
            assert figures["total"]["psnr_db"] <= max(figures["sh_band_limit"]["psnr_db"], figures["split_sum"]["psnr_db"])
        else:  # a constant is exact to the band limit: lambda_0 / pi L is the whole integral (to the texel sum's
            # quadrature of a piecewise-linear slice, 6e-5 at 128 x 256 texels)
            np.testing.assert_allclose(parts.diffuse_sh[parts.mask], parts.diffuse_exact[parts.mask], rtol=2e-4)
            # and the split sum is exact for a constant too, up to its table's quadrature (5e-4, environment_tables.py)
            np.testing.assert_allclose(parts.specular_split_sum[parts.mask], parts.specular_exact[parts.mask], rtol=2e-2)


@pytest.mark.slow
def test_a_lambert_slice_under_a_uniform_environment_integrates_to_albedo_times_radiance(atlas):
    scene = _scene("environment = [0.5, 1.0, 2.0]", *SMALL)
    aovs = _sphere_aovs(scene, LAMBERT)
    parts = environment_parts(atlas.levels, atlas.srgb, atlas.manifest.materials[LAMBERT], scene, aovs)
    expected = np.array([0.8, 0.6, 0.4]) * np.array([0.5, 1.0, 2.0])
    # The fixture's lambert slice is max(N.L, 0) stored in 8 bits: its integral is pi (1 + 1/63^2) to quantisation.
    np.testing.assert_allclose(parts.diffuse_exact[parts.mask] / expected, 1.0, atol=3e-3)
    np.testing.assert_allclose(parts.specular_exact[parts.mask], 0.0, atol=1e-12)


def test_the_environment_metrics_ignore_pixels_that_do_not_show_the_material():
    ids = np.full((12, 16), 0xFFFF)
    ids[3:9, 4:12] = 7
    entry = type("Entry", (), {"first_slice": 7, "slice_count": 1})()
    mask = ~material_mask(entry, {"id": ids})
    rng = np.random.default_rng(1)
    reference = rng.uniform(0.0, 1.0, (12, 16, 3)).astype(np.float32)
    test = reference.copy()
    test[mask] = rng.uniform(0.0, 1.0, (int(mask.sum()), 3))  # only the background differs
    m = compare_images(reference, test, mask=mask, with_flip=False)
    assert m.psnr == math.inf and m.linear_rmse == 0.0
    test[5, 6] += 0.1  # and a material pixel that differs is seen
    assert compare_images(reference, test, mask=mask, with_flip=False).psnr < 60.0


@pytest.mark.slow
def test_a_lambert_sphere_under_a_constant_emitter_meets_45_db_against_mitsuba(atlas, gpu_device, mitsuba_llvm):
    """The renderer's SH diffuse term is exact for a constant environment (lambda_0 / pi L), so the GPU image of a
    lambert sphere matches Mitsuba's ``constant`` emitter integrated by ``atlasgen_direct`` to the 8-bit table and
    the reference's noise: the model-reference goal, 45 dB, on the material's pixels."""
    from atlasgen.render.renderer import Renderer
    from atlasgen.validate.mitsuba_scene import build_mitsuba_scene, render_pixel_centres
    from atlasgen.validate.references import register_references

    mi = mitsuba_llvm
    register_references(mi)
    import dataclasses

    entry = atlas.manifest.materials[LAMBERT]
    scene = _scene("environment = [0.6, 0.7, 0.8]")
    scene = dataclasses.replace(scene, objects=[dataclasses.replace(o, material=entry.name) for o in scene.objects])
    result = Renderer(atlas, gpu_device).render(scene, outlines=False, aovs=True)
    mask = ~material_mask(entry, result.aovs)
    assert (~mask).sum() > 50
    # The fixture's lambert slice is max(N.L, 0): Mitsuba's diffuse of the object's albedo is its closed form.
    bsdfs = [{"type": "diffuse", "reflectance": {"type": "rgb", "value": [float(c) for c in o.albedo]}} for o in scene.objects]
    mi_scene = build_mitsuba_scene(mi, scene, bsdfs, 1, stochastic=True)
    reference, _ = render_pixel_centres(mi, mi_scene, 256, seed=0)
    m = compare_images(reference, np.asarray(result.radiance, dtype=np.float32), scene.settings.exposure, mask=mask,
                       with_flip=False)  # fmt: skip
    assert m.psnr >= 45.0, m.psnr


def test_a_separable_material_under_a_uniform_environment_is_its_split_sum_and_none_without_factors(separable_atlas):
    from atlasgen.render.atlas_texture import read_render_atlas
    from atlasgen.validate.environment import separable_environment_parts

    path, _ = separable_atlas
    atlas = read_render_atlas(path)
    radiance = np.array([0.5, 1.0, 2.0])
    scene = _scene("environment = [0.5, 1.0, 2.0]", *SMALL)
    entry = atlas.manifest.entry_named("plastic")
    parts = separable_environment_parts(atlas.levels, atlas.srgb, entry, scene, _sphere_aovs(scene, entry.first_slice))
    assert parts.mask.sum() > 50
    # The split sum is exact for a constant: albedo L S_sep(N.V) is the whole integral, to the texel sum's
    # quadrature of the rebuilt lobe (alpha 0.3: 1e-2 at 128 x 256 texels) against S_sep's Gauss-Legendre rule.
    on = parts.mask
    assert parts.specular_exact[on].min() > 1e-2
    np.testing.assert_allclose(parts.specular_split_sum[on], parts.specular_exact[on], rtol=2e-2)
    # And it is albedo L times the directional albedo: a white furnace reflects at most what arrives.
    assert np.all(parts.specular_exact[on] / (np.array([0.8, 0.6, 0.4]) * radiance) <= 1.0 + 1e-2)
    figures = break_down_environment(parts)
    assert figures["sh_band_limit"]["psnr_db"] is None  # no diffuse part: its error is exactly zero
    assert figures["total"]["psnr_db"] == pytest.approx(figures["split_sum"]["psnr_db"], rel=1e-12)

    sky = _scene('environment = "sky"', *SMALL)
    under_sky = break_down_environment(
        separable_environment_parts(atlas.levels, atlas.srgb, entry, sky, _sphere_aovs(sky, entry.first_slice))
    )
    # A sun costs the split sum much: the mirror direction's prefiltered radiance stands for a lobe that is
    # mostly diffuse here (16.9 dB when written).
    assert 10.0 < under_sky["total"]["psnr_db"] < figures["total"]["psnr_db"] - 20.0
    lut = atlas.manifest.entry_named("lut")
    assert separable_environment_parts(atlas.levels, atlas.srgb, lut, scene, _sphere_aovs(scene, lut.first_slice)) is None
