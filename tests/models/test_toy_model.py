"""Adding a model is one module: a toy model, registered here, goes through the bake, the renderer
and validation without any of them knowing its name (docs/adding-a-model.md).

Two toys share one closed form, Valve's half-Lambert wrap (Mitchell, McTaggart & Green,
"Shading in Valve's Source Engine", SIGGRAPH 2006 course): f cos = colour (N.L / 2 + 1/2)^2 / pi.
``half-lambert`` is a table model (every hook at its default: the renderer samples its
slice); ``shader-wrap`` sets ``custom_lighting`` and evaluates the same formula in its own
WGSL, so the lighting pass must dispatch to a model it has never heard of.
"""

from __future__ import annotations

import json
import textwrap
import tomllib

import numpy as np
import pytest

from atlasgen.contract import texel_centres
from atlasgen.errors import MaterialError
from atlasgen.io.fields import Param
from atlasgen.models import get_model, model_types, register_model, unregister_model
from atlasgen.models.base import Model

COLOUR = (0.8, 0.6, 0.4)


def wrap(n_dot_l):
    """(N.L / 2 + 1/2)^2, the half-Lambert fall-off (0 only for light from straight behind)."""
    w = 0.5 * np.clip(np.asarray(n_dot_l, dtype=np.float64), -1.0, 1.0) + 0.5
    return w * w


class HalfLambert(Model):
    """RGB = colour * (N.L / 2 + 1/2)^2, A = 0."""

    type_name = "half-lambert"
    reference = "Mitchell, McTaggart & Green, Shading in Valve's Source Engine, SIGGRAPH 2006"
    params = (Param("colour", (1.0, 1.0, 1.0), "colour", doc="diffuse colour, linear"),)

    def evaluate(self, values, n_dot_l, n_dot_v):
        shape = np.broadcast_shapes(np.shape(n_dot_l), np.shape(n_dot_v))
        out = np.zeros(shape + (4,))
        out[..., :3] = np.broadcast_to(wrap(n_dot_l), shape)[..., None] * np.asarray(values["colour"])
        return out


class ShaderWrap(HalfLambert):
    """The same half-Lambert, evaluated by its own WGSL in the lighting pass."""

    type_name = "shader-wrap"
    custom_lighting = True

    @classmethod
    def include_wgsl(cls, entries):
        return textwrap.dedent("""\
            fn toy_wrap_f_cos(n: vec3<f32>, l: vec3<f32>, colour: vec3<f32>) -> vec3<f32> {
                let w = 0.5 * dot(n, l) + 0.5;
                return colour * (w * w) / 3.14159265358979;
            }
            """)

    @classmethod
    def lighting_wgsl(cls, entry):
        r, g, b = (float(c) for c in entry.params["colour"])
        return f"toy_wrap_f_cos(n, l, vec3<f32>({r!r}, {g!r}, {b!r}))"


SCENE = """
[camera]
position = [0.0, 0.3, 3.2]
target = [0, 0, 0]
fov = 45
[image]
width = 56
height = 40
[[lights]]
type = "directional"
direction = [-0.4, -0.5, -1.0]
intensity = 2.0
[[lights]]
type = "point"
position = [2.0, 1.0, -1.5]
colour = [1.0, 0.8, 0.6]
intensity = 4.0
[[objects]]
shape = "sphere"
material = "table-toy"
translate = [-0.7, 0.0, 0.0]
scale = 0.6
albedo = [0.9, 1.0, 0.8]
segments = 96
[[objects]]
shape = "sphere"
material = "shader-toy"
translate = [0.7, 0.0, 0.0]
scale = 0.6
albedo = [1.0, 0.7, 0.9]
segments = 96
"""


@pytest.fixture(scope="module")
def toys():
    register_model(HalfLambert)
    register_model(ShaderWrap)
    yield
    unregister_model(HalfLambert.type_name)
    unregister_model(ShaderWrap.type_name)


@pytest.fixture(scope="module")
def toy_atlas(toys, tmp_path_factory):
    """``atlas.dds`` (manifest and include beside it) holding one material of each toy."""
    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.materials.material import read_materials

    root = tmp_path_factory.mktemp("toy")
    folder = root / "materials"
    folder.mkdir()
    (folder / "table-toy.toml").write_text(f'type = "half-lambert"\ncolour = {list(COLOUR)}\n')
    (folder / "shader-toy.toml").write_text(f'type = "shader-wrap"\ncolour = {list(COLOUR)}\n')
    path = root / "atlas.dds"
    write_bake(bake_atlas(read_materials([folder])), path)
    return path


def test_registering_makes_the_type_a_material_type_and_forgetting_it_does_not(toys, write_material):
    from atlasgen.materials.material import read_material

    assert {"half-lambert", "shader-wrap"} <= set(model_types())
    material = read_material(write_material("toy", 'type = "half-lambert"\ncolour = [0.1, 0.2, 0.3]\n'))
    assert isinstance(material.model, HalfLambert) and material.params["colour"] == (0.1, 0.2, 0.3)
    with pytest.raises(ValueError, match="already registered"):
        register_model(type("Impostor", (HalfLambert,), {}))
    with pytest.raises(ValueError, match="Model subclass"):
        register_model(dict)
    unregister_model("half-lambert")
    try:
        with pytest.raises(MaterialError, match="unknown model 'half-lambert'"):
            read_material(write_material("toy", 'type = "half-lambert"\n'))
    finally:
        register_model(HalfLambert)


def test_the_bake_stores_the_toys_closed_form_and_its_include(toy_atlas):
    from atlasgen.io.atlas import read_atlas

    atlas = read_atlas(toy_atlas)
    nl, _ = texel_centres()
    for name in ("table-toy", "shader-toy"):
        entry = atlas.manifest.entry_named(name)
        slice_ = atlas.decode_slice(entry.first_slice)
        expected = wrap(nl)[None, :, None] * np.asarray(COLOUR)
        np.testing.assert_allclose(slice_[..., :3], np.broadcast_to(expected, slice_[..., :3].shape), atol=1.5 / 255)
        assert np.all(slice_[..., 3] == 0.0)
        assert get_model(entry.type).describe_representation(entry) == "LUT, point-sampled"
    include = toy_atlas.with_suffix(".wgsl").read_text()
    assert include.count("fn toy_wrap_f_cos(") == 1  # the custom model's code, once per type


def _closed_form(scene, result, entry, albedo):
    """sum over lights of E * albedo * colour * wrap(N.L) / pi at the g-buffer's pixels of ``entry``."""
    from atlasgen.render.camera import pixel_rays
    from tests.render.atlas_fixture import light_at

    mask = result.aov("id") == entry.first_slice
    n = result.aov("normal")[mask].astype(np.float64)
    rays = pixel_rays(scene.camera, scene.width, scene.height)[mask]
    world = np.asarray(scene.camera.position) + rays * result.aov("depth")[mask, None]
    expected = np.zeros_like(n)
    for light in scene.lights:
        l, e = light_at(light, world)
        expected += e * np.asarray(albedo) * np.asarray(COLOUR) * wrap((n * l).sum(-1))[:, None] / np.pi
    return mask, expected


@pytest.mark.gpu
@pytest.mark.slow
def test_the_renderer_shades_both_toys_with_the_closed_form(toy_atlas, gpu_device):
    from atlasgen.materials.scene import parse_scene
    from atlasgen.render.atlas_texture import read_render_atlas
    from atlasgen.render.renderer import Renderer

    atlas = read_render_atlas(toy_atlas)
    gpu_device.take_errors()
    scene = parse_scene(tomllib.loads(SCENE), "toy.toml", None)
    result = Renderer(atlas, gpu_device).render(scene, outlines=False)
    assert gpu_device.take_errors() == []
    # The table toy goes through the 8-bit slice and bilinear filtering; the shader toy
    # through f32 arithmetic into a half-float target.
    for name, albedo, tolerance in (("table-toy", (0.9, 1.0, 0.8), 0.02), ("shader-toy", (1.0, 0.7, 0.9), 0.004)):
        mask, expected = _closed_form(scene, result, atlas.manifest.entry_named(name), albedo)
        assert mask.sum() > 200, name
        got = result.radiance[mask]
        err = np.abs(got - expected) / np.maximum(expected, 0.02 * expected.max())
        assert np.percentile(err, 99) < tolerance, (name, np.percentile(err, 99))


@pytest.mark.mitsuba
def test_the_model_reference_plugin_evaluates_the_closed_form(toy_atlas, mitsuba_llvm):
    import drjit as dr

    from atlasgen.io.atlas import read_atlas
    from atlasgen.validate.references import model_reference, register_references

    mi = mitsuba_llvm
    register_references(mi)
    entry = read_atlas(toy_atlas).manifest.entry_named("table-toy")
    reference = model_reference(entry, (0.5, 1.0, 1.0), 0.3)
    assert json.loads(reference.bsdf["material"])["type"] == "half-lambert"
    bsdf = mi.load_dict(reference.bsdf)
    rng = np.random.default_rng(3)
    wi = rng.normal(size=(64, 3))
    wi[:, 2] = np.abs(wi[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    cos_o = np.linspace(-0.9, 0.95, 64)
    wo = np.stack([np.sqrt(1 - cos_o**2), np.zeros(64), cos_o], -1)
    si = dr.zeros(mi.SurfaceInteraction3f, 64)
    si.wi = mi.Vector3f(*[mi.Float(np.ascontiguousarray(wi[:, k], np.float32)) for k in range(3)])
    si.n = mi.Normal3f(0.0, 0.0, 1.0)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    with dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, False):
        value = bsdf.eval(
            mi.BSDFContext(), si, mi.Vector3f(*[mi.Float(np.ascontiguousarray(wo[:, k], np.float32)) for k in range(3)])
        )
    got = np.stack([np.asarray(c) for c in (value.x, value.y, value.z)], -1)
    expected = np.asarray([0.5, 1.0, 1.0]) * np.asarray(COLOUR) * wrap(cos_o)[:, None] / np.pi
    np.testing.assert_allclose(got, expected, rtol=1e-5, atol=1e-7)


@pytest.mark.gpu
@pytest.mark.mitsuba
@pytest.mark.slow
def test_validation_measures_both_toys_against_their_mitsuba_model_reference(toy_atlas, gpu_device, mitsuba_llvm):
    from atlasgen.validate.run import validate_atlas

    gpu_device.take_errors()
    run = validate_atlas(toy_atlas, ["table-toy", "shader-toy"], scenes=["front", "back"], resolution=(40, 30))
    assert gpu_device.take_errors() == []
    assert {(r.material, r.scene) for r in run.runs} == {(m, s) for m in ("table-toy", "shader-toy") for s in ("front", "back")}
    for r in run.runs:
        model = r.references["model"]
        assert set(r.references) == {"model"}  # no physical reference: the toys have none
        assert model.description == f"{r.type} model, exact, in the renderer's equation"
        assert r.goals and r.claimed is None
        assert model.metrics.psnr >= 45.0 and model.metrics.flip <= 0.01, (r.material, r.scene, model.metrics)
        # The default rebuilds split the error: float table, 8-bit table, and the GPU against the latter.
        assert r.breakdown["table_float"]["psnr_db"] >= 50.0, (r.material, r.breakdown)
        assert r.breakdown["gpu_vs_8bit"]["psnr_db"] >= 45.0, (r.material, r.breakdown)
