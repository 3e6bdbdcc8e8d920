"""The frame as a whole: g-buffer contents against ray-traced geometry, degenerate input, errors."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.errors import SceneError
from atlasgen.render.camera import pixel_rays
from atlasgen.render.renderer import pack_frame

SCENE = """
[camera]
position = [0.5, 1.0, 4.0]
target = [0, 0, 0]
fov = 45
[image]
width = 72
height = 56
[render]
mip_distance = 100.0
[[lights]]
type = "point"
position = [1, 3, 3]
intensity = 10
"""


def ray_sphere_depth(eye, rays, centre, radius):
    """View depth of the nearest ray-sphere hit (rays have unit forward component), inf if none."""
    d = rays
    oc = np.asarray(eye) - np.asarray(centre)
    a = np.sum(d * d, -1)
    b = 2 * np.sum(d * oc, -1)
    c = oc @ oc - radius**2
    disc = b * b - 4 * a * c
    t = (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a)
    return np.where(disc > 0, t, np.inf)


def test_gbuffer_matches_ray_traced_sphere(renderer, scene_from):
    scene = scene_from(
        SCENE
        + """
[[objects]]
shape = "sphere"
material = "glossy"
translate = [0.2, -0.1, 0.3]
scale = 1.1
albedo = [0.25, 0.5, 0.75]
gloss = 0.8
segments = 256
"""
    )
    result = renderer.render(scene)
    rays = pixel_rays(scene.camera, scene.width, scene.height)
    depth = ray_sphere_depth(scene.camera.position, rays, (0.2, -0.1, 0.3), 1.1)
    ids = result.aov("id")
    # Coverage equals the analytic disc except along its rim (tessellation, sampling).
    from tests.render.atlas_fixture import interior

    inside = interior(ids, margin=2)
    assert (np.isfinite(depth) == (ids != 0xFFFF)).mean() > 0.97
    assert np.isfinite(depth[inside]).all()
    np.testing.assert_allclose(result.aov("depth")[inside], depth[inside], rtol=2e-3)
    hit = np.asarray(scene.camera.position) + rays * depth[..., None]
    normal = (hit - [0.2, -0.1, 0.3]) / 1.1
    cos = np.sum(result.aov("normal")[inside] * normal[inside], -1)
    assert cos.min() > 0.9995
    np.testing.assert_allclose(result.aov("albedo")[inside], np.broadcast_to([0.25, 0.5, 0.75], (inside.sum(), 3)), atol=1e-3)
    assert np.allclose(result.aov("gloss")[inside], 0.8, atol=1e-3)
    assert set(np.unique(ids)) == {1, 0xFFFF}
    assert np.isinf(result.aov("depth")[ids == 0xFFFF]).all()


def test_degenerate_meshes_give_no_nan(renderer, scene_from, tmp_path):
    # Zero-area triangles (repeated and collinear vertices) and all-zero normals.
    lines = ["v -1 -1 0", "v 1 -1 0", "v -1 1 0", "v 1 1 0", "v 0 0 0", "v 0.5 0.5 0", "v 2 2 0", "vn 0 0 0"]
    faces = ["f 1//1 2//1 3//1", "f 3//1 2//1 4//1", "f 5//1 5//1 5//1", "f 5//1 6//1 7//1", "f 1//1 1//1 2//1"]
    (tmp_path / "degenerate.obj").write_text("\n".join(lines + faces) + "\n")
    scene = scene_from(
        SCENE
        + """
[[objects]]
shape = "mesh"
file = "degenerate.obj"
material = "glossy"
[[objects]]
shape = "sphere"
material = "lambert"
segments = 3
translate = [1.5, 0, 0]
scale = 0.4
opacity = 0.5
""",
        base=tmp_path,
    )
    result = renderer.render(scene)
    assert np.isfinite(result.radiance).all()
    covered = result.aov("id") != 0xFFFF
    assert covered.sum() > 100
    normals = result.aov("normal")[covered]
    assert np.isfinite(normals).all()
    np.testing.assert_allclose(np.linalg.norm(normals, axis=-1), 1.0, atol=1e-3)
    # The quad's fallback (face) normal faces the camera.
    quad = result.aov("id") == 1
    assert (result.aov("normal")[quad][:, 2] > 0.99).all()
    assert result.radiance[quad].max() > 0


def test_unknown_material_is_a_scene_error(renderer, scene_from):
    scene = scene_from(SCENE + "[[objects]]\nshape = 'sphere'\nmaterial = 'unobtainium'\n", path="s.toml")
    with pytest.raises(SceneError) as info:
        renderer.render(scene)
    assert "glossy, lambert, mips, plain, toon" in str(info.value)


def test_a_scene_whose_meshes_pass_the_triangle_limit_is_refused_at_the_object(renderer, scene_from, monkeypatch):
    """A hostile sweep's: 100 tori of 1024 segments, each its own radius, took 5 GB (the limit is lowered here to
    stand for it). Objects sharing a mesh count it once."""
    import atlasgen.render.renderer as module
    from atlasgen.render.meshes import make_sphere

    sphere = "[[objects]]\nshape = 'sphere'\nmaterial = 'lambert'\nsegments = {}\n"
    limit = len(make_sphere(16).indices) + len(make_sphere(17).indices)  # the first two meshes, and not the third
    monkeypatch.setattr(module, "MAX_SCENE_TRIANGLES", limit)
    shared = scene_from(SCENE + sphere.format(16) * 5, path="s.toml")
    assert renderer.render(shared).radiance.shape[:2] == (shared.height, shared.width)
    scene = scene_from(SCENE + sphere.format(16) + sphere.format(17) + sphere.format(16) + sphere.format(18), path="s.toml")
    with pytest.raises(SceneError) as info:
        renderer.render(scene)
    assert str(info.value).startswith("s.toml: field 'objects[3]': ")
    assert str(info.value).endswith(
        f" triangles in the scene's meshes with this object's; expected at most {limit} in "
        "all (fewer segments, or objects sharing a mesh)"
    )


def test_empty_scene_is_background(renderer, scene_from):
    scene = scene_from(SCENE.replace("[render]", "[render]\n") + "")
    result = renderer.render(scene)
    assert (result.radiance == 0).all() and (result.aov("id") == 0xFFFF).all()


def test_frame_uniform_layout(scene_from):
    data = np.frombuffer(pack_frame(scene_from(SCENE), 7, mip_bias=1.25), dtype=np.float32)
    assert data.size == 60
    assert data[16:19].tolist() == [0.5, 1.0, 4.0]  # eye
    assert data[32:36].tolist() == [72, 56, np.float32(1 / 72), np.float32(1 / 56)]  # viewport
    assert data[40:43].tolist() == [1.25, 100.0, 6.0]  # bias, mip distance, last level
    assert np.frombuffer(data[44:48].tobytes(), dtype=np.uint32).tolist() == [1, 0, 0, 0]  # one light
    # Not culled: the tile-list texture is one layer of every light's four texels, a light a row.
    assert np.frombuffer(data[48:52].tobytes(), dtype=np.uint32).tolist() == [0, 2, 0, 0]
    assert data[56] == np.float32(0.05)  # outline depth threshold
    culled = np.frombuffer(pack_frame(scene_from(SCENE), 7, tile_capacity=255), dtype=np.uint32)
    # 72 x 56 pixels: 5 x 4 tiles, lists of 512 texels, and every light in layer 4.
    assert culled[44:48].tolist() == [1, 1, 5, 255] and culled[48:52].tolist() == [4, 9, 0, 0]


def test_a_given_mesh_is_drawn_without_reading_its_file(renderer, scene_from, tmp_path):
    from atlasgen.render.meshes import make_sphere

    # Not a mesh at all: reading it would fail, so the picture proves the renderer did not.
    (tmp_path / "ball.ply").write_text("not a mesh\n")
    renderer.add_mesh(tmp_path / "ball.ply", make_sphere(64))
    shown = SCENE + '[[objects]]\nshape = "{shape}"\nmaterial = "glossy"\n'
    given = renderer.render(scene_from(shown.format(shape="mesh") + 'file = "ball.ply"\n', base=tmp_path))
    built = renderer.render(scene_from(shown.format(shape="sphere") + "segments = 64\n"))
    assert (given.aov("id") != 0xFFFF).mean() > 0.2
    np.testing.assert_array_equal(given.radiance, built.radiance)


@pytest.mark.slow
def test_set_atlas_renders_what_a_new_renderer_would(gpu_device, write_material, scene_from):
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_materials
    from atlasgen.render.atlas_texture import RenderAtlas
    from atlasgen.render.renderer import Renderer

    def atlas(colour, other=False):
        paths = [write_material("clay", f'type = "lambert"\ncolour = {colour}\n')]
        if other:
            paths.append(write_material("stone", 'type = "lambert"\ncolour = [0.5, 0.5, 0.5]\n'))
        result = bake_atlas(read_materials(paths))
        return RenderAtlas(result.levels, True, result.manifest, result.include, "test")

    # Same peak (the slice's scale) with other texels; another peak, a new scale in the bake's include but
    # only a new buffer for the renderer; then another material, new code (its constant): a compile.
    first, same_peak, new_peak = atlas([0.7, 0.5, 0.3]), atlas([0.7, 0.2, 0.3]), atlas([0.4, 0.5, 0.3])
    more = atlas([0.4, 0.5, 0.3], other=True)
    assert first.include == same_peak.include != new_peak.include
    scene = scene_from(SCENE + '[[objects]]\nshape = "sphere"\nmaterial = "clay"\n')
    renderer = Renderer(first, gpu_device)
    before = renderer.render(scene, aovs=False).radiance
    assert renderer.set_atlas(same_peak) is False
    texels_only = renderer.render(scene, aovs=False).radiance
    assert renderer.set_atlas(new_peak) is False
    new_scale = renderer.render(scene, aovs=False).radiance
    assert renderer.set_atlas(more) is True
    recompiled = renderer.render(scene, aovs=False).radiance
    assert np.abs(texels_only - before).max() > 0.05 and np.abs(new_scale - texels_only).max() > 0.05
    for got, fresh in ((texels_only, same_peak), (new_scale, new_peak), (recompiled, more)):
        np.testing.assert_array_equal(got, Renderer(fresh, gpu_device).render(scene, aovs=False).radiance)


CLOSED_AND_OPEN = """
[[objects]]
shape = "sphere"
material = "lambert"
translate = [-1.1, 0.2, 0]
scale = 0.6
[[objects]]
shape = "box"
material = "glossy"
translate = [0.9, 0.3, -0.3]
rotate = [20, 35, 0]
scale = 0.5
[[objects]]
shape = "torus"
material = "plain"
translate = [0.0, -0.5, 0.8]
rotate = [60, 0, 0]
scale = 0.6
[[objects]]
shape = "plane"
material = "lambert"
translate = [0, 1.6, 0]
scale = 20
"""


def test_culling_the_back_faces_of_closed_meshes_changes_nothing_and_planes_stay_two_sided(renderer, scene_from):
    """Sphere, box and torus are drawn with back faces culled: the frame and g-buffer are those of the
    two-sided pipeline, bit for bit (a mesh wound inwards would show its far side). A plane is open: the
    one above the camera's target is seen from below, shaded with its flipped normal."""
    scene = scene_from(SCENE + CLOSED_AND_OPEN)
    culled = renderer.render(scene, outlines=False)
    pipelines = dict(renderer.gbuffer_pass.pipelines)
    renderer.gbuffer_pass.pipelines[True] = pipelines[False]
    try:
        two_sided = renderer.render(scene, outlines=False)
    finally:
        renderer.gbuffer_pass.pipelines.update(pipelines)
    np.testing.assert_array_equal(culled.radiance, two_sided.radiance)
    for name in ("id", "depth", "normal"):
        np.testing.assert_array_equal(culled.aov(name), two_sided.aov(name))
    assert len(np.unique(culled.aov("id"))) == 4  # three materials and the background
    # The plane overhead (y = 1.6, the camera at 1.0) fills the top row, its normal turned down to the eye.
    assert (culled.aov("normal")[0, :, 1] < -0.99).all()


def test_the_opaque_lighting_pass_shades_only_covered_pixels_unless_the_environment_shows(renderer, scene_from):
    """Behind the objects of a scene without a visible environment is the target's clear colour: the
    lighting triangle lies on the far plane and the depth test (``greater``) keeps the shader off every
    pixel no object covers. Shown by re-running the pass cleared to a colour the shader never writes:
    the background keeps it and the covered pixels are the frame's; shading every pixel paints the
    scene's background over it."""
    sphere = '[[objects]]\nshape = "sphere"\nmaterial = "glossy"\n'
    scene = scene_from(SCENE.replace("height = 56", "height = 56\nbackground = [0.25, 0.5, 0.75]") + sphere)
    frame = renderer.prepare(scene)
    renderer.submit(renderer.encode_frame(frame, outlines=False))
    shaded = renderer.read_radiance(frame)
    covered = renderer.read_aovs(frame)["id"] != 0xFFFF
    assert 0.1 < covered.mean() < 0.9

    def relit(shade_background):
        encoder = renderer.device.create_command_encoder()
        frame.lighting_pass.encode(encoder, frame.hdr, frame.gbuffer, frame.lighting_group, background=(5.0, 6.0, 7.0),
                                   shade_background=shade_background)  # fmt: skip
        renderer.submit([encoder.finish()])
        return renderer.read_radiance(frame)

    skipped = relit(False)
    np.testing.assert_array_equal(skipped[covered], shaded[covered])
    assert (skipped[~covered] == [5.0, 6.0, 7.0]).all()
    everywhere = relit(True)
    np.testing.assert_array_equal(everywhere[covered], shaded[covered])
    np.testing.assert_array_equal(everywhere[~covered], shaded[~covered])
    np.testing.assert_allclose(shaded[~covered], np.broadcast_to([0.25, 0.5, 0.75], shaded[~covered].shape), rtol=1e-3)
