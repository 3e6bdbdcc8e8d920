"""Separable BRDFs are rebuilt in the lighting pass through the include's separable_f_cos."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.materials.material import read_materials
from atlasgen.render.atlas_texture import read_render_atlas
from atlasgen.render.camera import pixel_rays
from atlasgen.render.renderer import Renderer
from tests.render.atlas_fixture import interior, light_at

SCENE = """
[camera]
position = [0.0, 0.5, 3.5]
target = [0, 0, 0]
fov = 45
[image]
width = 48
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
segments = 128
[[objects]]
shape = "sphere"
material = "clay"
translate = [1.4, 0.0, -1.0]
scale = 0.5
"""


@pytest.mark.slow
def test_separable_material_matches_numpy_rebuild(gpu_device, write_material, tmp_path, scene_from):
    from atlasgen.separable.rebuild import evaluate_separable

    write_material("metal", 'type = "separable"\nsource = "ggx"\nalpha = 0.3\nfresnel = "schlick"\n'
                            'f0 = [0.9, 0.6, 0.3]\nterms = 2\n')  # fmt: skip
    write_material("clay", 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n')
    path = tmp_path / "atlas.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), path)
    atlas = read_render_atlas(path)
    renderer = Renderer(atlas, gpu_device)
    scene = scene_from(SCENE)
    result = renderer.render(scene, outlines=False)
    metal = atlas.manifest.entry_named("metal").first_slice
    mask = interior(result.aov("id")) & (result.aov("id") == metal)
    assert mask.sum() > 200
    n = result.aov("normal")[mask].astype(np.float64)
    rays = pixel_rays(scene.camera, scene.width, scene.height)[mask]
    world = np.asarray(scene.camera.position) + rays * result.aov("depth")[mask, None]
    v = -rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    expected = np.zeros_like(n)
    for light in scene.lights:
        l, e = light_at(light, world)
        expected += e * np.asarray([0.9, 0.8, 0.7]) * evaluate_separable(path, "metal", n, l, v, cosine=True)
    got = result.radiance[mask]
    floor = 0.02 * expected.max()
    err = np.abs(got - expected) / np.maximum(expected, floor)
    assert expected.max() > 0.1
    assert np.quantile(err, 0.99) < 2e-2 and err.max() < 5e-2
