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
