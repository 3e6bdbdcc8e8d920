"""The preview's scene: what it holds, the environment it asks for, the ball's file, and its light."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.errors import OutputError, SceneError
from atlasgen.preview.scene import ENVIRONMENT, ball_mesh_file, parse_preview_scene, preview_scene_data
from atlasgen.render.meshes import make_material_ball, make_sphere


@pytest.fixture
def ball_file(tmp_path):
    return ball_mesh_file(make_material_ball(24), tmp_path)


def test_a_sphere_and_the_ball_rest_side_by_side_on_the_floor(ball_file):
    scene = parse_preview_scene(preview_scene_data("clay", "floor", ball_file))
    floor, sphere, ball = scene.objects
    assert (floor.shape, floor.material, sphere.shape, sphere.material, ball.shape, ball.material) == (
        "plane", "floor", "sphere", "clay", "mesh", "clay")  # fmt: skip
    assert ball.file == ball_file
    lowest = {"sphere": make_sphere(8).positions[:, 1].min(), "mesh": make_material_ball(24).positions[:, 1].min()}
    for obj in (sphere, ball):
        assert obj.translate[1] + obj.scale[1] * lowest[obj.shape] == pytest.approx(0.0, abs=1e-6)
    assert sphere.translate[0] < 0 < ball.translate[0]
    # A key light above and in front (the camera's side), a rim light from the right.
    key, rim = scene.lights
    assert key.type == "point" and key.position[1] > 2 and key.position[2] > 2
    assert rim.type == "directional" and rim.direction[0] < 0


def test_the_ball_is_lit_by_the_sky_which_is_also_its_background(ball_file):
    scene = parse_preview_scene(preview_scene_data("clay", "floor", ball_file))
    assert scene.environment is not None and scene.environment.source == "sky"
    assert scene.environment.intensity == ENVIRONMENT["intensity"] and not scene.background_given
    with pytest.raises(SceneError, match=r"objects\[2\]\.file"):
        parse_preview_scene(preview_scene_data("clay", "floor", ball_file.with_name("missing.ply")))


def test_the_balls_file_is_named_by_its_content_and_written_once(tmp_path):
    first = ball_mesh_file(make_material_ball(24), tmp_path)
    stamp = first.stat().st_mtime_ns
    assert ball_mesh_file(make_material_ball(24), tmp_path) == first and first.stat().st_mtime_ns == stamp
    other = ball_mesh_file(make_material_ball(32), tmp_path)
    assert other != first and other.parent == first.parent == tmp_path
    assert first.read_bytes().startswith(b"ply\n")


def test_a_damaged_ball_mesh_file_is_written_again(tmp_path):
    """A truncated cached PLY failed preview --reference on every run after (Mitsuba reads it), blamed on a scene the
    user never wrote: its bytes are the mesh's or it is written again."""
    path = ball_mesh_file(make_material_ball(24), tmp_path)
    whole = path.read_bytes()
    path.write_bytes(whole[:3000])
    assert ball_mesh_file(make_material_ball(24), tmp_path) == path and path.read_bytes() == whole
    path.unlink()
    path.mkdir()  # not a file at all: refused by the write, not taken as the mesh
    with pytest.raises(OutputError):
        ball_mesh_file(make_material_ball(24), tmp_path)


@pytest.mark.slow
def test_the_floor_shows_the_lights_in_the_scene_formats_units(gpu_device, ball_file, write_material):
    """Where the floor is seen, its radiance is a Lambertian's under the two lights and the sky (docs/scenes.md):
    L = albedo * colour / pi * (I cos / d^2 for the key + E cos for the rim + the sky's irradiance on N = +y),
    cos = N.L, the last by Funk-Hecke with the clamped cosine's closed-form lambda_l (docs/atlas-format.md)."""
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.io.package_data import package_data_path
    from atlasgen.materials.environment import environment_image
    from atlasgen.materials.material import read_material
    from atlasgen.optics.spherical_harmonics import evaluate_sh, project_equirect
    from atlasgen.preview.previewer import FLOOR_MATERIAL
    from atlasgen.render.atlas_texture import RenderAtlas
    from atlasgen.render.camera import pixel_rays
    from atlasgen.render.environment import IMAGE_HEIGHT
    from atlasgen.render.renderer import Renderer

    floor = read_material(package_data_path(*FLOOR_MATERIAL))
    clay = read_material(write_material("clay", 'type = "lambert"\n'))
    result = bake_atlas([clay, floor])
    renderer = Renderer(RenderAtlas(result.levels, True, result.manifest, result.include), gpu_device)
    renderer.add_mesh(ball_file, make_material_ball(24))
    scene = parse_preview_scene(preview_scene_data("clay", floor.name, ball_file))
    rendered = renderer.render(scene)
    on_floor = rendered.aov("id") == result.manifest.materials[[m.name for m in result.manifest.materials].index(floor.name)].id
    rays = pixel_rays(scene.camera, scene.width, scene.height)
    eye = np.asarray(scene.camera.position)
    points = eye + rays * (-eye[1] / rays[..., 1])[..., None]  # where each ray meets y = 0
    key, rim = scene.lights
    to_key = np.asarray(key.position) - points
    distance = np.linalg.norm(to_key, axis=-1)
    irradiance = (np.asarray(key.colour) * key.intensity * np.maximum(to_key[..., 1] / distance, 0)[..., None] / distance[..., None] ** 2
                  + np.asarray(rim.colour) * rim.intensity * max(-rim.direction[1], 0.0))  # fmt: skip
    sky = project_equirect(environment_image(scene.environment, IMAGE_HEIGHT, 2 * IMAGE_HEIGHT))
    clamped_cosine = np.array([np.pi, 2 * np.pi / 3, np.pi / 4, 0.0, -np.pi / 24])[:, None]
    irradiance = irradiance + evaluate_sh(sky, np.array([0.0, 1.0, 0.0]), zonal=clamped_cosine)
    expected = np.asarray(scene.objects[0].albedo) / np.pi * irradiance
    assert on_floor.mean() > 0.3
    np.testing.assert_allclose(rendered.radiance[on_floor], expected[on_floor], rtol=0.01)
