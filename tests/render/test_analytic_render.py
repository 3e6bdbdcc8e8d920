"""Analytic BRDFs (``representation = "analytic"``) are evaluated in closed form by the lighting pass.

The GPU image is held against :func:`atlasgen.separable.analytic.evaluate_analytic`, the NumPy
BRDF written from Walter et al. 2007, evaluated in float64 from the g-buffer read back.
"""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.materials.material import read_materials
from atlasgen.render.atlas_texture import read_render_atlas
from atlasgen.render.camera import pixel_rays
from atlasgen.render.renderer import Renderer
from atlasgen.separable.analytic import evaluate_analytic, to_local_frame
from tests.render.atlas_fixture import interior, light_at

SCENE = """
[camera]
position = [0.0, 0.5, 3.5]
target = [0, 0, 0]
fov = 45
[image]
width = 56
height = 40
[[lights]]
type = "directional"
direction = [-0.3, -0.6, -1.0]
intensity = 2.0
[[lights]]
type = "point"
position = [-2.0, 1.0, 2.0]
colour = [0.4, 0.6, 1.0]
intensity = 5.0
[[objects]]
shape = "sphere"
material = "metal"
albedo = [0.9, 0.8, 0.7]
translate = [-0.6, 0.0, 0.0]
scale = 0.7
segments = 128
[[objects]]
shape = "sphere"
material = "plastic"
translate = [0.8, 0.0, 0.0]
scale = 0.7
segments = 128
"""

MATERIALS = {
    "metal": ('source = "ggx"\nalpha = 0.3\nfresnel = "schlick"\nf0 = [0.9, 0.6, 0.3]\ndiffuse = [0.1, 0.2, 0.05]\n',
              {"source": "ggx", "alpha": 0.3, "fresnel": "schlick", "f0": (0.9, 0.6, 0.3), "ior": 1.5,
               "specular": (1.0, 1.0, 1.0), "diffuse": (0.1, 0.2, 0.05)}),
    "plastic": ('source = "beckmann"\nalpha = 0.2\nfresnel = "exact"\nior = 1.6\ndiffuse = [0.3, 0.1, 0.05]\n',
                {"source": "beckmann", "alpha": 0.2, "fresnel": "exact", "f0": (0.04, 0.04, 0.04), "ior": 1.6,
                 "specular": (1.0, 1.0, 1.0), "diffuse": (0.3, 0.1, 0.05)}),
}  # fmt: skip


@pytest.fixture
def analytic_render(gpu_device, write_material, tmp_path, scene_from):
    for name, (body, _) in MATERIALS.items():
        write_material(name, f'type = "separable"\nrepresentation = "analytic"\n{body}')
    path = tmp_path / "atlas.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), path)
    atlas = read_render_atlas(path)
    scene = scene_from(SCENE)
    return atlas, scene, Renderer(atlas, gpu_device).render(scene, outlines=False)


@pytest.mark.parametrize("name", sorted(MATERIALS))
@pytest.mark.slow
def test_analytic_material_matches_numpy_brdf(analytic_render, name):
    atlas, scene, result = analytic_render
    albedo = np.asarray([0.9, 0.8, 0.7]) if name == "metal" else np.ones(3)
    ids = result.aov("id")
    mask = interior(ids) & (ids == atlas.manifest.entry_named(name).first_slice)
    assert mask.sum() > 200
    n = result.aov("normal")[mask].astype(np.float64)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    rays = pixel_rays(scene.camera, scene.width, scene.height)[mask]
    world = np.asarray(scene.camera.position) + rays * result.aov("depth")[mask, None]
    v = -rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    expected = np.zeros_like(n)
    for light in scene.lights:
        l, e = light_at(light, world)
        ll, lv = to_local_frame(n, l), to_local_frame(n, v)
        f_cos = evaluate_analytic(MATERIALS[name][1], ll, lv) * np.maximum(ll[..., 2], 0.0)[..., None]
        expected += e * albedo * f_cos
    got = result.radiance[mask]
    floor = 0.02 * expected.max()
    err = np.abs(got - expected) / np.maximum(expected, floor)
    assert expected.max() > 0.1
    # f16 render target (3 decimal digits) and f32 arithmetic: the rest is the formula's.
    assert np.quantile(err, 0.99) < 1e-2 and err.max() < 3e-2


def test_local_frame_keeps_cosines_and_angles():
    rng = np.random.default_rng(3)
    n = rng.normal(size=(500, 3))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    n[:5] = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0.95, 0.3122, 0]]
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    a, b = rng.normal(size=(2, 500, 3))
    la, lb = to_local_frame(n, a), to_local_frame(n, b)
    np.testing.assert_allclose(la[:, 2], (a * n).sum(-1), atol=1e-12)
    np.testing.assert_allclose((la * lb).sum(-1), (a * b).sum(-1), atol=1e-12)
