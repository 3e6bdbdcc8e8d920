"""Deferred translucency: sorting, z-writes, stencil masking and blending (Meshkin's talk, sec. 2)."""

from __future__ import annotations

import numpy as np

from atlasgen.materials.scene import SceneObject
from atlasgen.render.camera import Camera
from atlasgen.render.translucency import sort_back_to_front

HEADER = """
[camera]
position = [0.0, 0.5, 5.0]
target = [0, 0, 0]
fov = 50
[image]
width = 64
height = 48
background = [0.05, 0.05, 0.08]
[render]
mip_distance = 100.0
[[lights]]
type = "point"
position = [2.0, 3.0, 4.0]
intensity = 12.0
[[lights]]
type = "directional"
direction = [-0.3, -0.5, -1.0]
colour = [0.6, 0.7, 1.0]
intensity = 1.0
"""

BACKDROP = """
[[objects]]
shape = "plane"
material = "lambert"
rotate = [90, 0, 0]
translate = [0, 0, -1.5]
scale = 3
albedo = [0.9, 0.9, 0.9]
"""

GLASS = [
    """
[[objects]]
shape = "sphere"
material = "glossy"
translate = [-0.5, 0.0, 0.0]
scale = 0.8
opacity = 0.5
albedo = [0.2, 0.6, 1.0]
""",
    """
[[objects]]
shape = "box"
material = "plain"
translate = [0.4, 0.1, 0.8]
scale = 0.45
rotate = [20, 30, 0]
opacity = 0.35
albedo = [1.0, 0.3, 0.2]
""",
    """
[[objects]]
shape = "torus"
material = "glossy"
translate = [0.2, -0.3, 1.5]
rotate = [70, 0, 0]
scale = 0.5
opacity = 0.7
""",
]


def test_image_does_not_depend_on_listing_order(renderer, scene_from):
    forward = scene_from(HEADER + BACKDROP + "".join(GLASS))
    backward = scene_from(HEADER + "".join(reversed(GLASS)) + BACKDROP)
    shuffled = scene_from(HEADER + GLASS[1] + BACKDROP + GLASS[2] + GLASS[0])
    a = renderer.render(forward).radiance
    b = renderer.render(backward).radiance
    c = renderer.render(shuffled).radiance
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, c)
    # ...and the translucent objects do change it.
    opaque_only = renderer.render(scene_from(HEADER + BACKDROP)).radiance
    assert np.abs(a - opaque_only).max() > 0.05


def test_opaque_object_in_front_hides_translucent_one(renderer, scene_from):
    blocker = """
[[objects]]
shape = "sphere"
material = "plain"
translate = [-0.4, 0.0, 2.2]
scale = 0.5
"""
    with_glass = renderer.render(scene_from(HEADER + BACKDROP + GLASS[0] + blocker))
    without = renderer.render(scene_from(HEADER + BACKDROP + blocker))
    hidden = with_glass.aov("id") == 4  # the blocker's "plain" slice wins the depth test
    assert hidden.sum() > 50
    np.testing.assert_array_equal(with_glass.radiance[hidden], without.radiance[hidden])
    # Elsewhere the glass sphere is visible.
    assert np.abs(with_glass.radiance - without.radiance)[~hidden].max() > 0.05


def test_lighting_is_confined_to_stencil_marked_pixels(renderer, scene_from):
    scene = scene_from(HEADER + BACKDROP + "".join(GLASS))
    result = renderer.render(scene, trace=True, outlines=False)
    assert [s.object_index for s in result.steps] == result.draw_order[1:]
    before = result.opaque_radiance
    for step in result.steps:
        changed = np.any(step.radiance != before, axis=-1)
        assert step.stencil.sum() > 20
        assert not (changed & ~step.stencil).any(), "a pixel outside the stencil mask was lit"
        assert changed[step.stencil].mean() > 0.9
        before = step.radiance
    np.testing.assert_array_equal(before, result.radiance)


def test_blend_uses_opacity_and_nearest_surface(renderer, scene_from):
    # frame = opacity * lit + (1 - opacity) * behind, where lit is the object rendered opaque.
    glass = GLASS[0]
    solid = glass.replace("opacity = 0.5", "opacity = 1.0")
    blended = renderer.render(scene_from(HEADER + BACKDROP + glass), trace=True, outlines=False)
    opaque = renderer.render(scene_from(HEADER + BACKDROP + solid), outlines=False)
    mask = blended.steps[0].stencil
    expected = 0.5 * opaque.radiance + 0.5 * blended.opaque_radiance
    np.testing.assert_allclose(blended.radiance[mask], expected[mask], rtol=2e-3, atol=2e-3)
    # The g-buffer keeps only the nearest surface of the sphere: its depth there is the
    # front intersection, identical to the opaque sphere's.
    np.testing.assert_array_equal(blended.aov("depth")[mask], opaque.aov("depth")[mask])


def test_sort_back_to_front_ignores_listing_order():
    camera = Camera((0.0, 0.0, 10.0), (0.0, 0.0, 0.0))
    objs = [SceneObject(i, "sphere", "m", translate=(0.0, 0.0, z), opacity=op) for i, (z, op) in
            enumerate([(0.0, 0.5), (3.0, 0.5), (-2.0, 1.0), (-4.0, 0.2), (3.0, 0.4)])]  # fmt: skip
    centres = [o.translate for o in objs]
    order = sort_back_to_front(objs, centres, camera)
    assert 2 not in order  # opaque
    assert order[:2] == [3, 0]
    assert set(order[2:]) == {1, 4}
    reversed_order = sort_back_to_front(objs[::-1], centres[::-1], camera)
    assert [objs[::-1][i].translate + (objs[::-1][i].opacity,) for i in reversed_order] == [
        objs[i].translate + (objs[i].opacity,) for i in order
    ]


def test_screen_rectangle_covers_the_projected_box():
    from atlasgen.render.camera import camera_basis, projection_matrix, view_matrix
    from atlasgen.render.translucency import screen_rectangle

    camera = Camera((1.0, 2.0, 6.0), (0.0, 0.0, 0.0), fov=60.0)
    vp = projection_matrix(camera, 64, 48) @ view_matrix(camera)
    rng = np.random.default_rng(3)
    lo, hi = np.array([-0.5, -0.2, -0.4]), np.array([0.7, 0.6, 0.3])
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    x, y, w, h = screen_rectangle(corners, vp, 64, 48)
    inside = lo + rng.random((500, 3)) * (hi - lo)
    clip = np.c_[inside, np.ones(500)] @ vp.T
    px = (clip[:, 0] / clip[:, 3] + 1) / 2 * 64
    py = (1 - clip[:, 1] / clip[:, 3]) / 2 * 48
    assert (px >= x).all() and (px <= x + w).all() and (py >= y).all() and (py <= y + h).all()
    assert w < 64 and h < 48  # a real reduction
    assert screen_rectangle(corners + [0, 0, 20], vp, 64, 48) == (0, 0, 64, 48)  # behind the camera
    right = camera_basis(camera)[0]
    assert screen_rectangle(corners + 30 * right, vp, 64, 48) is None  # off to the side, in front
