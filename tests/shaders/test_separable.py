"""The separable rebuild's shader code: it compiles, and on a GPU it returns what the Python rebuild returns."""

import numpy as np
import pytest

from atlasgen.io.manifest import MaterialEntry, SeparableFactors
from atlasgen.separable.parametrization import PARAMETRIZATIONS, Parametrization, Warp
from atlasgen.separable.rebuild import evaluate_separable
from atlasgen.shaders.common import PI
from atlasgen.shaders.lang import emit
from atlasgen.shaders.separable import SIDECAR_VERSION, UNWARP, separable_table, separable_wgsl, wgsl_function_name
from tests.separable.separable_helpers import random_frames
from tests.shaders.gpu_compute import run_compute

COMPUTE = """
@group(0) @binding(0) var atlas_tex: texture_2d_array<f32>;
@group(0) @binding(1) var atlas_samp: sampler;
@group(0) @binding(2) var<storage, read> dirs: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> result: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= arrayLength(&result)) {
        return;
    }
    let n = dirs[3u * i].xyz;
    let l = dirs[3u * i + 1u].xyz;
    let v = dirs[3u * i + 2u].xyz;
    let material = u32(dirs[3u * i].w);
    result[i] = vec4<f32>(separable_f_cos(atlas_tex, atlas_samp, material, n, l, v), 0.0);
}
"""


def _entry(name, parametrization, target, first=0, terms=2):
    scale = [[[1.5, 1.0, 0.5], [2.0, 2.0, 2.0]]] * terms
    bias = [[[0.0, 0.0, 0.0], [-0.5, -0.25, 0.0]]] * terms
    factors = SeparableFactors(parametrization=parametrization, target=target, factor_scale=scale, factor_bias=bias)
    return MaterialEntry(name=name, id=first, constant=name.upper(), first_slice=first, slice_count=terms, type="separable",
                         factors=factors)  # fmt: skip


def test_include_is_one_generic_function_over_a_data_table():
    entries = [_entry("gold-film", "half_diff", "f_cos", 4), _entry("b", "in_out", "f_proxy", 9, 1)]
    text = separable_wgsl(entries)
    assert text.count("fn separable_f_cos(") == 1 and "gold" not in text and "textureSampleLevel" in text
    table = separable_table(entries)
    # Directory: (first slice, block row, terms); blocks: head, 3 axes, 4 rows per term.
    assert table[0].tolist() == [2, 1 + 2 + (4 + 4 * 2) + (4 + 4 * 1), 32, SIDECAR_VERSION]
    assert table[1].tolist() == [4, 3, 2, 0] and table[2].tolist() == [9, 3 + 12, 1, 0]
    assert table[3, :2].tolist() == [0, 0] and table[15, :2].tolist() == [1, 1]  # (system, target)
    np.testing.assert_array_equal(table[7:11, :3], np.float32([[1.5, 1.0, 0.5], [0, 0, 0], [2, 2, 2], [-0.5, -0.25, 0]]))
    # The data changes with a re-bake; the code does not.
    other = [_entry("gold-film", "in_out", "f_proxy", 4, 3)]
    assert separable_wgsl(other).split("var<private> SEPARABLE_TABLE")[0] == text.split("var<private> SEPARABLE_TABLE")[0]
    assert separable_wgsl(other).split("\n);\n", 1)[1] == text.split("\n);\n", 1)[1]
    assert separable_wgsl([]) == "" and wgsl_function_name("A-b c") == "a_b_c"


@pytest.mark.slow
def test_include_compiles_for_every_parametrization_and_target(gpu_device):
    entries = [
        _entry(f"m{i}_{t}", name, t, first=4 * i + (2 if t == "f_proxy" else 0))
        for i, name in enumerate(sorted(PARAMETRIZATIONS))
        for t in ("f_cos", "f_proxy")
    ]
    code = separable_wgsl(entries) + COMPUTE
    gpu_device.device.create_shader_module(code=code)


def _run(ctx, level0, srgb, include, n, l, v, material):
    import wgpu

    device = ctx.device
    layers = level0.shape[0]
    texture = device.create_texture(
        size=(64, 32, layers),
        format=wgpu.TextureFormat.rgba8unorm_srgb if srgb else wgpu.TextureFormat.rgba8unorm,
        usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST,
        dimension="2d",
    )
    device.queue.write_texture(
        {"texture": texture, "origin": (0, 0, 0)},
        np.ascontiguousarray(level0).tobytes(),
        {"bytes_per_row": 64 * 4, "rows_per_image": 32},
        (64, 32, layers),
    )
    sampler = device.create_sampler(
        mag_filter="linear", min_filter="linear", address_mode_u="clamp-to-edge", address_mode_v="clamp-to-edge"
    )
    count = len(n)
    dirs = np.zeros((count, 3, 4), np.float32)
    dirs[:, 0, :3], dirs[:, 1, :3], dirs[:, 2, :3] = n, l, v
    dirs[:, 0, 3] = material
    dirs_buf = device.create_buffer_with_data(data=dirs.tobytes(), usage=wgpu.BufferUsage.STORAGE)
    out_buf = device.create_buffer(size=count * 16, usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)
    module = device.create_shader_module(code=include + COMPUTE)
    pipeline = device.create_compute_pipeline(layout="auto", compute={"module": module, "entry_point": "main"})
    bind = device.create_bind_group(
        layout=pipeline.get_bind_group_layout(0),
        entries=[
            {"binding": 0, "resource": texture.create_view(dimension="2d-array")},
            {"binding": 1, "resource": sampler},
            {"binding": 2, "resource": {"buffer": dirs_buf, "offset": 0, "size": dirs_buf.size}},
            {"binding": 3, "resource": {"buffer": out_buf, "offset": 0, "size": out_buf.size}},
        ],
    )
    encoder = device.create_command_encoder()
    compute = encoder.begin_compute_pass()
    compute.set_pipeline(pipeline)
    compute.set_bind_group(0, bind)
    compute.dispatch_workgroups((count + 63) // 64)
    compute.end()
    device.queue.submit([encoder.finish()])
    return np.frombuffer(device.queue.read_buffer(out_buf), np.float32).reshape(count, 4)[:, :3]


def test_gpu_rebuild_matches_the_python_rebuild(gpu_device, separable_atlas):
    from atlasgen.io.dds import read_dds

    path, result = separable_atlas
    dds = read_dds(path)
    level0 = np.asarray(dds.levels[0])
    n, l, v = random_frames(3000, seed=11)
    # Keep away from exact grazing, where f32 and f64 angles may pick different texels.
    for entry in result.manifest.materials:
        if entry.factors is None:
            continue
        gpu = _run(gpu_device, level0, dds.dxgi_format == 29, result.include, n, l, v, entry.first_slice)
        cpu = evaluate_separable(path, entry.name, n, l, v, cosine=True)
        scale = np.abs(cpu).max()
        # GPUs filter with 8-bit weight fractions (D3D: >= 8 bits of sub-texel precision):
        # allow 1% of the largest value (measured: 0.3-0.4%), the bulk far tighter.
        diff = np.abs(gpu - cpu)
        assert diff.max() <= 0.01 * scale, (entry.name, diff.max(), scale)
        assert np.median(diff) <= 2e-4 * scale
        assert np.corrcoef(gpu.ravel(), cpu.ravel())[0, 1] > 0.999


@pytest.mark.gpu
@pytest.mark.parametrize("warp", list(Warp), ids=lambda w: w.name)
@pytest.mark.slow
def test_gpu_unwarp_code_means_the_same_warp(warp, gpu_device):
    # The include's separable_unwarp, called with Warp's code, against the numpy texel mapping.
    lo, hi = 0.0, 0.5 * np.pi
    angles = np.linspace(-0.1, hi + 0.1, 41, dtype=np.float32)
    lines = "\n".join(
        f"    dst[{i}] = bitcast<u32>(separable_unwarp(src[{i}], vec4<f32>(0.0, {lo!r}, {hi!r}, {int(warp)}.0)));"
        for i in range(41)
    )
    code = (
        f"{emit('wgsl', [PI, UNWARP])}\n@group(0) @binding(0) var<storage, read> src: array<f32, 41>;\n"
        "@group(0) @binding(1) var<storage, read_write> dst: array<u32>;\n"
        f"@compute @workgroup_size(1)\nfn main() {{\n{lines}\n}}\n"
    )
    got = run_compute(gpu_device, code, angles.tobytes(), False, 41).view(np.float32)
    expected = Parametrization("t", "half_diff", "theta_h", (("theta_h", warp.name.lower()),)).texel_of("theta_h", angles, 2)
    np.testing.assert_allclose(got, expected, atol=2e-6)
