"""The generated WGSL include: compiled by a real WebGPU device and checked against the contract."""

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.contract import atlas_uv, texel_centres
from atlasgen.io.manifest import read_manifest
from atlasgen.materials.material import read_materials
from atlasgen.models import get_model
from atlasgen.optics.quantize import dequantize_rgba, unorm_scale
from atlasgen.shaders.include import MaterialFlag, render_include
from atlasgen.shaders.structs import wgsl_constants


@pytest.fixture
def atlas(tmp_path, write_material):
    write_material("clay", 'type = "lambert"\ncolour = [0.8, 0.5, 0.25]\nid = 3\n')
    write_material("hot", 'type = "lambert"\nid = 4\nrgb_scale = 0.5\n')  # clamps: stored 1 -> 0.5 linear
    write_material("cel", 'type = "toon"\nid = 5\nthresholds = [-0.3, 0.33]\nsilhouette = 0.2\n')
    result = bake_atlas(read_materials([tmp_path / "materials"]))
    paths = write_bake(result, tmp_path / "atlas.dds")
    return result, paths["include"].read_text()


def test_include_defines_the_contract(atlas):
    result, text = atlas
    assert "const MATERIAL_CLAY: u32 = 3u;" in text and "const MATERIAL_HOT: u32 = 4u;" in text
    assert "fn atlas_uv(n_dot_l: f32, n_dot_v: f32) -> vec2<f32>" in text
    assert "fn atlas_sample(atlas: texture_2d_array<f32>" in text


def bilinear(texels, u, v):
    """Reference bilinear lookup with clamp-to-edge, in normalised coordinates."""
    h, w, _ = texels.shape
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = np.clip(np.floor(x).astype(int), 0, w - 1), np.clip(np.floor(y).astype(int), 0, h - 1)
    x1, y1 = np.clip(x0 + 1, 0, w - 1), np.clip(y0 + 1, 0, h - 1)
    fx, fy = np.clip(x - x0, 0, 1)[:, None], np.clip(y - y0, 0, 1)[:, None]
    return (1 - fy) * ((1 - fx) * texels[y0, x0] + fx * texels[y0, x1]) + fy * ((1 - fx) * texels[y1, x0] + fx * texels[y1, x1])


@pytest.mark.slow
def test_atlas_sample_on_the_gpu_matches_the_contract(gpu_device, atlas):
    import wgpu

    from atlasgen.render.atlas_texture import RenderAtlas, upload_atlas

    result, include = atlas
    rng = np.random.default_rng(7)
    nl_c, nv_c = texel_centres()
    # Texel centres (exact) and random points in between (bilinear), for both materials.
    nl = np.concatenate([nl_c[rng.integers(0, 64, 64)], rng.uniform(-1, 1, 64)])
    nv = np.concatenate([nv_c[rng.integers(0, 32, 64)], rng.uniform(0, 1, 64)])
    ids = np.tile([3, 4, 5, 3], 32)
    points = np.stack([nl, nv, ids.astype(np.float64), np.zeros_like(nl)], axis=1).astype(np.float32)

    shader = (
        include
        + """
@group(0) @binding(0) var atlas_tex: texture_2d_array<f32>;
@group(0) @binding(1) var atlas_smp: sampler;
@group(0) @binding(2) var<storage, read> points: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> out: array<vec4<f32>>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = points[gid.x];
    out[gid.x] = atlas_sample(atlas_tex, atlas_smp, u32(p.z), p.x, p.y, 0.0);
}
"""
    )
    device = gpu_device.device
    texture = upload_atlas(gpu_device, RenderAtlas(result.levels, True, result.manifest, include))
    sampler = device.create_sampler(
        mag_filter="linear",
        min_filter="linear",
        mipmap_filter="linear",
        address_mode_u="clamp-to-edge",
        address_mode_v="clamp-to-edge",
    )
    pbuf = device.create_buffer_with_data(data=points.tobytes(), usage=wgpu.BufferUsage.STORAGE)
    obuf = device.create_buffer(size=points.nbytes, usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)
    pipeline = device.create_compute_pipeline(
        layout="auto", compute={"module": device.create_shader_module(code=shader), "entry_point": "main"}
    )
    bind = device.create_bind_group(
        layout=pipeline.get_bind_group_layout(0),
        entries=[
            {"binding": 0, "resource": texture.create_view(dimension="2d-array")},
            {"binding": 1, "resource": sampler},
            {"binding": 2, "resource": {"buffer": pbuf}},
            {"binding": 3, "resource": {"buffer": obuf}},
        ],
    )
    enc = device.create_command_encoder()
    cp = enc.begin_compute_pass()
    cp.set_pipeline(pipeline)
    cp.set_bind_group(0, bind)
    cp.dispatch_workgroups(len(points) // 64)
    cp.end()
    device.queue.submit([enc.finish()])
    got = np.frombuffer(device.queue.read_buffer(obuf), np.float32).reshape(-1, 4)

    u, v = atlas_uv(nl, nv)
    for material_id in (3, 4):  # bilinear slices: the first at its peak's scale, the second at its TOML's 0.5
        sel = ids == material_id
        ((scale, alpha_scale),) = next(e for e in result.manifest.materials if e.first_slice == material_id).scale
        assert scale == (0.5 if material_id == 4 else unorm_scale(0.8))
        texels = dequantize_rgba(result.levels[0][material_id], srgb=True)
        expected = bilinear(texels, u[sel], v[sel]) * np.array([scale, scale, scale, alpha_scale])
        # Filtering precision of an 8-bit sampler (8-bit fraction weights) bounds the match.
        np.testing.assert_allclose(got[sel], expected, atol=4e-3)
    # The toon slice is flagged nearest: the GPU reads one texel, so the bands stay hard
    # and equal the model itself at any point, to 8-bit precision.
    from atlasgen.materials.material import read_material

    cel = result.manifest.entry_named("cel")
    assert cel.flag("nearest")
    toon = read_material(cel.source)
    sel = ids == 5
    np.testing.assert_allclose(got[sel], toon.model.evaluate(toon.params, nl[sel], nv[sel]), atol=3e-3)
    # At texel centres the clay slice is its closed form, to 8-bit precision.
    centre = (ids == 3) & (np.arange(len(ids)) < 64)
    closed = np.maximum(nl[centre], 0)[:, None] * np.array([0.8, 0.5, 0.25])
    np.testing.assert_allclose(got[centre, :3], closed, atol=8e-3)


def test_material_flags_are_the_include_bits():
    golden = read_manifest(Path(__file__).parents[1] / "resources" / "golden" / "array-srgb.json")
    a, b = golden.materials[0], golden.materials[5]
    manifest = dataclasses.replace(golden, materials=[
        dataclasses.replace(a, first_slice=0, id=0, slice_count=1, flags={"outline": True, "nearest": True}),
        dataclasses.replace(b, first_slice=1, id=1, slice_count=2, flags={"nearest": True}, factors=None),
    ])  # fmt: skip
    text = render_include(manifest, np.ones((256, 2)), np.zeros((256, 2)), models=get_model)
    assert wgsl_constants(MaterialFlag, "ATLAS_FLAG_") in text
    assert "const ATLAS_FLAG_OUTLINE: u32 = 1u;\nconst ATLAS_FLAG_NEAREST: u32 = 2u;" in text
    assert "case 0u: { return 3u; }" in text  # OUTLINE | NEAREST
    assert "case 1u: { return 2u; }" in text and "case 2u: { return 2u; }" in text


@pytest.mark.parametrize("lang", ["wgsl", "glsl", "hlsl"])
def test_the_include_defines_every_constant_its_docs_name(lang):
    # Every ATLAS_* and SEPARABLE_* name the engine docs give is declared by the include (the
    # golden one, which holds separable materials), so code written from the docs compiles.
    root = Path(__file__).parents[2]
    docs = "".join((root / doc).read_text() for doc in ("docs/engine-integration.md", "docs/atlas-format.md"))
    names = sorted(set(re.findall(r"\b(?:ATLAS|SEPARABLE)_[A-Z0-9_]*[A-Z0-9]\b", docs)))
    assert {"ATLAS_PI", "ATLAS_WIDTH", "SEPARABLE_TABLE"} <= set(names), names
    text = (root / "tests" / "resources" / "golden" / f"array-srgb.{lang}").read_text()
    undeclared = [n for n in names if not re.search(rf"^(?:static )?(?:const |var<private> )?(?:\w+ )?{n}\b", text, re.MULTILINE)]
    assert not undeclared, f"the {lang} include lacks {undeclared}"
