"""Toon outlines from g-buffer depth and normal discontinuities, for flagged materials only."""

from __future__ import annotations

import numpy as np
import pytest

SCENE = """
[camera]
position = [0, 0, 4]
target = [0, 0, 0]
fov = 40
[image]
width = 80
height = 64
[render]
mip_distance = 100.0
outline_colour = [0.0, 100.0, 0.0]
[[lights]]
type = "directional"
direction = [0.3, -0.4, -1]
intensity = 3.0
[[objects]]
shape = "{shape}"
material = "{material}"
segments = 128
rotate = [30, 40, 0]
"""


def outline_pixels(result):
    # The outline colour (green 100) cannot come out of the lighting of this scene.
    return result.radiance[..., 1] > 50.0


def distance_to_silhouette(covered: np.ndarray) -> np.ndarray:
    """City-block distance of each covered pixel to the nearest empty pixel (4-neighbour steps)."""
    from scipy.ndimage import distance_transform_cdt

    return distance_transform_cdt(covered, metric="taxicab")


def test_outline_follows_sphere_silhouette_and_nothing_inside(renderer, scene_from):
    result = renderer.render(scene_from(SCENE.format(shape="sphere", material="toon")))
    covered = result.aov("id") != 0xFFFF
    outline = outline_pixels(result)
    dist = distance_to_silhouette(covered)
    silhouette = covered & (dist == 1)
    assert outline[silhouette].mean() > 0.95
    assert not (outline & (dist > 2)).any(), "outline pixels inside the smooth sphere"
    # Empty pixels touching the sphere are outlined too; empty pixels farther away are not.
    outside = distance_to_silhouette(~covered)
    assert not (outline & ~covered & (outside > 1)).any()


def test_outline_marks_box_creases(renderer, scene_from):
    result = renderer.render(scene_from(SCENE.format(shape="box", material="toon").replace("segments = 128\n", "")))
    covered = result.aov("id") != 0xFFFF
    outline = outline_pixels(result)
    dist = distance_to_silhouette(covered)
    # Some interior pixels (the crease between two visible faces) are outlined.
    assert (outline & (dist > 3)).any()


@pytest.mark.parametrize("material", ["lambert", "glossy"])
def test_no_outline_for_materials_that_do_not_ask(renderer, scene_from, material):
    result = renderer.render(scene_from(SCENE.format(shape="sphere", material=material)))
    assert not outline_pixels(result).any()


def test_outlines_can_be_switched_off(renderer, scene_from):
    result = renderer.render(scene_from(SCENE.format(shape="sphere", material="toon")), outlines=False)
    assert not outline_pixels(result).any()


#: SCENE's camera and light over a toon sphere partly off screen, a toon box and a lambert sphere.
TWO_OUTLINED = (
    SCENE[: SCENE.index("[[objects]]")]
    + """
[[objects]]
shape = "sphere"
material = "toon"
translate = [-1.9, 0.2, 0]
scale = 0.6
[[objects]]
shape = "box"
material = "toon"
translate = [0.9, -0.4, 0.3]
rotate = [30, 40, 0]
scale = 0.4
[[objects]]
shape = "sphere"
material = "lambert"
translate = [0.1, 0.5, -0.4]
scale = 0.5
"""
)


def test_outlines_drawn_over_the_flagged_objects_rectangles_equal_the_full_screen_pass(renderer, scene_from, monkeypatch):
    """The pass is scissored to the outlined objects' screen rectangles (one partly off screen,
    one touching an unflagged object): the frame is the full-screen pass's, bit for bit."""
    from atlasgen.render.outline import OutlinePass

    scene = scene_from(TWO_OUTLINED)
    rectangles = renderer.prepare(scene).outline_rectangles
    assert len(rectangles) == 2
    assert sum(w * h for _, _, w, h in rectangles) < 0.5 * scene.width * scene.height  # the scissor does cut
    scissored = renderer.render(scene)
    full_screen = OutlinePass.encode
    monkeypatch.setattr(OutlinePass, "encode", lambda self, enc, target, group, rectangles=None, timestamps=None:
                        full_screen(self, enc, target, group, None, timestamps))  # fmt: skip
    whole = renderer.render(scene)
    assert outline_pixels(whole).sum() > 50
    np.testing.assert_array_equal(scissored.radiance, whole.radiance)


def test_an_invisible_toon_object_leaves_no_outline(renderer, scene_from):
    """opacity = 0 rendered nothing of the sphere but a full ring of outline where its silhouette would be."""
    base = SCENE.format(shape="plane", material="lambert").replace("segments = 128\nrotate = [30, 40, 0]",
                                                                   "translate = [0, -1, 0]\nscale = 4")  # fmt: skip
    hidden = base + "[[objects]]\nshape = 'sphere'\nmaterial = 'toon'\nopacity = 0.0\n"
    without, invisible = renderer.render(scene_from(base)), renderer.render(scene_from(hidden))
    np.testing.assert_array_equal(invisible.radiance, without.radiance)
    np.testing.assert_array_equal(invisible.aov("id"), without.aov("id"))
