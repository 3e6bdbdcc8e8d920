"""Camera matrices agree with the per-pixel rays the lighting pass rebuilds positions from."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.render.camera import Camera, camera_basis, pixel_rays, projection_matrix, view_matrix

coords = st.floats(-5, 5)


@settings(max_examples=40, deadline=None)
@given(
    eye=st.tuples(coords, coords, coords).map(np.array),
    target=st.tuples(coords, coords, coords).map(np.array),
    fov=st.floats(10, 120),
    width=st.integers(4, 64),
    height=st.integers(4, 64),
)
def test_projecting_a_pixel_ray_lands_on_its_pixel_centre(eye, target, fov, width, height):
    if np.linalg.norm(target - eye) < 0.5 or np.linalg.norm(np.cross(target - eye, [0, 1, 0])) < 0.1:
        return
    cam = Camera(tuple(eye), tuple(target), fov=fov, near=0.1, far=100.0)
    rays = pixel_rays(cam, width, height)
    depth = 3.0
    points = eye + rays * depth
    clip = (projection_matrix(cam, width, height) @ view_matrix(cam) @ np.c_[points.reshape(-1, 3), np.ones(width * height)].T).T
    ndc = clip[:, :3] / clip[:, 3:]
    px = (ndc[:, 0] + 1) / 2 * width
    py = (1 - ndc[:, 1]) / 2 * height  # framebuffer y runs down
    ys, xs = np.mgrid[0:height, 0:width]
    np.testing.assert_allclose(px, xs.ravel() + 0.5, atol=1e-6)
    np.testing.assert_allclose(py, ys.ravel() + 0.5, atol=1e-6)
    # Depth is in [0, 1] and the view depth along forward is what was asked for.
    assert ((ndc[:, 2] > 0) & (ndc[:, 2] < 1)).all()
    _, _, forward = camera_basis(cam)
    np.testing.assert_allclose((points - eye) @ forward, depth, rtol=1e-9)


def test_horizontal_field_of_view():
    cam = Camera((0, 0, 0), (0, 0, -1), fov=90.0)
    rays = pixel_rays(cam, 100, 50)
    # Edge pixels' centres are half a pixel inside tan(45 deg) = 1 horizontally.
    assert rays[0, -1, 0] == pytest.approx(1 - 1 / 100, abs=1e-12)
    assert rays[0, 0, 1] == pytest.approx(0.5 - 0.5 / 50, abs=1e-12)  # top row looks up
    right, up, forward = camera_basis(cam)
    np.testing.assert_allclose([right, up, forward], [[1, 0, 0], [0, 1, 0], [0, 0, -1]], atol=1e-12)


def test_the_far_plane_lies_at_the_depth_buffer_s_clear_value():
    """Depth 0 at near and FAR_PLANE_DEPTH (1 - DEPTH_HEADROOM, the g-buffer's clear value) at far, in closed form:
    at the widest far / near allowed, a point 10% in front of the far plane stays steps of 24 bits below it."""
    from atlasgen.materials.scene import MAX_FAR_OVER_NEAR
    from atlasgen.render.camera import DEPTH_HEADROOM, FAR_PLANE_DEPTH

    cam = Camera((0, 0, 0), (0, 0, -1), fov=60.0, near=1000.0 / MAX_FAR_OVER_NEAR, far=1000.0)
    p = projection_matrix(cam, 16, 16)
    depth = [(p @ [0, 0, -z, 1])[2] / (p @ [0, 0, -z, 1])[3] for z in (cam.near, 900.0, 1000.0)]
    assert depth[0] == pytest.approx(0.0, abs=1e-12)
    assert depth[2] == pytest.approx(FAR_PLANE_DEPTH, abs=1e-12) and FAR_PLANE_DEPTH == 1.0 - DEPTH_HEADROOM
    assert round(depth[1] * (2**24 - 1)) <= round(FAR_PLANE_DEPTH * (2**24 - 1)) - 8  # 8 steps below, 900 away


@pytest.mark.gpu
@pytest.mark.parametrize("distance", [900.0, 3e20])
def test_a_sphere_near_the_far_plane_of_a_small_near_is_drawn_whole(renderer, scene_from, distance):
    """A sphere 900 away, near 1e-4 and far 1000 (a ratio scenes allowed then), lost 73% of its pixels: their depth
    rounded to the clear value 1 and failed the "less" test. At the widest ratio allowed now (near 1e-2), the view
    covers the pixels the same one with near 0.05 (the same x and y projection) does."""

    def covered(near):
        s = distance / 900.0
        scene = scene_from(f"""
            [camera]
            position = [0, 0, {distance}]
            target = [0, 0, 0]
            near = {near * s}
            far = {1000.0 * s}
            [image]
            width = 80
            height = 60
            [[lights]]
            type = "directional"
            direction = [0.3, -0.5, -1]
            intensity = 3.0
            [[objects]]
            shape = "sphere"
            material = "lambert"
            scale = {150.0 * s}
            """)  # fmt: skip
        return renderer.render(scene).aov("id") != 0xFFFF

    whole = covered(0.05)
    assert whole.sum() > 900
    np.testing.assert_array_equal(covered(1e-2), whole)


def _spheres_ahead(scene_from, far: float, width: int, objects: str):
    """A scene looking down -z from 10 away at ``objects`` (TOML), lit head-on, near = far / 100 (set per test)."""
    return scene_from(f"""
        [camera]
        position = [0, 0, 10]
        target = [0, 0, 0]
        near = {far / 100.0}
        far = {far}
        [image]
        width = {width}
        height = {width * 3 // 4}
        [[lights]]
        type = "directional"
        direction = [0, 0, -1]
        intensity = 1.0
        """ + objects)  # fmt: skip


def _ids_at(renderer, scene, ratio: float):
    """The id AOV of ``scene`` with near = far / ``ratio``, set on the camera directly (past the parser's limit too)."""
    import dataclasses

    camera = dataclasses.replace(scene.camera, near=scene.camera.far / ratio)
    return renderer.render(dataclasses.replace(scene, camera=camera)).aov("id")


@pytest.mark.gpu
def test_an_object_beyond_the_far_plane_is_not_drawn_at_the_widest_depth_range(renderer, scene_from):
    """The finding: with the depth cleared to 1, a sphere 1% beyond the far plane was drawn at far / near = 1e5
    (its depth fell between the far plane's, 1 - DEPTH_HEADROOM, and 1), and from 2e6 on all of a scene beyond it.
    Cleared to the far plane's depth, it is not; moved in front of the far plane, the same sphere is drawn."""

    def covered(far, ratio):
        scene = _spheres_ahead(scene_from, far, 40, '[[objects]]\nshape = "sphere"\nmaterial = "lambert"\n')
        return int((_ids_at(renderer, scene, ratio) != 0xFFFF).sum())

    assert covered(8.9, 1e5) == 0 and covered(8.9, 100.0) == 0  # its nearest point is 9 away
    assert covered(11.0, 1e5) > 50 and covered(11.0, 1e5) == covered(11.0, 100.0)
    assert renderer.ctx.take_errors() == []


@pytest.mark.gpu
def test_a_depth_range_wider_than_the_scenes_allow_shows_the_wrong_object(renderer, scene_from):
    """Why MAX_FAR_OVER_NEAR is 1e5 (docs/scenes.md): two spheres crossing 10 away, rendered at far / near = 400, 1e5
    and 1e7 (past the parser's limit, its camera set directly). Against the first, 1e5 differs at most where the two
    surfaces meet (a pixel or two); 1e7 shows the wrong sphere over a fifth of their pixels."""
    from atlasgen.materials.scene import MAX_FAR_OVER_NEAR

    scene = _spheres_ahead(scene_from, 20.0, 64, """
        [[objects]]
        shape = "sphere"
        material = "lambert"
        translate = [0, 0, -0.3]
        [[objects]]
        shape = "sphere"
        material = "toon"
        translate = [0.5, 0, 0]
        """)  # fmt: skip
    reference = _ids_at(renderer, scene, 400.0)
    covered = int((reference != 0xFFFF).sum())
    assert MAX_FAR_OVER_NEAR == 1e5 and covered > 200 and len(np.unique(reference)) == 3
    assert int((_ids_at(renderer, scene, 1e5) != reference).sum()) <= 2
    assert int((_ids_at(renderer, scene, 1e7) != reference).sum()) > 0.2 * covered
    assert renderer.ctx.take_errors() == []
