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


def test_the_far_plane_lies_below_the_depth_buffer_s_clear_value():
    """Depth 0 at near and 1 - DEPTH_HEADROOM at far, in closed form: every point in front of the far plane stays
    below 1, which a 24-bit depth buffer must tell from its clear value."""
    from atlasgen.render.camera import DEPTH_HEADROOM

    cam = Camera((0, 0, 0), (0, 0, -1), fov=60.0, near=1e-4, far=1000.0)
    p = projection_matrix(cam, 16, 16)
    depth = [(p @ [0, 0, -z, 1])[2] / (p @ [0, 0, -z, 1])[3] for z in (1e-4, 900.0, 1000.0)]
    assert depth[0] == pytest.approx(0.0, abs=1e-12)
    assert depth[2] == pytest.approx(1.0 - DEPTH_HEADROOM, abs=1e-12)
    assert round(depth[1] * (2**24 - 1)) <= 2**24 - 1 - 8  # 8 steps of 24 bits below 1, 900 away


@pytest.mark.gpu
@pytest.mark.parametrize("distance", [900.0, 3e20])
def test_a_sphere_near_the_far_plane_of_a_small_near_is_drawn_whole(renderer, scene_from, distance):
    """A sphere 900 away, near 1e-4 and far 1000 (a ratio scenes allow), lost 73% of its pixels: their depth
    rounded to the clear value 1 and failed the "less" test. The same view with near 0.05 (the same x and y
    projection) covers the pixels it must."""

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
    np.testing.assert_array_equal(covered(1e-4), whole)
