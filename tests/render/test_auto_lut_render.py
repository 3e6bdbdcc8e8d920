"""A separable material that ``representation = "auto"`` bakes as one LUT slice fitted from physics is drawn
by the lighting pass as that slice in the renderer's equation at the *fitted* gloss, times the albedo.

The GPU image is held against the validation rebuild (:meth:`atlasgen.models.separable.Separable.radiance_rebuilds`),
evaluated in float64 from the g-buffer read back.
"""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.materials.material import read_materials
from atlasgen.models.separable import Separable
from atlasgen.render.atlas_texture import read_render_atlas
from atlasgen.render.camera import pixel_rays
from atlasgen.render.renderer import Renderer
from tests.render.atlas_fixture import interior, light_at

SCENE = """
[camera]
position = [0.0, 0.3, 3.0]
target = [0, 0, 0]
fov = 40
[image]
width = 48
height = 40
[[lights]]
type = "directional"
direction = [-0.3, -0.5, -1.0]
intensity = 2.0
[[lights]]
type = "point"
position = [1.5, 1.0, 2.0]
intensity = 4.0
[[objects]]
shape = "sphere"
material = "sheen"
albedo = [0.9, 0.7, 0.5]
gloss = 0.95
segments = 128
"""


@pytest.mark.slow
def test_auto_lut_material_matches_its_rebuild_at_the_fitted_gloss(gpu_device, write_material, tmp_path, scene_from):
    write_material("sheen", 'type = "separable"\nsource = "blinn_phong"\nexponent = 4.0\nspecular = [0.2, 0.2, 0.2]\n'
                            'diffuse = [0.5, 0.35, 0.25]\nrepresentation = "auto"\nerror_budget = 0.05\n')  # fmt: skip
    path = tmp_path / "atlas.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), path)
    atlas = read_render_atlas(path)
    entry = atlas.manifest.entry_named("sheen")
    assert entry.representation.kind == "lut" and entry.fit.gloss < 0.9  # not the object's 0.95
    scene = scene_from(SCENE)
    result = Renderer(atlas, gpu_device).render(scene, outlines=False)
    ids = result.aov("id")
    mask = interior(ids) & (ids == entry.first_slice)
    assert mask.sum() > 200
    n = result.aov("normal")[mask].astype(np.float64)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    rays = pixel_rays(scene.camera, scene.width, scene.height)[mask]
    world = np.asarray(scene.camera.position) + rays * result.aov("depth")[mask, None]
    v = -rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    rebuild = Separable().radiance_rebuilds(entry, path)["8bit"].radiance
    albedo = np.asarray([0.9, 0.7, 0.5])
    expected = np.zeros_like(n)
    for light in scene.lights:
        l, e = light_at(light, world)
        expected += rebuild(n, l, v, albedo, 0.95, e)
    got = result.radiance[mask]
    floor = 0.02 * expected.max()
    err = np.abs(got - expected) / np.maximum(expected, floor)
    assert expected.max() > 0.05
    # f16 render target and the GPU's bilinear filter (8-bit weights): the rest is the equation's.
    assert np.quantile(err, 0.99) < 2e-2, np.quantile(err, 0.99)
