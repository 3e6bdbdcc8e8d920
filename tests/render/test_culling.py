"""Tiled light culling: lists read back against a CPU reference, culled frames against the full loop."""

from __future__ import annotations

import math

import numpy as np
import pytest

from atlasgen.render.culling import (
    TileLists,
    cull_tiles_reference,
    decode_tile_lists,
    lights_reaching,
    list_width,
    overflowing_tiles,
    pack_cull,
    tile_grid,
    tile_rectangle,
    tile_texture_size,
)
from atlasgen.render.layout import CULL, LIGHT, TILE_SIZE

#: Floor far behind, two opaque spheres, and (``{translucent}``) a glass sphere near the camera.
SCENE = """
[camera]
position = [0, 2.5, 7]
target = [0, 0, 0]
fov = 60
[image]
width = 160
height = 96
[[objects]]
shape = "plane"
material = "lambert"
translate = [0, -1, 0]
scale = 8
[[objects]]
shape = "sphere"
material = "glossy"
translate = [-1.5, 0, -1]
segments = 32
[[objects]]
shape = "sphere"
material = "plain"
translate = [1.8, 0, 0]
segments = 32
{translucent}
{lights}
"""

GLASS = """
[[objects]]
shape = "sphere"
material = "glossy"
translate = [0.2, 0.6, 4.2]
scale = 0.7
opacity = 0.5
segments = 32
[[objects]]
shape = "sphere"
material = "plain"
translate = [-0.3, -0.2, 2.0]
scale = 0.6
opacity = 0.4
segments = 32
"""


def scattered_lights(count: int, seed: int = 3, extra: str = "") -> str:
    """``count`` ranged point lights over the floor (ranges 0.6..2.2), a ranged spot, an unbounded
    point light and a directional one (neither is ever culled)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        p = rng.uniform([-6, -0.9, -6], [6, 2, 5]).tolist()
        out.append(f"[[lights]]\ntype = 'point'\nposition = [{p[0]!r}, {p[1]!r}, {p[2]!r}]\nintensity = 2.0\n"
                   f"range = {float(rng.uniform(0.6, 2.2))!r}\ncolour = [{float(rng.uniform(0.2, 1))!r}, 0.7, 0.5]")  # fmt: skip
    out.append("[[lights]]\ntype = 'spot'\nposition = [0, 3, 1]\ndirection = [0.1, -1, -0.3]\nintensity = 9\n"
               "inner_angle = 10\nouter_angle = 25\nrange = 5")  # fmt: skip
    out.append("[[lights]]\ntype = 'point'\nposition = [3, 4, 3]\nintensity = 1.5")
    out.append("[[lights]]\ntype = 'directional'\ndirection = [0.3, -1, -0.2]\nintensity = 0.2")
    return "\n".join(out) + extra


def edge_lights(scene, depth, count: int = 6) -> tuple[str, list]:
    """Lights at the right edges of tiles (1 + k, 2 + k // 2), for k < ``count``, and those tiles.

    Even k: a light that only just *touches* the tile: its centre lies outside the tile's right
    plane by (1 - 1e-4) of its range, so its sphere meets the frustum by 1e-4 of it (it reaches no
    pixel centre, which lie half a pixel inside). Odd k: a light that only just *reaches* it:
    0.4 across the edge from the surface point of the tile's last pixel column, with a range of
    1.02 x 0.4, so it lights a sliver of the tile's pixels and no light elsewhere covers for it.
    """
    from atlasgen.render.camera import camera_basis, pixel_rays, tangents

    rays = pixel_rays(scene.camera, scene.width, scene.height)
    right, up, forward = camera_basis(scene.camera)
    tan_x, _ = tangents(scene.camera, scene.width, scene.height)
    eye = np.asarray(scene.camera.position)
    out, tiles = [], []
    for k in range(count):
        tx, ty = 1 + k, 2 + k // 2
        x, y = TILE_SIZE * (tx + 1) - 1, TILE_SIZE * ty + 7  # the tile's last column, a middle row
        assert np.isfinite(depth[y, x])
        point = eye + rays[y, x] * depth[y, x]
        if k % 2 == 0:
            radius = 0.4
            a = ((x + 1) / scene.width * 2 - 1) * tan_x  # the right edge's slope x / z
            inward = (-right + a * forward) / np.hypot(1.0, a)
            offset = point - eye
            on_plane = eye + up * (offset @ up) + (offset @ forward) * (forward + a * right)
            centre = on_plane - inward * radius * (1 - 1e-4)
        else:
            radius = 0.4 * 1.02
            centre = point + right * 0.4
        c = centre.tolist()
        out.append(f"[[lights]]\ntype = 'point'\nposition = [{c[0]!r}, {c[1]!r}, {c[2]!r}]\nintensity = 50.0\nrange = {radius!r}")
        tiles.append((tx, ty))
    return "\n" + "\n".join(out) + "\n", tiles


def assert_frames_equal(culled, brute):
    """Within 1e-5 relative (per pixel, floored at 1e-5 of the frame's peak)."""
    floor = 1e-5 * np.abs(brute).max()
    err = np.abs(culled - brute) / np.maximum(np.abs(brute), floor)
    assert err.max() <= 1e-5, f"worst relative difference {err.max():.3g}"


def render_both(renderer, scene, **kw):
    culled = renderer.render(scene, outlines=False, **kw)
    brute = renderer.render(scene, outlines=False, aovs=False, **{**kw, "trace": False}, culling=False)
    return culled, brute


def test_tile_helpers():
    assert tile_grid(160, 96) == (10, 6)
    assert tile_rectangle((15, 16, 2, 17), 160, 96) == (0, 1, 2, 2)
    assert list(CULL.decode(pack_cull([(3, 4, 1, 2)])[: CULL.size])["origin"]) == [3, 4, 4, 6]
    assert len(pack_cull([(0, 0, 1, 1)] * 3)) == 3 * 256


def test_decoded_lists_keep_the_true_count_and_at_most_capacity_indices():
    # A 32 x 16 frame (two tiles) at capacity 3: a tile's row is 8 texels (1 + 2 x 3, up to a power of
    # two), the count first, then each entry copies its light's texels 0 and 1. Bytes 16..31 of a light
    # are radiant then its index (offset 28): texel 1, word 3.
    rows = np.arange(10 * 16, dtype=np.uint32).reshape(10, 4, 4) + 1000
    rows[:, 1, 3] = np.arange(10)
    texels = np.zeros((1, 2, 8, 4), dtype=np.uint32)
    texels[0, 0, 0, 0] = 2
    texels[0, 0, 1:5] = rows[[7, 9], :2].reshape(4, 4)
    texels[0, 1, 0, 0] = 5  # five lights, three held: an overflowed tile
    texels[0, 1, 1:7] = rows[[1, 2, 3], :2].reshape(6, 4)
    lists = decode_tile_lists(texels.tobytes(), 32, 16, 3)
    assert lists.counts.tolist() == [[2, 5]] and lists.lists == [[[7, 9], [1, 2, 3]]]
    assert lists.overflowed().tolist() == [[False, True]] and overflowing_tiles(lists) == 1


def test_tile_texture_rows_hold_a_list_or_every_light():
    assert list_width(255) == 512 and list_width(3) == 8 and list_width(0) == LIGHT.size // 16
    # 80 x 45 tiles, then one layer for every light: 1024 lights of 4 texels fill 8 rows of 512.
    assert tile_texture_size(1280, 720, 255, 1024) == (512, 80, 46)
    assert tile_texture_size(32, 16, 255, 1024) == (512, 8, 2)
    assert tile_texture_size(32, 16, 0, 3, culled=False) == (4, 3, 1)


def test_culled_frame_equals_the_brute_force_frame(renderer, scene_from):
    probe = scene_from(SCENE.format(translucent="", lights=scattered_lights(60)))
    depth = renderer.render(probe, outlines=False).aov("depth")
    extra, tiles = edge_lights(probe, depth)
    scene = scene_from(SCENE.format(translucent="", lights=scattered_lights(60) + extra))
    culled, brute = render_both(renderer, scene)
    assert culled.tile_lists is not None and brute.tile_lists is None
    assert_frames_equal(culled.radiance, brute.radiance)
    reference = cull_tiles_reference(scene, culled.aov("depth"))
    first = len(scene.lights) - len(tiles)
    for k, (tx, ty) in enumerate(tiles):
        # The edge lights are listed for the tile they only just meet (and the reference agrees).
        assert first + k in reference[(tx, ty)] and first + k in culled.tile_lists.lists[ty][tx], k
    # The culling did cull: most tiles list a small share of the lights.
    assert np.median(culled.tile_lists.counts) < 0.3 * len(scene.lights)


def test_tile_lists_hold_every_light_that_reaches_the_tile(renderer, scene_from):
    scene = scene_from(SCENE.format(translucent="", lights=scattered_lights(60)))
    result = renderer.render(scene, outlines=False)
    lists, depth = result.tile_lists, result.aov("depth")
    exact = cull_tiles_reference(scene, depth)
    loose = cull_tiles_reference(scene, depth, slack=1.002)  # the shader's slack is 1.001
    unbounded = {len(scene.lights) - 2, len(scene.lights) - 1}
    for (tx, ty), expected in exact.items():
        got = set(lists.lists[ty][tx])
        assert lists.counts[ty, tx] == len(got)
        assert expected <= got <= loose[(tx, ty)], (tx, ty, expected ^ got)
        if np.isfinite(depth[ty * TILE_SIZE : (ty + 1) * TILE_SIZE, tx * TILE_SIZE : (tx + 1) * TILE_SIZE]).any():
            assert unbounded <= got  # an unbounded point light and a directional light are never culled
        else:
            assert not got  # nothing drawn: no light
    # Per pixel: the lights reaching each surface point are all in its tile's list.
    np.testing.assert_array_equal(lights_reaching(scene, depth, lists), lights_reaching(scene, depth))


def test_translucent_layers_are_lit_with_lists_for_their_own_depths(renderer, scene_from):
    # A short-range light beside the nearest glass sphere only: it reaches no opaque surface.
    near = "\n[[lights]]\ntype = 'point'\nposition = [0.2, 0.6, 5.1]\nintensity = 3.0\nrange = 0.5\n"
    scene = scene_from(SCENE.format(translucent=GLASS, lights=scattered_lights(40, extra=near)))
    culled, brute = render_both(renderer, scene, trace=True)
    assert_frames_equal(culled.radiance, brute.radiance)
    assert len(culled.steps) == 2
    near_index = len(scene.lights) - 1
    opaque = cull_tiles_reference(scene, culled.opaque_depth)
    assert all(near_index not in s for s in opaque.values())
    frame = renderer.prepare(scene)
    held = []
    for n, step in enumerate(culled.steps):
        tiles = frame.cull_tiles[1 + n]
        reference = cull_tiles_reference(scene, step.depth, tiles=tiles)
        loose = cull_tiles_reference(scene, step.depth, slack=1.002, tiles=tiles)
        for (tx, ty), expected in reference.items():
            assert expected <= set(step.tile_lists.lists[ty][tx]) <= loose[(tx, ty)], (n, tx, ty)
        held.append(any(near_index in step.tile_lists.lists[ty][tx] for (tx, ty) in reference))
    # The nearest glass (drawn last) is lit by the light beside it: the opaque layer's lists lack it.
    assert held[-1]


def test_a_full_tile_falls_back_to_the_full_loop(renderer, scene_from):
    scene = scene_from(SCENE.format(translucent=GLASS, lights=scattered_lights(60)))
    capacity = renderer.tile_capacity
    renderer.tile_capacity = 4
    try:
        culled, brute = render_both(renderer, scene)
    finally:
        renderer.tile_capacity = capacity
    lists = culled.tile_lists
    assert isinstance(lists, TileLists) and lists.capacity == 4
    assert overflowing_tiles(lists) > 10  # many tiles hold more than 4 lights ...
    exact = cull_tiles_reference(scene, culled.aov("depth"))
    loose = cull_tiles_reference(scene, culled.aov("depth"), slack=1.002)
    for (tx, ty), expected in exact.items():  # ... their count is the true one, their list the first 4
        assert len(expected) <= lists.counts[ty, tx] <= len(loose[(tx, ty)])
        assert len(lists.lists[ty][tx]) == min(lists.counts[ty, tx], 4)
    assert_frames_equal(culled.radiance, brute.radiance)  # ... and they are lit by every light, not 4


def test_a_frame_whose_lists_would_pass_the_budget_holds_fewer_lights_a_tile(renderer, scene_from, monkeypatch):
    """8192 x 8192 with a ranged light asked 2.1 GB of tile lists, an internal error: a frame past the budget gets
    shorter lists, its fuller tiles lit by the full loop, and the same image."""
    from atlasgen.render import culling

    scene = scene_from(SCENE.format(translucent=GLASS, lights=scattered_lights(60)))
    bytes_at = lambda c: 16 * math.prod(culling.tile_texture_size(scene.width, scene.height, c, len(scene.lights)))  # noqa: E731
    monkeypatch.setattr(culling, "TILE_TEXTURE_BUDGET", bytes_at(7))
    culled, brute = render_both(renderer, scene)
    lists = culled.tile_lists
    assert lists.capacity == 7 and bytes_at(15) > culling.TILE_TEXTURE_BUDGET  # rows of 16 texels, not 32
    assert overflowing_tiles(lists) > 10
    assert_frames_equal(culled.radiance, brute.radiance)


def test_a_scene_without_ranges_is_not_culled(renderer, scene_from):
    scene = scene_from(SCENE.format(translucent="", lights="[[lights]]\ntype = 'point'\nposition = [0, 3, 1]\nintensity = 4"))
    frame = renderer.prepare(scene)
    assert not frame.culled and [s[0] for s in renderer.frame_steps(frame, outlines=False)] == ["gbuffer", "lighting"]
    assert renderer.render(scene, outlines=False).tile_lists is None


@pytest.mark.parametrize("translucent", [False, True])
def test_every_pass_is_timed(renderer, scene_from, translucent):
    from atlasgen.render.timing import has_timestamps, time_passes

    scene = scene_from(SCENE.format(translucent=GLASS if translucent else "", lights=scattered_lights(20)))
    frame = renderer.prepare(scene)
    expected = {"gbuffer", "culling", "lighting"} | ({"translucency"} if translucent else set())
    methods = ["fences"] + (["timestamps"] if has_timestamps(renderer.device) else [])
    for method in methods:
        times, used = time_passes(renderer, frame, outlines=False, method=method)
        assert used == method and set(times) == expected
        assert all(0 < t < 10_000 for t in times.values()), times


def test_doctests():
    import doctest

    from atlasgen.render import culling

    assert doctest.testmod(culling).failed == 0
