"""The include's per-slice lookups for a full atlas, run on the GPU in every language: what the manifest says.

``atlas_scale_bias`` and ``atlas_material_flags`` are switch statements (a 256-entry private array takes lavapipe a
minute to compile). Mesa's lavapipe miscompiled a switch of about 80 cases or more: a library of 256 materials read
174 IDs with another's flags and scale, in atlasgen's own renderer too. Switches are split at
:data:`~atlasgen.shaders.lang.SWITCH_CASES_MAX` cases, and this runs all 256 IDs through them.
"""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.materials.material import read_materials
from atlasgen.shaders.include import MaterialFlag
from atlasgen.shaders.lang import LANGUAGES, SWITCH_CASES_MAX
from tests.shaders.gpu_compute import run_compute
from tests.shaders.test_include_languages import GLSLANG, _spirv

IDS = 256
# Word 5i..5i+4 of the result: scale and bias of slice i (rgb_scale, alpha_scale, rgb_bias, alpha_bias) and its flags.
SHADERS = {
    "wgsl": """
@group(0) @binding(0) var<storage, read> ids: array<u32>;
@group(0) @binding(1) var<storage, read_write> r: array<u32>;
@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = ids[gid.x];
    let sb = bitcast<vec4<u32>>(atlas_scale_bias(i));
    r[5u * gid.x] = sb.x; r[5u * gid.x + 1u] = sb.y; r[5u * gid.x + 2u] = sb.z; r[5u * gid.x + 3u] = sb.w;
    r[5u * gid.x + 4u] = atlas_material_flags(i);
}
""",
    "glsl": """#version 450
#extension GL_GOOGLE_include_directive : require
#include "atlas.glsl"
layout(std430, set = 0, binding = 0) readonly buffer Ids { uint ids[]; };
layout(std430, set = 0, binding = 1) buffer Results { uint r[]; };
layout(local_size_x = 256) in;
void main() {
    uint g = gl_GlobalInvocationID.x;
    uint i = ids[g];
    uvec4 sb = floatBitsToUint(atlas_scale_bias(i));
    r[5u * g] = sb.x; r[5u * g + 1u] = sb.y; r[5u * g + 2u] = sb.z; r[5u * g + 3u] = sb.w;
    r[5u * g + 4u] = atlas_material_flags(i);
}
""",
    "hlsl": """#include "atlas.hlsl"
[[vk::binding(0, 0)]] StructuredBuffer<uint> ids;
[[vk::binding(1, 0)]] RWStructuredBuffer<uint> r;
[numthreads(256, 1, 1)]
void main(uint3 gid : SV_DispatchThreadID) {
    uint g = gid.x;
    uint i = ids[g];
    uint4 sb = asuint(atlas_scale_bias(i));
    r[5u * g] = sb.x; r[5u * g + 1u] = sb.y; r[5u * g + 2u] = sb.z; r[5u * g + 3u] = sb.w;
    r[5u * g + 4u] = atlas_material_flags(i);
}
""",
}


@pytest.fixture(scope="module")
def full_atlas(tmp_path_factory):
    """256 one-slice materials: every third a toon (outlined or not: flags), the others lambert of varied colours (each
    its own scale), written with its includes."""
    folder = tmp_path_factory.mktemp("full")
    for i in range(IDS):
        if i % 3 == 0:
            text = f'type = "toon"\noutline = {"true" if i % 2 == 0 else "false"}\n'
        else:
            text = f'type = "lambert"\ncolour = [{0.2 + 0.7 * i / IDS:.4f}, 0.5, 0.3]\n'
        (folder / f"m{i:03d}.toml").write_text(text)
    result = bake_atlas(read_materials([folder]), "array", False, {})
    write_bake(result, folder / "atlas.dds")
    return result.manifest, folder


def _expected(manifest) -> np.ndarray:
    """Per slice (scale rgb, scale a, bias rgb, bias a, flags) from the manifest; (1, 1, 0, 0, 0) where unused."""
    out = np.tile(np.array([1.0, 1.0, 0.0, 0.0, 0.0]), (IDS, 1))
    for m in manifest.materials:
        bits = sum(int(flag) for flag in MaterialFlag if m.flag(flag.name.lower()))
        for k, s in enumerate(m.slices):
            out[s] = [*m.scale[k], *m.bias[k], bits]
    return out


@pytest.mark.gpu
@pytest.mark.slow
@pytest.mark.parametrize("lang", LANGUAGES)
def test_every_slice_s_scale_and_flags_read_on_the_gpu_are_the_manifest_s(lang, full_atlas, gpu_device):
    if lang != "wgsl" and GLSLANG is None:
        pytest.skip("glslangValidator (Debian glslang-tools) is not installed")
    manifest, folder = full_atlas
    expected = _expected(manifest)
    assert len({tuple(row) for row in expected}) > 80  # more cases than one switch lavapipe compiled right
    include = (folder / f"atlas.{lang}").read_text()
    code = include + SHADERS["wgsl"] if lang == "wgsl" else _spirv(lang, folder, SHADERS[lang], name="switch")
    words = run_compute(gpu_device, code, np.arange(IDS, dtype="<u4").tobytes(), False, 5 * IDS).reshape(IDS, 5)
    np.testing.assert_allclose(words[:, :4].view("<f4"), expected[:, :4], rtol=1e-6)
    np.testing.assert_array_equal(words[:, 4], expected[:, 4])
    assert gpu_device.take_errors() == []


@pytest.mark.gpu
def test_a_long_switch_returns_each_case_s_value_on_the_gpu(gpu_device):
    """switch_lines over 128 cases (the renderer's material dispatch is written with it too): each label its own
    value, every other ID the default, each switch of at most SWITCH_CASES_MAX cases."""
    from atlasgen.shaders.lang import switch_lines

    labels = range(0, IDS, 2)
    lines = switch_lines("wgsl", "i", [(k, f"return {3 * k + 1}u;") for k in labels], "return 999u;", "    ")
    assert max(text.count("case") for text in "\n".join(lines).split("switch")) <= SWITCH_CASES_MAX
    code = "\n".join(["fn f(i: u32) -> u32 {", *lines, "}", """
@group(0) @binding(0) var<storage, read> ids: array<u32>;
@group(0) @binding(1) var<storage, read_write> r: array<u32>;
@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) { r[gid.x] = f(ids[gid.x]); }
"""])  # fmt: skip
    got = run_compute(gpu_device, code, np.arange(IDS, dtype="<u4").tobytes(), False, IDS)
    np.testing.assert_array_equal(got, [3 * i + 1 if i % 2 == 0 else 999 for i in range(IDS)])
