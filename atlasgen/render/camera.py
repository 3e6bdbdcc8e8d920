"""The pinhole camera: look-at frame, view and WebGPU projection matrices.

Conventions match Mitsuba 3's ``perspective`` sensor with ``fov_axis = "x"``: the
field of view is horizontal, the frame is built by ``look_at(origin, target, up)``,
image x runs along ``right = forward x up`` and image y runs along ``-up``, and a
pixel's ray passes through its centre.
"""

from __future__ import annotations

import math

import numpy as np

from atlasgen.materials.scene import Camera

__all__ = ["DEPTH_HEADROOM", "FAR_PLANE_DEPTH", "Camera", "camera_basis", "view_matrix", "projection_matrix", "pixel_rays"]


def camera_basis(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orthonormal ``(right, up, forward)`` of the look-at frame."""
    eye = np.asarray(camera.position, dtype=np.float64)
    forward = np.asarray(camera.target, dtype=np.float64) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.asarray(camera.up, dtype=np.float64))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    return right, up, forward


def view_matrix(camera: Camera) -> np.ndarray:
    """World to view space; the view space looks down -z (right-handed, y up)."""
    right, up, forward = camera_basis(camera)
    eye = np.asarray(camera.position, dtype=np.float64)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = right, up, -forward
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def tangents(camera: Camera, width: int, height: int) -> tuple[float, float]:
    """``tan`` of the horizontal and vertical half-angles."""
    tan_x = math.tan(math.radians(camera.fov) * 0.5)
    return tan_x, tan_x * height / width


#: How far below 1, the depth buffer's clear value, the far plane's depth lies: 8 steps of a 24-bit depth buffer.
#: A point's depth is about 1 - near / distance, which float32 and 24 bits round to exactly 1 far from a camera with a
#: small near: it then failed the g-buffer's "less" test against the clear value and drew nothing (a sphere 900 away
#: with near 1e-4 and far 1000, a ratio scenes allow, lost 73% of its pixels). With the headroom every point in front
#: of the far plane has a depth below 1 and is drawn (nearby ones may tie, as any depth buffer's would).
DEPTH_HEADROOM = 2.0**-21
#: The far plane's depth, which the g-buffer's depth is cleared to: what lies at or beyond it fails the "less" test.
FAR_PLANE_DEPTH = 1.0 - DEPTH_HEADROOM


def projection_matrix(camera: Camera, width: int, height: int) -> np.ndarray:
    """View to clip space for WebGPU: NDC depth in [0, 1), y up.

    x_ndc = x / (-z tan_x), y_ndc = y / (-z tan_y) and depth
    d = (1 - h) (f z + n f) / ((n - f) (-z)), which is 0 at z = -near and 1 - h at z = -far
    (h = :data:`DEPTH_HEADROOM`).
    """
    tan_x, tan_y = tangents(camera, width, height)
    n, f = camera.near, camera.far
    p = np.zeros((4, 4))
    p[0, 0] = 1.0 / tan_x
    p[1, 1] = 1.0 / tan_y
    p[2, 2] = (1.0 - DEPTH_HEADROOM) * f / (n - f)
    p[2, 3] = (1.0 - DEPTH_HEADROOM) * n * f / (n - f)
    p[3, 2] = -1.0
    return p


def pixel_rays(camera: Camera, width: int, height: int) -> np.ndarray:
    """Un-normalised ray directions through pixel centres, ``(height, width, 3)``.

    Each ray has unit component along ``forward``, so ``position + ray * depth`` is the
    point at view depth ``depth`` (what the g-buffer stores).
    """
    right, up, forward = camera_basis(camera)
    tan_x, tan_y = tangents(camera, width, height)
    sx = ((np.arange(width) + 0.5) / width * 2.0 - 1.0) * tan_x
    sy = (1.0 - (np.arange(height) + 0.5) / height * 2.0) * tan_y
    return forward + sx[None, :, None] * right + sy[:, None, None] * up
