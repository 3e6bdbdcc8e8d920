"""The g-buffer's packed normal and depth: the octahedral map against its definition, and the GPU's
encoder (common.wgsl) against the NumPy decoder that reads the AOVs back."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.render.gbuffer import decode_normals, encode_normals

unit = st.tuples(*[st.floats(-1.0, 1.0, allow_nan=False)] * 3).filter(lambda v: np.linalg.norm(v) > 1e-3)


@settings(max_examples=300, deadline=None)
@given(unit)
def test_octahedral_normals_come_back_within_a_snorm16_step(v):
    n = np.asarray(v) / np.linalg.norm(v)
    back = decode_normals(encode_normals(n))
    # A snorm16 step is 2 / 65534 of the octahedron's side; the map stretches it at most ~2x on the sphere.
    assert np.arccos(np.clip(back @ n, -1.0, 1.0)) < 1.5e-4
    assert abs(np.linalg.norm(back) - 1.0) < 1e-12


def test_octahedral_words_follow_the_map():
    # The +z hemisphere is p = (x, y) / (|x| + |y| + |z|); below it the fold sends p to (1 - |p_y|, 1 - |p_x|) sign(p).
    n = np.array([0.6, 0.0, 0.8])
    assert encode_normals(n) == round(0.6 / 1.4 * 32767)
    n = np.array([0.6, 0.0, -0.8])  # p = (3/7, 0), folded to (1, 4/7)
    assert encode_normals(n) == 32767 | (round(4 / 7 * 32767) << 16)
    n = np.array([-0.6, -0.0, -0.8])  # sign(0) counts as +1: (-1, 4/7)
    assert encode_normals(n) == (-32767 & 0xFFFF) | (round(4 / 7 * 32767) << 16)


def _angles_from_the_sphere_s_normals(renderer, scene):
    """The covered pixels of a render of a sphere at the origin, and the angle of each pixel's normal, read
    back through decode_normals, from the sphere's exact normal at the pixel's surface point."""
    from atlasgen.render.camera import pixel_rays

    result = renderer.render(scene)
    on = result.aov("id") != 0xFFFF
    rays = pixel_rays(scene.camera, scene.width, scene.height)[on]
    points = np.asarray(scene.camera.position) + rays * result.aov("depth")[on][:, None]
    exact = points / np.linalg.norm(points, axis=-1, keepdims=True)
    return on, np.arccos(np.clip((result.aov("normal")[on] * exact).sum(-1), -1.0, 1.0))


@pytest.mark.gpu
def test_the_gpu_packs_the_normals_the_numpy_decoder_reads(renderer, scene_from):
    """Every covered pixel's normal, read back through decode_normals, against the sphere's exact
    normal at the pixel's surface point: an encoder that swapped or dropped a half would miss by far."""
    scene = scene_from(
        """
        [camera]
        position = [0.3, 0.8, 3.0]
        target = [0, 0, 0]
        fov = 50
        [image]
        width = 64
        height = 48
        [[lights]]
        type = "point"
        position = [1, 3, 3]
        intensity = 10
        [[objects]]
        shape = "sphere"
        material = "lambert"
        segments = 256
        """
    )
    on, angle = _angles_from_the_sphere_s_normals(renderer, scene)
    assert on.sum() > 300 and np.median(angle) < 2e-3 and angle.max() < 2e-2


@pytest.mark.gpu
@pytest.mark.parametrize("size", [1e11, 1e-11, 1e18, 1e-20])
def test_a_sphere_of_any_size_keeps_its_normals(renderer, scene_from, size):
    """The same view of a sphere scaled by 1e11 (and 1e-11), the camera with it: its normal matrix
    scales normals by 1/size, and the squared length of a 1e-11 normal (or of a face's 1e22
    cross product) passed float32's range, so every pixel got the fallback normal (0, 0, -1).
    At 1e18 and 1e-20 (a hostile sweep) the normals, 1/size long, fell below float32's normal range once the
    rasteriser's perspective interpolation multiplied them by 1/w: flat facets. The normal matrix is now
    divided by its largest entry."""
    s = repr(size)
    scene = scene_from(
        f"""
        [camera]
        position = [{0.3 * size!r}, {0.8 * size!r}, {3.0 * size!r}]
        target = [0, 0, 0]
        fov = 50
        near = {0.05 * size!r}
        far = {10.0 * size!r}
        [image]
        width = 64
        height = 48
        [[lights]]
        type = "directional"
        direction = [0, -1, -1]
        intensity = 2
        [[objects]]
        shape = "sphere"
        material = "lambert"
        segments = 256
        scale = {s}
        """
    )
    on, angle = _angles_from_the_sphere_s_normals(renderer, scene)
    assert on.sum() > 300 and np.median(angle) < 2e-3 and angle.max() < 2e-2


@pytest.mark.gpu
@pytest.mark.parametrize("size", [1.0, 6e17])
def test_a_floor_of_any_size_seen_from_above_faces_up(renderer, scene_from, size):
    """A hostile sweep's floor, 3.6e18 x 2.4e18 wide and scaled 6e17 in y, seen from above: every pixel had the
    normal (0, -1, 0), shaded as seen from behind; the same scene divided by 6e17 faced up."""
    scene = scene_from(f"""
        [camera]
        position = [0, {2.2 * size!r}, {7.0 * size!r}]
        target = [0, {0.2 * size!r}, 0]
        fov = 45
        near = {0.05 * size!r}
        far = {1000.0 * size!r}
        [image]
        width = 64
        height = 48
        [[lights]]
        type = "directional"
        direction = [0.5, -0.8, -0.35]
        intensity = 2
        [[objects]]
        shape = "plane"
        material = "lambert"
        translate = [0, {-size!r}, 0]
        scale = [{6.0 * size!r}, {size!r}, {4.0 * size!r}]
        """)  # fmt: skip
    result = renderer.render(scene)
    on = result.aov("id") != 0xFFFF
    assert on.sum() > 100 and np.allclose(result.aov("normal")[on], [0.0, 1.0, 0.0], atol=1e-3)
    assert renderer.ctx.take_errors() == []


@pytest.mark.gpu
def test_a_flattened_sphere_faces_along_its_flat_axis(renderer, scene_from):
    """A sphere scaled by [1, 1e-30, 1] is a disc facing +y: its normal matrix scales y by 1e30, whose
    square overflowed float32, and the disc's top went unlit under a light from above."""
    scene = scene_from(
        """
        [camera]
        position = [0, 5, 0.1]
        target = [0, 0, 0]
        [image]
        width = 48
        height = 48
        [[lights]]
        type = "directional"
        direction = [0, -1, 0]
        intensity = 2
        [[objects]]
        shape = "sphere"
        material = "lambert"
        scale = [1, 1e-30, 1]
        """
    )
    result = renderer.render(scene)
    on = result.aov("id") != 0xFFFF
    assert on.sum() > 300 and np.all(result.aov("normal")[on][:, 1] > 0.999)
