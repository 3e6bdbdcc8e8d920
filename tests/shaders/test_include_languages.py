"""The include in WGSL, GLSL and HLSL: one description, each compiles, each samples what the CPU samples.

GLSL and HLSL are compiled to SPIR-V with glslang and run through wgpu (lavapipe) next
to the WGSL, on a small baked library (a lambert, a toon with hard steps, a separable).
"""

import hashlib
import re
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.io.sidecar import SIDECAR_MAGIC
from atlasgen.materials.material import read_materials
from atlasgen.optics.interpolation import sample_slice
from atlasgen.optics.specular import specular_f_cos
from atlasgen.separable.rebuild import evaluate_separable
from atlasgen.shaders.lang import LANGUAGES
from atlasgen.shaders.separable import separable_table

ROOT = Path(__file__).resolve().parents[2]
GLSLANG = shutil.which("glslangValidator")
needs_glslang = pytest.mark.skipif(GLSLANG is None, reason="glslangValidator (Debian glslang-tools) is not installed")

# Query i: q[3i] = (n, material), q[3i+1] = (l, mode), q[3i+2] = (v, gloss). Mode 0: atlas_sample at
# (N.L, N.V) = (n.x, n.y); mode 1: separable_f_cos(n, l, v); mode 2: the renderer's specular lobe,
# specular(n, l, v, specular_alpha(gloss)).
SHADERS = {
    "wgsl": """
@group(0) @binding(0) var atlas_tex: texture_2d_array<f32>;
@group(0) @binding(1) var atlas_samp: sampler;
@group(0) @binding(2) var<storage, read> q: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> r: array<vec4<f32>>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (i >= arrayLength(&r)) { return; }
    let a = q[3u * i]; let b = q[3u * i + 1u]; let c = q[3u * i + 2u];
    let m = u32(a.w);
    if (b.w > 1.5) { r[i] = vec4<f32>(specular(a.xyz, b.xyz, c.xyz, specular_alpha(c.w)), 0.0, 0.0, 0.0); }
    else if (b.w > 0.5) { r[i] = vec4<f32>(separable_f_cos(atlas_tex, atlas_samp, m, a.xyz, b.xyz, c.xyz), 0.0); }
    else { r[i] = atlas_sample(atlas_tex, atlas_samp, m, a.x, a.y, 0.0); }
}
""",
    "glsl": """#version 450
#extension GL_GOOGLE_include_directive : require
#include "atlas.glsl"
layout(set = 0, binding = 0) uniform texture2DArray atlas_tex;
layout(set = 0, binding = 1) uniform sampler atlas_samp;
layout(std430, set = 0, binding = 2) readonly buffer Queries { vec4 q[]; };
layout(std430, set = 0, binding = 3) buffer Results { vec4 r[]; };
layout(local_size_x = 64) in;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= uint(r.length())) { return; }
    vec4 a = q[3u * i]; vec4 b = q[3u * i + 1u]; vec4 c = q[3u * i + 2u];
    uint m = uint(a.w);
    if (b.w > 1.5) { r[i] = vec4(specular(a.xyz, b.xyz, c.xyz, specular_alpha(c.w)), 0.0, 0.0, 0.0); }
    else if (b.w > 0.5) { r[i] = vec4(separable_f_cos(atlas_tex, atlas_samp, m, a.xyz, b.xyz, c.xyz), 0.0); }
    else { r[i] = atlas_sample(atlas_tex, atlas_samp, m, a.x, a.y, 0.0); }
}
""",
    "hlsl": """#include "atlas.hlsl"
[[vk::binding(0, 0)]] Texture2DArray<float4> atlas_tex;
[[vk::binding(1, 0)]] SamplerState atlas_samp;
[[vk::binding(2, 0)]] StructuredBuffer<float4> q;
[[vk::binding(3, 0)]] RWStructuredBuffer<float4> r;
[numthreads(64, 1, 1)]
void main(uint3 gid : SV_DispatchThreadID) {
    uint i = gid.x;
    uint count, stride;
    r.GetDimensions(count, stride);
    if (i >= count) { return; }
    float4 a = q[3u * i]; float4 b = q[3u * i + 1u]; float4 c = q[3u * i + 2u];
    uint m = uint(a.w);
    if (b.w > 1.5) { r[i] = float4(specular(a.xyz, b.xyz, c.xyz, specular_alpha(c.w)), 0.0, 0.0, 0.0); }
    else if (b.w > 0.5) { r[i] = float4(separable_f_cos(atlas_tex, atlas_samp, m, a.xyz, b.xyz, c.xyz), 0.0); }
    else { r[i] = atlas_sample(atlas_tex, atlas_samp, m, a.x, a.y, 0.0); }
}
""",
}


@pytest.fixture(scope="module")
def small_atlas(tmp_path_factory):
    """A linear (UNORM) atlas of a lambert, a toon and two separable materials, one a back-lit film
    with a transmission slice after its terms, written to disk."""
    folder = tmp_path_factory.mktemp("languages")
    names = ("terracotta", "toon-hero", "separable-plastic")
    film = folder / "film.toml"
    film.write_text(
        'type = "separable"\nsource = "thin_film"\nalpha = 0.3\nterms = 2\n'
        "film = { thickness = 420.0, film_ior = 1.45, base_ior = 1.8, backlight = 1.5, backlight_colour = [0.5, 0.8, 1.0] }\n"
    )
    materials = read_materials([*(ROOT / "materials" / f"{n}.toml" for n in names), film])
    result = bake_atlas(materials, "array", True, {})
    paths = write_bake(result, folder / "atlas.dds")
    return result, paths


def _spirv(lang: str, folder: Path, code: str | None = None, name: str = "test") -> bytes:
    source = folder / f"{name}.{lang}.comp"
    source.write_text(SHADERS[lang] if code is None else code)
    out = folder / f"{name}.{lang}.spv"
    args = ["-V", "-S", "comp"] if lang == "glsl" else ["-D", "-V", "-S", "comp", "-e", "main"]
    run = subprocess.run([GLSLANG, *args, str(source), "-o", str(out)], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    return out.read_bytes()


@pytest.mark.slow
def test_every_language_comes_from_the_one_description(small_atlas):
    result, paths = small_atlas
    texts = {"wgsl": result.include, **result.includes}
    assert sorted(texts) == sorted(LANGUAGES)
    for key in ("include", "glsl", "hlsl"):
        first, rest = paths[key].read_text().split("\n", 1)
        assert rest == texts["wgsl" if key == "include" else key]
        assert first == "// atlasgen manifest sha256: " + hashlib.sha256(paths["manifest"].read_bytes()).hexdigest()
    # The same functions, constants and table rows in each language.
    for name in (
        "atlas_uv",
        "atlas_sample",
        "atlas_scale_bias",
        "specular_alpha",
        "separable_f_cos",
        "MATERIAL_TERRACOTTA",
        "SEPARABLE_TABLE",
        "ATLAS_FLAG_NEAREST",
    ):
        assert all(name in text for text in texts.values()), name
    spelling = {"wgsl": "vec4<f32>(", "glsl": "vec4(", "hlsl": "float4("}
    rows = {lang: text.count(spelling[lang]) for lang, text in texts.items()}
    assert len(set(rows.values())) == 1, rows


@pytest.mark.slow
def test_sidecar_is_the_include_table_little_endian(small_atlas):
    result, paths = small_atlas
    data = paths["separable"].read_bytes()
    magic, (version, rows, digest_length) = data[:4], struct.unpack("<3I", data[4:16])
    assert magic == SIDECAR_MAGIC and version == 2 and digest_length == 32 and len(data) == 48 + 16 * rows
    assert data[16:48] == hashlib.sha256(paths["manifest"].read_bytes()).digest()
    table = np.frombuffer(data[48:], "<f4").reshape(rows, 4)
    np.testing.assert_array_equal(table, separable_table(result.manifest.materials))
    separable = sorted((m for m in result.manifest.materials if m.factors is not None), key=lambda m: m.first_slice)
    assert table[0, 0] == len(separable) == 2
    for row, entry in zip(table[1:3], separable):
        assert row[0] == entry.first_slice and row[2] == len(entry.factors.factor_scale)
        # w: the transmission slice's RGB scale (the back-lit film), else 0.
        back = entry.factors.transmission
        assert row[3] == (0.0 if back is None else np.float32(entry.scale[back.slice][0])) and (back is None) == (row[3] == 0)


@needs_glslang
@pytest.mark.parametrize("lang", ["glsl", "hlsl"])
@pytest.mark.slow
def test_glslang_compiles_the_include(lang, small_atlas):
    _, paths = small_atlas
    spirv = _spirv(lang, paths["dds"].parent)
    assert spirv[:4] == struct.pack("<I", 0x07230203)


# The shading line the docs give engines, compiled against the include alone (the include must define
# every name the line uses) and in a program that has its own PI, as most engines do and atlasgen's
# renderer did (the include's names must not clash with it: WGSL forbids declaring a name twice).
DOCUMENTED = ("docs/engine-integration.md", "docs/atlas-format.md")
_SHADING_LINE = re.compile(r"`(L \+= E \* \(albedo \* A\.rgb [^`]*)`")
SHADING_PROGRAMS = {
    "wgsl": """
OWN_PI
@group(0) @binding(0) var atlas_tex: texture_2d_array<f32>;
@group(0) @binding(1) var atlas_samp: sampler;
@group(0) @binding(2) var<storage, read_write> r: array<vec4<f32>>;
@compute @workgroup_size(1)
fn main() {
    let n = vec3<f32>(0.0, 0.0, 1.0); let l = vec3<f32>(0.6, 0.0, 0.8); let v = vec3<f32>(0.0, 0.6, 0.8);
    let E = vec3<f32>(2.0); let albedo = vec3<f32>(0.8); let gloss = 0.5;
    let A = atlas_sample(atlas_tex, atlas_samp, 0u, dot(n, l), dot(n, v), 0.0);
    var L = vec3<f32>(0.0);
    SHADING;
    r[0] = vec4<f32>(L, 1.0);
}
""",
    "glsl": """#version 450
#extension GL_GOOGLE_include_directive : require
#include "atlas.glsl"
OWN_PI
layout(set = 0, binding = 0) uniform texture2DArray atlas_tex;
layout(set = 0, binding = 1) uniform sampler atlas_samp;
layout(std430, set = 0, binding = 2) buffer Results { vec4 r[]; };
layout(local_size_x = 1) in;
void main() {
    vec3 n = vec3(0.0, 0.0, 1.0); vec3 l = vec3(0.6, 0.0, 0.8); vec3 v = vec3(0.0, 0.6, 0.8);
    vec3 E = vec3(2.0); vec3 albedo = vec3(0.8); float gloss = 0.5;
    vec4 A = atlas_sample(atlas_tex, atlas_samp, 0u, dot(n, l), dot(n, v), 0.0);
    vec3 L = vec3(0.0);
    SHADING;
    r[0] = vec4(L, 1.0);
}
""",
    "hlsl": """#include "atlas.hlsl"
OWN_PI
[[vk::binding(0, 0)]] Texture2DArray<float4> atlas_tex;
[[vk::binding(1, 0)]] SamplerState atlas_samp;
[[vk::binding(2, 0)]] RWStructuredBuffer<float4> r;
[numthreads(1, 1, 1)]
void main() {
    float3 n = float3(0.0, 0.0, 1.0); float3 l = float3(0.6, 0.0, 0.8); float3 v = float3(0.0, 0.6, 0.8);
    float3 E = float3(2.0, 2.0, 2.0); float3 albedo = float3(0.8, 0.8, 0.8); float gloss = 0.5;
    float4 A = atlas_sample(atlas_tex, atlas_samp, 0u, dot(n, l), dot(n, v), 0.0);
    float3 L = float3(0.0, 0.0, 0.0);
    SHADING;
    r[0] = float4(L, 1.0);
}
""",
}


OWN_PI = {
    "wgsl": "const PI: f32 = 3.1415927;",
    "glsl": "const float PI = 3.1415927;",
    "hlsl": "static const float PI = 3.1415927;",
}


def shading_program(lang: str, own_pi: bool) -> str:
    return SHADING_PROGRAMS[lang].replace("OWN_PI", OWN_PI[lang] if own_pi else "").replace("SHADING", documented_shading())


def documented_shading() -> str:
    """The one shading line both docs give, as written there."""
    found = {doc: _SHADING_LINE.findall((ROOT / doc).read_text()) for doc in DOCUMENTED}
    assert all(found.values()), f"no shading line in {[doc for doc, lines in found.items() if not lines]}"
    lines = {line for doc_lines in found.values() for line in doc_lines}
    assert len(lines) == 1, lines
    return lines.pop()


@needs_glslang
@pytest.mark.parametrize("own_pi", [False, True], ids=["include-alone", "own-pi"])
@pytest.mark.parametrize("lang", ["glsl", "hlsl"])
@pytest.mark.slow
def test_glslang_compiles_the_documented_shading(lang, own_pi, small_atlas):
    _, paths = small_atlas
    spirv = _spirv(lang, paths["dds"].parent, shading_program(lang, own_pi), f"shading-{own_pi}")
    assert spirv[:4] == struct.pack("<I", 0x07230203)


@pytest.mark.parametrize("own_pi", [False, True], ids=["include-alone", "own-pi"])
@pytest.mark.slow
def test_naga_compiles_the_documented_shading(own_pi, small_atlas, gpu_device):
    result, _ = small_atlas
    gpu_device.device.create_shader_module(label="shading", code=result.include + shading_program("wgsl", own_pi))


def _queries(result, rng):
    """Random (N.L, N.V) points on the LUT materials and random frames on the separable one."""
    lut = [m for m in result.manifest.materials if m.factors is None]
    sep = [m for m in result.manifest.materials if m.factors is not None]
    rows, expected_kind = [], []
    for m in lut:
        nl, nv = rng.uniform(-1.0, 1.0, 400), rng.uniform(0.0, 1.0, 400)
        for s in m.slices:
            for a, b in zip(nl, nv):
                rows += [(a, b, 0.0, s), (0, 0, 0, 0.0), (0, 0, 0, 0)]
            expected_kind.append(("lut", m, s, nl, nv))
    n, l, v = _random_frames(rng, 1500)
    for m in sep:
        if m.factors.transmission is not None:  # half the lights behind the surface: the transmission slice
            l = l.copy()
            l[::2] -= 2.0 * (n[::2] * l[::2]).sum(1, keepdims=True) * n[::2]
        for i in range(len(n)):
            rows += [(*n[i], m.first_slice), (*l[i], 1.0), (*v[i], 0.0)]
        expected_kind.append(("sep", m, m.first_slice, (n, l, v), None))
    # The specular lobe from rough to the roughness floor, on random frames and on mirror
    # configurations (l the reflection of v, nudged), where a narrow lobe peaks.
    n, l, v = _random_frames(rng, 1200)
    mirror = 2.0 * (n * v).sum(1, keepdims=True) * n - v + 0.01 * rng.normal(size=v.shape)
    l[:600] = mirror[:600] / np.linalg.norm(mirror[:600], axis=1, keepdims=True)
    gloss = rng.choice([0.0, 0.3, 0.5, 0.7, 0.9, 1.0], len(n))
    for i in range(len(n)):
        rows += [(*n[i], 0.0), (*l[i], 2.0), (*v[i], gloss[i])]
    expected_kind.append(("spec", None, None, (n, l, v), gloss))
    return np.asarray(rows, np.float32), expected_kind


def _random_frames(rng, count):
    """Unit n, and l, v above its horizon (cosines >= 0.02: away from grazing, where f32 and f64 angles
    may pick different texels)."""

    def unit(x):
        return x / np.linalg.norm(x, axis=1, keepdims=True)

    n = unit(rng.normal(size=(count, 3)))
    out = []
    for _ in range(2):
        d = unit(rng.normal(size=(count, 3)))
        d = np.where((d * n).sum(1, keepdims=True) < 0.0, -d, d)
        out.append(unit(d + 0.02 * n))
    return n, out[0], out[1]


def _dispatch(ctx, level0, queries, lang, code, texture=None):
    """Run ``code`` over ``queries`` with ``level0`` bound as a 2D array, or as ``texture`` (a 3D one) where given."""
    import wgpu

    device = ctx.device
    layers = level0.shape[0]
    volume = texture is not None
    if texture is None:
        texture = device.create_texture(size=(64, 32, layers), format=wgpu.TextureFormat.rgba8unorm, dimension="2d",
                                        usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST)  # fmt: skip
    device.queue.write_texture({"texture": texture, "origin": (0, 0, 0)}, np.ascontiguousarray(level0).tobytes(),
                               {"bytes_per_row": 64 * 4, "rows_per_image": 32}, (64, 32, layers))  # fmt: skip
    sampler = device.create_sampler(mag_filter="linear", min_filter="linear", address_mode_u="clamp-to-edge",
                                    address_mode_v="clamp-to-edge")  # fmt: skip
    count = len(queries) // 3
    q_buf = device.create_buffer_with_data(data=queries.tobytes(), usage=wgpu.BufferUsage.STORAGE)
    r_buf = device.create_buffer(size=count * 16, usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)
    module = device.create_shader_module(label=f"include-{lang}", code=code)
    pipeline = device.create_compute_pipeline(layout="auto", compute={"module": module, "entry_point": "main"})
    bind = device.create_bind_group(layout=pipeline.get_bind_group_layout(0), entries=[
        {"binding": 0, "resource": texture.create_view(dimension="3d" if volume else "2d-array")},
        {"binding": 1, "resource": sampler},
        {"binding": 2, "resource": {"buffer": q_buf, "offset": 0, "size": q_buf.size}},
        {"binding": 3, "resource": {"buffer": r_buf, "offset": 0, "size": r_buf.size}},
    ])  # fmt: skip
    encoder = device.create_command_encoder()
    compute = encoder.begin_compute_pass()
    compute.set_pipeline(pipeline)
    compute.set_bind_group(0, bind)
    compute.dispatch_workgroups((count + 63) // 64)
    compute.end()
    device.queue.submit([encoder.finish()])
    return np.frombuffer(device.queue.read_buffer(r_buf), np.float32).reshape(count, 4)


@pytest.mark.gpu
@pytest.mark.parametrize("lang", LANGUAGES)
@pytest.mark.slow
def test_each_language_samples_what_the_cpu_samples(lang, small_atlas, gpu_device):
    from atlasgen.io.dds import read_dds

    result, paths = small_atlas
    if lang == "wgsl":
        code = result.include + SHADERS["wgsl"]
    else:
        if GLSLANG is None:
            pytest.skip("glslangValidator (Debian glslang-tools) is not installed")
        code = _spirv(lang, paths["dds"].parent)
    dds = read_dds(paths["dds"])
    level0 = np.asarray(dds.levels[0])
    queries, kinds = _queries(result, np.random.default_rng(3))
    got = _dispatch(gpu_device, level0, queries, lang, code)
    assert gpu_device.take_errors() == []
    row = 0
    for kind, m, s, a, b in kinds:
        if kind == "spec":
            count = len(b)
            # The same f32 vectors the GPU read, in float64, through the NumPy lobe.
            q = queries.reshape(-1, 3, 4)[row : row + count].astype(np.float64)
            n, l, v = q[:, 0, :3], q[:, 1, :3], q[:, 2, :3]
            h = l + v
            nh = (n * h).sum(1) / np.linalg.norm(h, axis=1)
            cpu = np.array([specular_f_cos(g, nl, nv, x) for g, nl, nv, x in zip(q[:, 2, 3], (n * l).sum(1), (n * v).sum(1), nh)])
            gpu = got[row : row + count, 0]
            assert cpu.max() > 1000.0  # the floor's peak is 1 / (pi alpha^2) V N.L: the narrow lobes were hit
            # At the roughness floor (alpha^2 = 4e-6) an f32 unit vector's own rounding (|n|^2 = 1 +- 1e-7)
            # moves D by a few percent near its peak; elsewhere the shader is the NumPy lobe to 0.5%.
            floor = q[:, 2, 3] == 1.0
            np.testing.assert_allclose(gpu[~floor], cpu[~floor], rtol=5e-3, atol=1e-5 * cpu.max(), err_msg=lang)
            np.testing.assert_allclose(gpu[floor], cpu[floor], rtol=5e-2, atol=1e-5 * cpu.max(), err_msg=lang)
            row += count
            continue
        if kind == "lut":
            count = len(a)
            table = level0[s].astype(np.float64) / 255.0
            texel = sample_slice(table, a, b, nearest=bool(m.flag("nearest")))
            gpu = got[row : row + count]
            # The GPU result is texel * scale + bias; undo it with the include's own constants.
            sb = np.asarray(_scale_bias(result.include, s))
            gpu_texel = np.concatenate([(gpu[:, :3] - sb[2]) / sb[0], ((gpu[:, 3] - sb[3]) / sb[1])[:, None]], axis=1)
            assert np.abs(gpu_texel - texel).max() <= 1.0 / 255.0, (lang, m.name, s)
        else:
            count = len(a[0])
            gpu = got[row : row + count, :3]
            cpu = evaluate_separable(paths["dds"], m.name, *a, cosine=True)
            scale = np.abs(cpu).max()
            diff = np.abs(gpu - cpu)
            # GPUs filter with 8-bit weight fractions: 1.5% of the largest value at worst (measured 1.1%,
            # identical in the three languages), the bulk far tighter.
            assert diff.max() <= 0.015 * scale, (lang, m.name, diff.max(), scale)
            if m.factors.transmission is None:
                assert np.median(diff) <= 2e-4 * scale, (lang, m.name)
            else:
                # The film's hue swings from texel to texel, so 8-bit filter weights err more on its terms
                # (median 6e-4 of the peak, measured) than on a plastic's. Its light from behind, the
                # transmission slice, is held to the same bounds against its own peak.
                n, l, v = a
                below = (n * l).sum(1) < 0.0
                back = np.abs(cpu[below]).max()
                assert below.sum() > 500 and back > 0.0
                assert diff[below].max() <= 0.015 * back and np.median(diff[below]) <= 2e-3 * back, (lang, m.name)
        row += count
    assert row == len(got)


def _scale_bias(include: str, s: int):
    match = re.search(rf"case {s}u: {{ return vec4<f32>\(([^)]*)\); }}", include)
    return [float(x) for x in match.group(1).split(",")] if match else [1.0, 1.0, 0.0, 0.0]


def _volume_code(lang: str) -> str:
    """The compute shader of :data:`SHADERS` binding a volume (Texture3D) atlas instead of a 2D array."""
    swap = {"wgsl": ("texture_2d_array<f32>", "texture_3d<f32>"), "glsl": ("texture2DArray", "texture3D"),
            "hlsl": ("Texture2DArray<float4>", "Texture3D<float4>")}[lang]  # fmt: skip
    return SHADERS[lang].replace(*swap)


@pytest.mark.gpu
@pytest.mark.slow
@pytest.mark.parametrize("lang", LANGUAGES)
def test_a_volume_include_reads_separable_terms_as_the_array_include_does(lang, small_atlas, tmp_path, gpu_device):
    """A volume include's atlas_sample took a Texture3D while separable_f_cos took a 2D array, so one bound atlas
    could not be passed to both: the include did not compile. The model code now reads the volume at each layer's
    depth centre, where level 0 is the layer alone: every query, terms and LUT, gives the array include's value."""
    import wgpu

    from atlasgen.io.dds import read_dds

    result, paths = small_atlas
    materials = read_materials([Path(m.source) for m in result.manifest.materials])
    volume = bake_atlas(materials, "volume", True, {})
    vpaths = write_bake(volume, tmp_path / "atlas.dds")
    queries, _ = _queries(result, np.random.default_rng(4))
    level0 = np.asarray(read_dds(paths["dds"]).levels[0])
    array_values = _dispatch(gpu_device, level0, queries, "wgsl", result.include + SHADERS["wgsl"])
    if lang == "wgsl":
        code = volume.include + _volume_code("wgsl")
    else:
        if GLSLANG is None:
            pytest.skip("glslangValidator (Debian glslang-tools) is not installed")
        code = _spirv(lang, vpaths["dds"].parent, _volume_code(lang), "volume")
    device = gpu_device.device
    texture = device.create_texture(size=(64, 32, level0.shape[0]), format=wgpu.TextureFormat.rgba8unorm, dimension="3d",
                                    usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST)  # fmt: skip
    vlevel0 = np.asarray(read_dds(vpaths["dds"]).levels[0])
    assert np.array_equal(vlevel0, level0)  # level 0 holds the same texels in either layout
    got = _dispatch(gpu_device, vlevel0, queries, lang, code, texture=texture)
    assert gpu_device.take_errors() == []
    np.testing.assert_allclose(got, array_values, rtol=0, atol=1e-5 * max(1.0, float(np.abs(array_values).max())))
