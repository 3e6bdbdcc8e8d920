"""The deferred lighting pass against an independent numpy evaluation of its equation."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.materials.scene import Light
from atlasgen.optics.srgb import decode_srgb
from atlasgen.render.camera import pixel_rays
from atlasgen.render.lighting import pack_lights
from tests.render.atlas_fixture import MIP_GREYS, MIPS, decoded_slice, interior, reference_radiance

SPHERE = """
[camera]
position = [0.3, 0.4, 3.5]
target = [0, 0, 0]
fov = 45
[image]
width = 64
height = 48
background = [0.02, 0.03, 0.04]
[render]
mip_distance = 100.0
{lights}
[[objects]]
shape = "sphere"
material = "{material}"
albedo = [0.7, 0.5, 0.9]
gloss = {gloss}
segments = 96
"""

LIGHTS = """
[[lights]]
type = "point"
position = [2.0, 2.0, 2.0]
colour = [1.0, 0.8, 0.6]
intensity = 6.0
[[lights]]
type = "point"
position = [-2.5, 0.5, 1.0]
colour = [0.3, 0.6, 1.0]
intensity = 4.0
[[lights]]
type = "point"
position = [0.0, -2.0, 2.5]
intensity = 3.0
[[lights]]
type = "directional"
direction = [0.5, -0.3, -1.0]
colour = [1.0, 1.0, 0.9]
intensity = 1.5
"""


def relative_error(got, ref):
    floor = 1e-3 * np.abs(ref).max()
    return np.abs(got - ref) / np.maximum(np.abs(ref), floor)


@pytest.mark.parametrize("material, gloss", [("glossy", 0.3), ("glossy", 0.6), ("plain", 0.5)])
def test_shading_equation_matches_numpy(renderer, fixture_atlas, scene_from, material, gloss):
    scene = scene_from(SPHERE.format(lights=LIGHTS, material=material, gloss=gloss))
    result = renderer.render(scene, outlines=False)
    rays = pixel_rays(scene.camera, scene.width, scene.height)
    ref = reference_radiance(fixture_atlas, scene, result.aovs, rays)
    inside = interior(result.aov("id"))
    assert inside.sum() > 0.3 * inside.size
    err = relative_error(result.radiance[inside], ref[inside])
    assert err.max() < 1e-2, f"worst relative error {err.max():.4f}"
    background = result.aov("id") == 0xFFFF
    assert np.allclose(result.radiance[background], scene.background, atol=1e-3)
    if material == "glossy":
        # The comparison can fail: without the specular term the reference no longer matches.
        diffuse_only = reference_radiance(fixture_atlas, scene, result.aovs, rays, specular=False)
        assert relative_error(result.radiance[inside], diffuse_only[inside]).max() > 0.1


def test_lambert_slice_reproduces_cosine_at_texel_centres(renderer, scene_from):
    # E = pi and albedo 1 make the radiance equal to the slice value A.rgb = max(N.L, 0).
    lights = '[[lights]]\ntype = "directional"\ndirection = [-0.8, -0.1, -0.5]\nintensity = 3.141592653589793\n'
    scene = scene_from(SPHERE.format(lights=lights, material="lambert", gloss=0.5).replace("[0.7, 0.5, 0.9]", "[1, 1, 1]"))
    result = renderer.render(scene, outlines=False)
    inside = interior(result.aov("id"))
    l = -np.asarray(scene.lights[0].direction)
    n_dot_l = np.clip(result.aov("normal") @ l, -1, 1)
    expected = np.maximum(n_dot_l, 0.0)
    # Half an 8-bit sRGB step at the top of the range, plus half-float output rounding.
    quantization = (decode_srgb(1.0) - decode_srgb(254 / 255)) / 2 + 1e-3
    away_from_kink = inside & (np.abs(n_dot_l) > 2.0 / 63)
    got = result.radiance[..., 0]
    assert np.abs(got - expected)[away_from_kink].max() < quantization
    assert (n_dot_l[inside] < -0.3).any() and (n_dot_l[inside] > 0.9).any()
    # A lookup half a texel off (u = (N.L + 1) / 2, no texel-centre offset) is caught.
    shifted = np.maximum(-1.0 + 2.0 * ((n_dot_l + 1) / 2 * 64 - 0.5) / 63, 0.0)
    assert np.abs(got - shifted)[away_from_kink & (n_dot_l > 0)].max() > quantization


def test_sixty_four_lights_add_linearly(renderer, scene_from):
    one = '[[lights]]\ntype = "directional"\ndirection = [0.2, -0.5, -1]\nintensity = 6.4\n'
    many = "".join(
        f'[[lights]]\ntype = "directional"\ndirection = [0.2, -0.5, -1]\nintensity = {6.4 / 64!r}\n' for _ in range(64)
    )
    single = renderer.render(scene_from(SPHERE.format(lights=one, material="glossy", gloss=0.4)), outlines=False)
    summed = renderer.render(scene_from(SPHERE.format(lights=many, material="glossy", gloss=0.4)), outlines=False)
    assert single.radiance.max() > 0.5
    np.testing.assert_allclose(summed.radiance, single.radiance, rtol=2e-3, atol=2e-3)


def test_mip_bias_changes_the_level(renderer, scene_from):
    # The "mips" slice is a constant grey per level, different at every level.
    lights = '[[lights]]\ntype = "directional"\ndirection = [0, 0, -1]\nintensity = 3.141592653589793\n'
    text = SPHERE.format(lights=lights, material="mips", gloss=0.5).replace("[0.7, 0.5, 0.9]", "[1, 1, 1]")
    scene = scene_from(text)
    inside = interior(renderer.render(scene, outlines=False).aov("id"))
    greys = np.array([decoded_slice(renderer.atlas, MIPS, k)[0, 0, 1] for k in range(len(MIP_GREYS))])
    assert np.abs(greys - MIP_GREYS).max() < 0.01
    seen = {}
    for bias in (-1.0, 0.0, 1.0, 1.5, 2.0, 6.0, 9.0):
        value = renderer.render(scene, mip_bias=bias, outlines=False).radiance[..., 1][inside]
        assert np.ptp(value) < 2e-3, "depth below mip_distance: one level everywhere"
        lod = min(max(bias, 0.0), len(MIP_GREYS) - 1)
        k = int(np.floor(lod))
        t = lod - k
        expected = greys[k] * (1 - t) + greys[min(k + 1, len(greys) - 1)] * t
        assert value.mean() == pytest.approx(expected, abs=2e-3)
        seen[bias] = value.mean()
    assert seen[0.0] != pytest.approx(seen[2.0], abs=0.05)
    # Depth beyond mip_distance raises the level by log2(depth / mip_distance).
    far = scene_from(text.replace("mip_distance = 100.0", "mip_distance = 0.8125"))
    result = renderer.render(far, outlines=False)
    lod = np.clip(np.log2(np.maximum(result.aov("depth"), 0.8125) / 0.8125), 0, 6)
    k = np.floor(lod).astype(int)
    t = lod - k
    expected = greys[k] * (1 - t) + greys[np.minimum(k + 1, 6)] * t
    np.testing.assert_allclose(result.radiance[..., 1][inside], expected[inside], atol=3e-3)


def test_pack_lights_layout():
    lights = [Light("point", (1.0, 0.5, 0.25), 4.0, position=(1.0, 2.0, 3.0)),
              Light("directional", (1.0, 1.0, 1.0), 2.0, direction=(0.0, -1.0, 0.0)),
              Light("spot", (1.0, 1.0, 1.0), 1.0, (0.0, 1.0, 0.0), (0.0, -1.0, 0.0), 5.0, 20.0, 30.0)]  # fmt: skip
    # WGSL layout: each vec3 is followed by a 4-byte scalar in its last 4 bytes; then cone (a vec2) and kind; size 64.
    light = np.dtype({"names": ["position", "range", "radiant", "index", "direction", "cos_outer", "cone", "kind"],
                      "formats": [("<f4", 3), "<f4", ("<f4", 3), "<u4", ("<f4", 3), "<f4", ("<f4", 2), "<u4"],
                      "offsets": [0, 12, 16, 28, 32, 44, 48, 56], "itemsize": 64})  # fmt: skip
    data = np.frombuffer(pack_lights(lights), dtype=light)
    np.testing.assert_array_equal(data["position"], [[1, 2, 3], [0, 0, 0], [0, 1, 0]])
    np.testing.assert_array_equal(data["direction"], [[0, 0, -1], [0, -1, 0], [0, -1, 0]])
    assert data["kind"].tolist() == [1, 0, 2]  # LIGHT_POINT, LIGHT_DIRECTIONAL, LIGHT_SPOT
    assert data["index"].tolist() == [0, 1, 2]  # what names a light in a tile list's copy
    np.testing.assert_array_equal(data["radiant"], [[4, 2, 1], [2, 2, 2], [1, 1, 1]])
    assert data["range"].tolist() == [0.0, 0.0, 5.0]  # 0: unbounded
    np.testing.assert_allclose(data["cos_outer"][2], np.cos(np.radians(30)), rtol=1e-7)
    np.testing.assert_allclose(data["cone"][2], [np.radians(30), 1 / np.radians(10)], rtol=1e-6)
    assert len(pack_lights([])) == 64  # never a zero-size buffer


PLANE = """
[camera]
position = [0.0, 3.0, 2.5]
target = [0, 0, 0]
fov = 70
[image]
width = 64
height = 48
[render]
mip_distance = 100.0
[[lights]]
type = "point"
position = [-0.8, 0.4, 0.3]
intensity = 2.0
range = 1.1
[[lights]]
type = "spot"
position = [0.9, 1.2, -0.2]
direction = [-0.2, -1.0, 0.1]
colour = [0.6, 0.8, 1.0]
intensity = 5.0
inner_angle = 12
outer_angle = 30
range = 2.0
[[objects]]
shape = "plane"
material = "{material}"
scale = 3
gloss = 0.5
"""


@pytest.mark.parametrize("material", ["lambert", "glossy"])
@pytest.mark.parametrize("culling", [True, False])
def test_ranged_and_spot_lights_match_numpy_and_are_exactly_zero_beyond_range(renderer, fixture_atlas, scene_from, material,
                                                                              culling):  # fmt: skip
    scene = scene_from(PLANE.format(material=material))
    result = renderer.render(scene, outlines=False, culling=culling)
    rays = pixel_rays(scene.camera, scene.width, scene.height)
    ref = reference_radiance(fixture_atlas, scene, result.aovs, rays)
    covered = result.aov("id") != 0xFFFF
    lit = covered & (ref.max(-1) > 0)
    dark = covered & (ref.max(-1) == 0)
    assert lit.mean() > 0.15 and dark.mean() > 0.15  # both sides of each range in view
    err = relative_error(result.radiance[lit], ref[lit])
    # 2%: the lights graze parts of the plane, where the 8-bit slice holds N.L to ~1% of itself.
    assert err.max() < 2e-2, f"worst relative error {err.max():.4f}"
    assert (result.radiance[dark] == 0).all()  # at and beyond the range, and outside the cone: exactly 0


def _scaled(text: str, k: float) -> str:
    """``text``'s scene at k times its size (positions, ranges, the plane's scale and mip distance times k, intensities
    times k^2, the same directions and angles), with near and far planes that frame it."""
    out = []
    for line in text.splitlines():
        key, _, value = line.partition(" = ")
        if key in ("position", "target"):
            value = "[" + ", ".join(repr(float(v) * k) for v in value.strip("[]").split(",")) + "]"
        elif key in ("range", "scale", "mip_distance"):
            value = repr(float(value) * k)
        elif key == "intensity":
            value = repr(float(value) * k * k)
        out.append(f"{key} = {value}" if _ else line)
        if line == "fov = 70":
            out += [f"near = {0.01 * k!r}", f"far = {100.0 * k!r}"]
    return "\n".join(out) + "\n"


@pytest.mark.parametrize("culling", [True, False])
def test_a_scene_a_ten_millionth_the_size_is_lit_as_numpy_says(renderer, fixture_atlas, scene_from, culling):
    """The plane's scene at 1e-7 of its size: its ranges (1.1e-7, 2e-7) and distances are below 1e-6, where the
    1e-12 that bounds 1/d^2 once entered the window (every point out of reach: a black frame, exit 0) and the
    light direction (not of unit length: N.L a tenth of itself)."""
    scene = scene_from(_scaled(PLANE.format(material="lambert"), 1e-7))
    result = renderer.render(scene, outlines=False, culling=culling)
    rays = pixel_rays(scene.camera, scene.width, scene.height)
    ref = reference_radiance(fixture_atlas, scene, result.aovs, rays)
    covered = result.aov("id") != 0xFFFF
    lit = covered & (ref.max(-1) > 0)
    assert lit.mean() > 0.15 and covered.mean() > 0.5
    err = relative_error(result.radiance[lit], ref[lit])
    assert err.max() < 2e-2, f"worst relative error {err.max():.4f}"


RANGED_POINTS = """
[[lights]]
type = "point"
position = [1.5, 1.0, 1.5]
intensity = 5.0
range = 3.0
[[lights]]
type = "point"
position = [-1.0, -0.5, 2.0]
colour = [0.3, 0.6, 1.0]
intensity = 3.0
range = 2.5
"""
OTHER_KINDS = {
    "directional": '[[lights]]\ntype = "directional"\ndirection = [0.5, -0.3, -1.0]\nintensity = 1.5\n',
    "spot": '[[lights]]\ntype = "spot"\nposition = [0.0, 2.5, 2.0]\ndirection = [0, -1, -0.6]\n'
    "outer_angle = 30\nintensity = 8.0\nrange = 6.0\n",
}


@pytest.mark.parametrize("kind", sorted(OTHER_KINDS))
def test_light_kinds_compiled_per_scene_add_linearly(renderer, scene_from, kind):
    # A scene of point lights runs a shader without the directional and spot code (DIRECTIONAL_LIGHTS,
    # SPOT_LIGHTS); adding a light of another kind compiles its code in. Whichever shader runs, the lights
    # add: points + other = points alone + other alone.
    def render(lights):
        text = SPHERE.format(lights=lights, material="glossy", gloss=0.4)
        result = renderer.render(scene_from(text), outlines=False)
        return result.radiance[result.aov("id") != 0xFFFF]  # the sphere: the background is no light's

    points, other, both = render(RANGED_POINTS), render(OTHER_KINDS[kind]), render(RANGED_POINTS + OTHER_KINDS[kind])
    assert points.max() > 0.2 and other.max() > 0.2 and (points > 0).mean() > 0.3 and (other > 0).mean() > 0.3
    assert len({key[2] for key in renderer._lighting_passes}) >= 2  # two kind sets, two shaders
    # The frame is rgba16float: each sum is rounded to half precision (2^-11 relative) once or twice.
    np.testing.assert_allclose(both, points + other, rtol=2e-3, atol=1e-4)


_FAR_LIGHT = """
[camera]
position = [0, 0, 5]
target = [0, 0, 0]
[image]
width = 32
height = 24
[[lights]]
type = "point"
position = [0, 0, {distance!r}]
intensity = {intensity!r}
{extra}
[[objects]]
shape = "sphere"
material = "lambert"
"""


@pytest.mark.parametrize(("distance", "intensity", "extra", "refused"), [
    (1e20, 3e38, "", True),  # 0.03 W/m^2 at the sphere, which the pass squared to infinity: a black image
    (1e20, 1e30, "", False),  # 1e-10 W/m^2: below the smallest half float, nothing to lose
    (3e38, 3e38, "", False),  # 3e-39 W/m^2 at the nearest point
    (1e20, 3e38, "range = 1e19", False),  # its range ends before the squares overflow
    (1e19, 3e36, "", False),  # the same irradiance, within reach
])  # fmt: skip
def test_a_light_beyond_float32_s_reach_of_an_object_it_lights_is_refused(scene_from, distance, intensity, extra, refused):
    from atlasgen.errors import SceneError
    from atlasgen.render.lighting import check_light_distances

    scene = scene_from(_FAR_LIGHT.format(distance=distance, intensity=intensity, extra=extra), path="scenes/far.toml")
    boxes = [(np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0]))]  # the unit sphere's box
    if not refused:
        check_light_distances(scene, boxes)
        return
    with pytest.raises(SceneError) as info:
        check_light_distances(scene, boxes)
    assert str(info.value).startswith("scenes/far.toml: field 'lights[0].position': expected within 1.84e+19 of the")


_BEHIND = """
[camera]
position = [0, 2, 6]
target = [0, 0, 0]
[image]
width = 48
height = 36
[[objects]]
shape = "plane"
material = "lambert"
translate = [0, -1, 0]
scale = 4
[[lights]]
type = "directional"
direction = [0.3, -1, -0.2]
intensity = 2.0
{extra}
"""


@pytest.mark.gpu
def test_a_bright_light_just_behind_a_surface_never_darkens_it(renderer, scene_from):
    """I / d^2 of a light of 1e38 a tenth below the plane overflowed float32, and inf x 0 (where the slice is 0 for
    the light's N.L < 0) made 112 pixels NaN, written as black over the directional light's share. Near N.L = 0 the
    slice's texels still reach (the sampler blends the texel at N.L = -1/63 with the one at +1/63), and there the
    light's huge irradiance saturates the frame, as it should."""
    extra = '[[lights]]\ntype = "point"\nposition = [0, -1.1, 1]\nintensity = 1e38'
    alone = renderer.render(scene_from(_BEHIND.format(extra="")), outlines=False).radiance
    both = renderer.render(scene_from(_BEHIND.format(extra=extra)), outlines=False).radiance
    assert np.isfinite(both).all() and alone.max() > 0.1
    assert np.all(both >= alone)
    lit = alone > 0.0
    assert np.mean(both[lit] == alone[lit]) > 0.5  # most of the plane is beyond the blend's reach: the light adds 0


@pytest.mark.gpu
def test_the_renderer_refuses_a_light_it_would_lose_before_drawing(renderer, scene_from):
    from atlasgen.errors import SceneError

    scene = scene_from(_FAR_LIGHT.format(distance=1e20, intensity=3e38, extra=""), path="scenes/far.toml")
    with pytest.raises(SceneError, match=r"lights\[0\].position.*objects\[0\]"):
        renderer.render(scene)
