"""The include's environment functions in WGSL, GLSL and HLSL against their NumPy twins (atlasgen/optics).

GLSL and HLSL are compiled to SPIR-V with glslang and run through wgpu (lavapipe), as the rest of the
include is (tests/shaders/test_include_languages.py).
"""

import shutil
import subprocess

import numpy as np
import pytest

from atlasgen.optics.equirect import direction_to_uv, uv_to_texel
from atlasgen.optics.spherical_harmonics import SH_ORDER, evaluate_sh, sh_basis, sh_count
from atlasgen.shaders.common import common_declarations
from atlasgen.shaders.environment import environment_declarations
from atlasgen.shaders.lang import LANGUAGES, emit
from tests.shaders.gpu_compute import run_compute

GLSLANG = shutil.which("glslangValidator")
RNG = np.random.default_rng(20)
N = 64
K = sh_count(SH_ORDER)

# Binding 0: sh[25], lam[5], then per query (n.xyz, height) and (gloss, levels, 0, 0).
# Binding 1: per query (diffuse.rgb, level) and (uv, 0, 0).
SHADERS = {
    "wgsl": """
struct Src { sh: array<vec4<f32>, 25>, lam: array<vec4<f32>, 5>, q: array<vec4<f32>, 128> };
@group(0) @binding(0) var<storage, read> src: Src;
@group(0) @binding(1) var<storage, read_write> r: array<vec4<f32>, 128>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    let a = src.q[2u * i]; let b = src.q[2u * i + 1u];
    r[2u * i] = vec4<f32>(atlas_sh_diffuse(a.xyz, src.sh, src.lam), atlas_env_level(b.x, b.y));
    r[2u * i + 1u] = vec4<f32>(atlas_env_uv(a.xyz, a.w), 0.0, 0.0);
}
""",
    "glsl": """#version 450
INCLUDE
layout(std430, set = 0, binding = 0) readonly buffer Src { vec4 sh[25]; vec4 lam[5]; vec4 q[128]; };
layout(std430, set = 0, binding = 1) buffer Results { vec4 r[128]; };
layout(local_size_x = 64) in;
void main() {
    uint i = gl_GlobalInvocationID.x;
    vec4 a = q[2u * i]; vec4 b = q[2u * i + 1u];
    r[2u * i] = vec4(atlas_sh_diffuse(a.xyz, sh, lam), atlas_env_level(b.x, b.y));
    r[2u * i + 1u] = vec4(atlas_env_uv(a.xyz, a.w), 0.0, 0.0);
}
""",
    "hlsl": """INCLUDE
[[vk::binding(0, 0)]] StructuredBuffer<float4> src;
[[vk::binding(1, 0)]] RWStructuredBuffer<float4> r;
[numthreads(64, 1, 1)]
void main(uint3 gid : SV_DispatchThreadID) {
    uint i = gid.x;
    float4 sh[25]; float4 lam[5];
    for (uint k = 0u; k < 25u; k = k + 1u) { sh[k] = src[k]; }
    for (uint l = 0u; l < 5u; l = l + 1u) { lam[l] = src[25u + l]; }
    float4 a = src[30u + 2u * i]; float4 b = src[31u + 2u * i];
    r[2u * i] = float4(atlas_sh_diffuse(a.xyz, sh, lam), atlas_env_level(b.x, b.y));
    r[2u * i + 1u] = float4(atlas_env_uv(a.xyz, a.w), 0.0, 0.0);
}
""",
}


def _program(lang: str) -> str:
    include = emit(lang, common_declarations() + environment_declarations())
    if lang == "wgsl":
        return include + SHADERS[lang]
    return SHADERS[lang].replace("INCLUDE", include)


def _module(lang: str, folder):
    code = _program(lang)
    if lang == "wgsl":
        return code
    source = folder / f"env.{lang}.comp"
    source.write_text(code)
    out = folder / f"env.{lang}.spv"
    args = ["-V", "-S", "comp"] if lang == "glsl" else ["-D", "-V", "-S", "comp", "-e", "main"]
    run = subprocess.run([GLSLANG, *args, str(source), "-o", str(out)], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    return out.read_bytes()


def _inputs():
    sh = RNG.normal(size=(K, 3))
    lam = RNG.normal(size=(SH_ORDER + 1, 3))
    n = RNG.normal(size=(N, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n[:4] = [[0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -0.999]]  # poles and seams
    n[3] /= np.linalg.norm(n[3])
    height = RNG.choice([4.0, 16.0, 128.0], size=N)
    gloss = RNG.uniform(-0.2, 1.2, size=N)
    levels = RNG.choice([2.0, 6.0], size=N)
    pad = np.zeros((K + SH_ORDER + 1, 1))
    q = np.empty((N, 2, 4))
    q[:, 0, :3], q[:, 0, 3] = n, height
    q[:, 1] = np.stack([gloss, levels, 0 * gloss, 0 * gloss], 1)
    data = np.concatenate([np.hstack([sh, pad[:K]]), np.hstack([lam, pad[: SH_ORDER + 1]]), q.reshape(-1, 4)])
    return data.astype("<f4"), sh, lam, n, height, gloss, levels


@pytest.mark.slow
@pytest.mark.parametrize("lang", LANGUAGES)
def test_the_environment_functions_compute_what_their_numpy_twins_do(lang, gpu_device, tmp_path):
    if lang != "wgsl" and GLSLANG is None:
        pytest.skip("glslangValidator (Debian glslang-tools) is not installed")
    data, sh, lam, n, height, gloss, levels = _inputs()
    words = run_compute(gpu_device, _module(lang, tmp_path), data.tobytes(), False, 8 * N)
    out = words.view("<f4").reshape(N, 2, 4).astype(np.float64)
    # (1/pi) sum_l lam_l sum_m L_lm Y_lm(n): the f32 sum against float64, relative to its terms' size.
    f32_sh = sh.astype(np.float32).astype(np.float64)
    f32_lam = lam.astype(np.float32).astype(np.float64)
    n32 = n.astype(np.float32).astype(np.float64)
    expected = np.maximum(evaluate_sh(f32_sh, n32, zonal=np.broadcast_to(f32_lam, (N, SH_ORDER + 1, 3))) / np.pi, 0.0)
    assert (expected == 0.0).any() and (expected > 0.0).any()  # random signs: the clamp is exercised
    size = np.abs(sh_basis(n32)) @ np.abs(f32_sh) * np.abs(f32_lam).max() / np.pi
    np.testing.assert_array_less(np.abs(out[:, 0, :3] - expected), 1e-5 * size + 1e-7)
    np.testing.assert_allclose(out[:, 0, 3], (1.0 - np.clip(gloss, 0.0, 1.0)) * (levels - 1.0), rtol=1e-6, atol=1e-6)
    # uv: the sampler's texel coordinates (u W - 1/2, v_tex H - 1/2) are Mitsuba's (column, row) of the direction.
    u, v = direction_to_uv(n32)
    width = 2.0 * height
    x, y = uv_to_texel(u, v, height.astype(int), width.astype(int))
    gx = np.mod(out[:, 1, 0] * width - 0.5, width)
    dx = np.abs(gx - x)
    at_pole = np.hypot(n32[:, 0], n32[:, 2]) == 0.0  # every column is the pole: u is any
    assert at_pole.sum() == 2
    np.testing.assert_array_less(np.minimum(dx, width - dx)[~at_pole], 1e-4 * width[~at_pole])
    np.testing.assert_array_less(np.abs(out[:, 1, 1] * height - 0.5 - y), 1e-4 * height)
    assert np.all((out[:, 1, 0] >= 0.0) & (out[:, 1, 0] <= 1.0))
