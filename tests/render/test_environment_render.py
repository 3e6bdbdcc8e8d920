"""Environment lighting in the renderer: closed forms, the CPU twins at the g-buffer's normals, the background.

The CPU twins are atlasgen/optics/environment_tables.py's diffuse_environment, specular_environment and
split_sum_environment, fed with the same tables (atlasgen/render/environment.py) and prefiltered levels.
Tolerances: the environment texture and the radiance target are rgba16float (5e-4 relative each).
"""

import numpy as np
import pytest

from atlasgen.materials.scene import shading_gloss
from atlasgen.optics.environment_tables import (
    diffuse_environment,
    directional_albedo_table,
    reflect,
    slice_sh_table,
    slice_specular_table,
    specular_environment,
    split_sum_environment,
)
from atlasgen.optics.equirect import sample_equirect
from atlasgen.render.camera import camera_basis, tangents
from atlasgen.render.environment import decode_render_slice
from tests.render.atlas_fixture import GLOSSY, LAMBERT

pytestmark = pytest.mark.slow

SPHERE = """
{environment}
[camera]
position = [0, 0.4, 3]
target = [0, 0, 0]
[image]
width = 64
height = 48
{background}
[[objects]]
shape = "sphere"
segments = 96
material = "{material}"
albedo = [0.8, 0.6, 0.4]
gloss = 0.6
"""


def _scene(scene_from, material="lambert", environment='environment = "sky"', background=""):
    return scene_from(SPHERE.format(environment=environment, background=background, material=material))


def _rays(scene):
    """Unit directions of the pixels' rays, (h, w, 3), as the lighting pass builds them."""
    right, up, forward = camera_basis(scene.camera)
    tan_x, tan_y = tangents(scene.camera, scene.width, scene.height)
    x = ((np.arange(scene.width) + 0.5) / scene.width) * 2.0 - 1.0
    y = ((np.arange(scene.height) + 0.5) / scene.height) * 2.0 - 1.0
    ray = forward + x[None, :, None] * tan_x * right - y[:, None, None] * tan_y * up
    return ray / np.linalg.norm(ray, axis=-1, keepdims=True)


def test_a_lambert_sphere_under_a_uniform_environment_renders_colour_times_albedo_times_radiance(renderer, scene_from):
    radiance = np.array([0.5, 1.0, 2.0])
    scene = _scene(scene_from, environment="environment = [0.5, 1.0, 2.0]")
    result = renderer.render(scene)
    on = result.aov("id") != 0xFFFF
    assert on.sum() > 500 and not scene.lights
    ratio = result.radiance[on] / (np.array([0.8, 0.6, 0.4]) * radiance)
    # The lambert slice is max(N.L, 0) in 8-bit sRGB: lambda_0 = pi (1 + 1/63^2) up to its quantisation.
    np.testing.assert_allclose(ratio, 1.0, atol=2e-3)
    # The same from the decoded slice's own table, to the rgba16float target's rounding.
    lam0 = slice_sh_table(decode_render_slice(renderer.atlas.levels, True, renderer.atlas.manifest.materials[LAMBERT], LAMBERT))
    assert np.ptp(lam0[:, 0], axis=0).max() < 1e-12  # flat in N.V: a lambert slice's rows are alike
    np.testing.assert_allclose(ratio, np.broadcast_to(lam0[0, 0] / np.pi, ratio.shape), rtol=1e-3)


def test_a_scene_with_an_environment_and_no_lights_is_lit(renderer, scene_from):
    result = renderer.render(_scene(scene_from, material="glossy"))
    on = result.aov("id") != 0xFFFF
    assert np.all(result.radiance[on].sum(-1) > 1e-3)


def test_the_background_shows_the_environment_unless_the_scene_sets_one(renderer, scene_from):
    scene = _scene(scene_from)
    result = renderer.render(scene)
    off = result.aov("id") == 0xFFFF
    image = renderer.environment.data(scene.environment).image
    expected = sample_equirect(image, _rays(scene))
    np.testing.assert_allclose(result.radiance[off], expected[off], rtol=2e-3, atol=1e-3)
    assert np.ptp(result.radiance[off][:, 2]) > 0.05  # a gradient, not one colour
    given = renderer.render(_scene(scene_from, background="background = [0.1, 0.2, 0.3]"))
    shown = given.radiance[given.aov("id") == 0xFFFF]
    np.testing.assert_allclose(shown, np.broadcast_to([0.1, 0.2, 0.3], shown.shape), rtol=1e-3)


def test_a_glossy_lut_sphere_under_the_sky_matches_the_cpu_twin(renderer, scene_from):
    scene = _scene(scene_from, material="glossy")
    result = renderer.render(scene)
    on = result.aov("id") == GLOSSY
    entry = renderer.atlas.manifest.materials[GLOSSY]
    values = decode_render_slice(renderer.atlas.levels, True, entry, GLOSSY)
    assert values[..., 3].min() > 0.2  # A.a > 0: the specular term is there
    data = renderer.environment.data(scene.environment)
    n = result.aov("normal")[on].astype(np.float64)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    v = -_rays(scene)[on]
    nv = np.clip(np.sum(n * v, -1), 0.0, 1.0)
    gloss = shading_gloss(0.6, entry)
    albedo = np.array([0.8, 0.6, 0.4])
    diffuse = albedo * diffuse_environment(data.sh, slice_sh_table(values), n, nv)
    specular = specular_environment(data.levels, slice_specular_table(values), reflect(v, n), nv, gloss)
    expected = diffuse + specular
    assert specular.mean() > 0.05 * expected.mean()
    np.testing.assert_allclose(result.radiance[on], expected, rtol=5e-3, atol=2e-3 * expected.max())


def test_a_separable_sphere_under_the_sky_is_its_split_sum(gpu_context, separable_atlas, scene_from):
    from atlasgen.render.atlas_texture import read_render_atlas
    from atlasgen.render.renderer import Renderer
    from atlasgen.separable.rebuild import evaluate_separable

    path, _ = separable_atlas
    renderer = Renderer(read_render_atlas(path), gpu_context)
    scene = _scene(scene_from, material="plastic")
    result = renderer.render(scene)
    entry = renderer.atlas.manifest.entry_named("plastic")
    on = result.aov("id") == entry.first_slice
    data = renderer.environment.data(scene.environment)

    def f_cos(l, v):
        return evaluate_separable(path, "plastic", np.broadcast_to([0.0, 0.0, 1.0], l.shape), l, v, cosine=True)

    table = directional_albedo_table(f_cos)
    assert table.max() > 0.1
    n = result.aov("normal")[on].astype(np.float64)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    v = -_rays(scene)[on]
    nv = np.clip(np.sum(n * v, -1), 0.0, 1.0)
    expected = np.array([0.8, 0.6, 0.4]) * split_sum_environment(data.levels, table, reflect(v, n), nv, 0.6)
    np.testing.assert_allclose(result.radiance[on], expected, rtol=5e-3, atol=2e-3 * expected.max())


def test_a_separable_material_drawn_by_one_lut_slice_gets_the_split_sum_of_that_slice(tmp_path):
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_materials
    from atlasgen.models.separable import representation_radiance
    from atlasgen.render.atlas_texture import RenderAtlas
    from atlasgen.render.environment import decode_render_slice, material_tables

    (tmp_path / "m.toml").write_text('type = "separable"\nsource = "ggx"\nalpha = 0.3\nrepresentation = "lut"\n')
    result = bake_atlas(read_materials([tmp_path / "m.toml"]))
    atlas = RenderAtlas(result.levels, result.dxgi_format == 29, result.manifest, result.include, "test")
    entry = atlas.manifest.entry_named("m")
    tables = material_tables(atlas.levels, atlas.srgb, entry, custom_lighting=True)
    radiance = representation_radiance(entry, decode_render_slice(atlas.levels, atlas.srgb, entry, entry.first_slice))

    def f_cos(l, v):
        one = np.ones_like(l)
        return radiance(np.broadcast_to([0.0, 0.0, 1.0], l.shape), l, v, one, np.full(len(l), 0.5), one)

    # Column 9 is S_sep of what the light loop shades it with (it was all zero: no environment light).
    np.testing.assert_allclose(tables[:, 9, :3], directional_albedo_table(f_cos, even=True), rtol=1e-5, atol=1e-7)
    assert tables[-1, 9, :3].min() > 0.01
