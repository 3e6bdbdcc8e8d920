"""Structs and constants shared with WGSL: layout rules, packing, generation, and the GPU's own reading.

Expected offsets are worked out by hand from the WGSL specification's "Memory Layout"
section (https://www.w3.org/TR/WGSL/#memory-layouts), not from the code under test. The
renderer's own structs (:mod:`atlasgen.render.layout`) serve as examples beside the spec's.
"""

from __future__ import annotations

import enum

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.render.layout import FRAME, LIGHT, OBJECT, LightType
from atlasgen.shaders.structs import (
    F32,
    I32,
    U32,
    Array,
    Field,
    Matrix,
    Scalar,
    Struct,
    Vector,
    mat3x3,
    mat4x4,
    uniform_violations,
    vec2,
    vec3,
    vec4,
    wgsl_constants,
)
from tests.shaders.gpu_compute import run_compute

# The specification's own example (WGSL, "Structure Member Layout"), its comments copied:
# struct A { u: f32 @0, v: f32 @4, w: vec2<f32> @8, x: f32 @16 }              align 8, size 24
# struct B { a: vec2<f32> @0, b: vec3<f32> @16, c: f32 @28, d: f32 @32, e: A @40,
#            f: vec3<f32> @64, g: array<A, 3> @80 (stride 24), h: i32 @152 }  align 16, size 160
SPEC_A = Struct("A", [Field("u", F32), Field("v", F32), Field("w", vec2()), Field("x", F32)])
SPEC_B = Struct(
    "B",
    [
        Field("a", vec2()),
        Field("b", vec3()),
        Field("c", F32),
        Field("d", F32),
        Field("e", SPEC_A),
        Field("f", vec3()),
        Field("g", Array(SPEC_A, 3)),
        Field("h", I32),
    ],
)

# Every kind of member at awkward places: vec3 then scalar, scalar then vec3, a padded
# matrix, an array whose elements need padding, integers of both signs.
MIXED = Struct(
    "Mixed",
    [
        Field("a", F32),
        Field("p", vec3()),
        Field("s", F32),
        Field("m", mat3x3),
        Field("t", vec2()),
        Field("k", I32),
        Field("arr", Array(vec3(), 2)),
        Field("u", U32),
        Field("q", vec3(U32)),
    ],
)


def test_spec_example_offsets():
    assert SPEC_A.offsets == {"u": 0, "v": 4, "w": 8, "x": 16}
    assert (SPEC_A.align, SPEC_A.size) == (8, 24)
    assert SPEC_B.offsets == {"a": 0, "b": 16, "c": 28, "d": 32, "e": 40, "f": 64, "g": 80, "h": 152}
    assert (SPEC_B.align, SPEC_B.size) == (16, 160)
    assert Array(SPEC_A, 3).stride == 24


def test_vec3_then_scalar_shares_its_16_bytes():
    # AlignOf(vec3<f32>) = 16 but SizeOf = 12: a following f32 fills the last 4 bytes.
    packed = Struct("S", [Field("p", vec3()), Field("s", F32)])
    assert packed.offsets == {"p": 0, "s": 12} and packed.size == 16
    # The other way round the vec3 moves to the next 16-byte boundary, and the size
    # rounds up from 28 to the struct's alignment, 16.
    spread = Struct("S", [Field("s", F32), Field("p", vec3())])
    assert spread.offsets == {"s": 0, "p": 16} and spread.size == 32


def test_matrices_are_padded_columns():
    # matCxR: C columns of vecR, each roundUp(AlignOf(vecR), SizeOf(vecR)) bytes apart.
    assert (mat4x4.align, mat4x4.size) == (16, 64)
    assert (mat3x3.align, mat3x3.size) == (16, 48)
    assert (Matrix(2, 2).align, Matrix(2, 2).size) == (8, 16)
    after_scalar = Struct("S", [Field("a", F32), Field("m", mat4x4)])
    assert after_scalar.offsets["m"] == 16 and after_scalar.size == 80
    m = np.arange(9, dtype=np.float32).reshape(3, 3) * 10 + 1  # m[row, col]
    words = np.frombuffer(mat3x3.encode(m), dtype=np.float32).reshape(3, 4)
    np.testing.assert_array_equal(words[:, :3], m.T)  # word block c is column c
    assert (words[:, 3] == 0).all()


def test_array_strides_round_up_to_the_element_alignment():
    assert (Array(vec3(), 4).stride, Array(vec3(), 4).size) == (16, 64)
    assert (Array(F32, 3).stride, Array(F32, 3).size) == (4, 12)
    assert (Array(vec2(), 3).align, Array(vec2(), 3).size) == (8, 24)
    words = np.frombuffer(Array(vec3(), 2).encode([[1, 2, 3], [4, 5, 6]]), dtype=np.float32)
    np.testing.assert_array_equal(words, [1, 2, 3, 0, 4, 5, 6, 0])


def test_mixed_struct_offsets():
    assert MIXED.offsets == {"a": 0, "p": 16, "s": 28, "m": 32, "t": 80, "k": 88, "arr": 96, "u": 128, "q": 144}
    assert (MIXED.align, MIXED.size) == (16, 160)


def test_uniform_rules_are_enforced():
    with pytest.raises(ValueError, match=r"B\.e: offset 40 is not a multiple of 16.*B\.g: array stride 24"):
        Struct("B", SPEC_B.fields, address_space="uniform")
    with pytest.raises(ValueError, match="array stride 4"):
        Struct("U", [Field("weights", Array(F32, 4))], address_space="uniform")
    # A struct member must be followed by roundUp(16, its size) bytes: A is 24 bytes, so
    # a member 24 bytes after it is too close even when aligned.
    spaced = [Field("first", vec4()), Field("a", Struct("A16", SPEC_A.fields)), Field("after", F32)]
    with pytest.raises(ValueError, match="next member 24 bytes on, needs 32"):
        Struct("U", spaced, address_space="uniform")
    assert Struct("U", [Field("lights", Array(vec4(), 4)), Field("n", U32)], address_space="uniform").size == 80


def _random_value(t, rng):
    """A value of WGSL type ``t`` with random, exactly representable components."""
    if isinstance(t, Struct):
        return {f.name: _random_value(f.type, rng) for f in t.fields}
    if isinstance(t, Array):
        return [_random_value(t.element, rng) for _ in range(t.count)]
    shape = (t.rows, t.columns) if isinstance(t, Matrix) else (t.count,) if isinstance(t, Vector) else ()
    scalar = F32 if isinstance(t, Matrix) else t.scalar if isinstance(t, Vector) else t
    if scalar is F32:
        return rng.standard_normal(shape).astype(np.float32)
    info = np.iinfo(scalar.dtype)
    return rng.integers(info.min, info.max, size=shape, endpoint=True, dtype=scalar.dtype)


def _assert_same(t, got, expected):
    if isinstance(t, Struct):
        assert set(got) == set(expected)
        for f in t.fields:
            _assert_same(f.type, got[f.name], expected[f.name])
    elif isinstance(t, Array):
        assert len(got) == len(expected)
        for g, e in zip(got, expected):
            _assert_same(t.element, g, e)
    else:
        np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("struct", [FRAME, OBJECT, LIGHT, SPEC_B, MIXED], ids=lambda s: s.name)
def test_pack_round_trips(struct):
    rng = np.random.default_rng(7)
    value = _random_value(struct, rng)
    data = struct.encode(value)
    assert len(data) == struct.size
    _assert_same(struct, struct.decode(data), value)
    assert struct.pack(**value) == data


def test_padding_is_zero():
    data = np.frombuffer(MIXED.encode(_random_value(MIXED, np.random.default_rng(1))), dtype=np.uint32)
    # Padding words: 1..3 after a, 11, 15, 19 closing the columns of m, 23 after k, 27, 31
    # in arr, 33..35 after u, 39 after q (the struct's end, rounded up to 16).
    padding = [1, 2, 3, 11, 15, 19, 23, 27, 31, 33, 34, 35, 39]
    assert (data[padding] == 0).all()
    assert (np.delete(data, padding) != 0).all()


def test_packing_rejects_mistakes():
    value = _random_value(LIGHT, np.random.default_rng(2))
    with pytest.raises(ValueError, match=r"missing members \['radiant'\]"):
        LIGHT.encode({k: v for k, v in value.items() if k != "radiant"})
    with pytest.raises(ValueError, match=r"unknown members \['colour'\]"):
        LIGHT.encode({**value, "colour": (1, 1, 1)})
    with pytest.raises(ValueError, match=r"expected shape \(3,\)"):
        LIGHT.encode({**value, "position": (1.0, 2.0, 3.0, 1.0)})
    with pytest.raises(TypeError, match="u32: expected integers"):
        LIGHT.encode({**value, "kind": 1.5})
    with pytest.raises(ValueError, match="u32: values outside"):
        LIGHT.encode({**value, "kind": -1})


_LEAF_TYPES = [F32, U32, I32, vec2(), vec3(), vec4(), vec3(U32), vec2(I32), mat3x3, mat4x4, Matrix(2, 3), Matrix(4, 2)]
_TYPES = st.recursive(
    st.sampled_from(_LEAF_TYPES),
    lambda inner: st.one_of(
        st.builds(Array, inner, st.integers(1, 3)),
        st.lists(inner, min_size=1, max_size=4).map(lambda ts: Struct("N", [Field(f"f{i}", t) for i, t in enumerate(ts)])),
    ),
    max_leaves=6,
)


@settings(max_examples=60, deadline=None)
@given(st.lists(_TYPES, min_size=1, max_size=6), st.integers(0, 2**32 - 1))
@pytest.mark.slow
def test_any_struct_lays_out_and_round_trips(types, seed):
    struct = Struct("S", [Field(f"f{i}", t) for i, t in enumerate(types)])
    end = 0
    for f in struct.fields:
        offset = struct.offsets[f.name]
        # Each member at the first offset past the previous one that its alignment allows.
        assert offset % f.type.align == 0 and end <= offset < end + f.type.align
        end = offset + f.type.size
    assert struct.size % struct.align == 0 and end <= struct.size < end + struct.align
    value = _random_value(struct, np.random.default_rng(seed))
    _assert_same(struct, struct.decode(struct.encode(value)), value)


def test_struct_text():
    text = LIGHT.wgsl()
    body = text[text.index("struct Light {") :]
    members = [line.split("//")[0].strip() for line in body.splitlines()[1:-1]]
    assert members == ["position: vec3<f32>,", "range: f32,", "radiant: vec3<f32>,", "index: u32,", "direction: vec3<f32>,",
                       "cos_outer: f32,", "cone: vec2<f32>,", "kind: u32,"]  # fmt: skip
    assert body.splitlines()[-1] == "};" and "size 64, align 16" in text


def test_enum_constants():
    assert wgsl_constants(LightType, "LIGHT_") == (
        "const LIGHT_DIRECTIONAL: u32 = 0u;\nconst LIGHT_POINT: u32 = 1u;\nconst LIGHT_SPOT: u32 = 2u;\n"
    )

    class Signed(enum.IntEnum):
        LOW = -2
        HIGH = 5

    assert wgsl_constants(Signed, "S_", I32) == "const S_LOW: i32 = -2i;\nconst S_HIGH: i32 = 5i;\n"
    with pytest.raises(TypeError):
        wgsl_constants(Signed, "S_", F32)


# ---- the GPU reads the packed bytes back ----------------------------------------------


def _leaves(t, expr: str, value):
    """(WGSL expression, expected u32 bit pattern) of every scalar inside a value of type ``t``."""
    if isinstance(t, Struct):
        for f in t.fields:
            yield from _leaves(f.type, f"{expr}.{f.name}", value[f.name])
    elif isinstance(t, Array):
        for i, v in enumerate(value):
            yield from _leaves(t.element, f"{expr}[{i}]", v)
    elif isinstance(t, Matrix):
        for c in range(t.columns):  # WGSL m[c] is column c: maths entry (row r, column c)
            for r in range(t.rows):
                yield f"{expr}[{c}][{r}]", np.asarray(value[r][c], dtype=F32.dtype).view("<u4")
    elif isinstance(t, Vector):
        for i in range(t.count):
            yield f"{expr}[{i}]", np.asarray(value[i], dtype=t.scalar.dtype).view("<u4")
    else:
        assert isinstance(t, Scalar)
        yield expr, np.asarray(value, dtype=t.dtype).view("<u4")


def _read_on_gpu(ctx, t, value, space: str, declarations: str):
    """Bind ``t.encode(value)`` as ``space``; a compute shader copies every scalar out in order."""
    leaves = list(_leaves(t, "src", value))
    body = "\n".join(f"    dst[{i}] = bitcast<u32>({expr});" for i, (expr, _) in enumerate(leaves))
    var = "var<uniform>" if space == "uniform" else "var<storage, read>"
    code = (
        f"{declarations}\n"
        f"@group(0) @binding(0) {var} src: {t.name};\n"
        "@group(0) @binding(1) var<storage, read_write> dst: array<u32>;\n"
        f"@compute @workgroup_size(1)\nfn main() {{\n{body}\n}}\n"
    )
    got = run_compute(ctx, code, t.encode(value), space == "uniform", len(leaves))
    return got, np.array([bits for _, bits in leaves], dtype="<u4"), [expr for expr, _ in leaves]


CASES = {
    "Frame": (FRAME, "uniform", [FRAME]),
    "Object": (OBJECT, "uniform", [OBJECT]),
    "Light": (Array(LIGHT, 3), "storage", [LIGHT]),
    "spec-B": (SPEC_B, "storage", [SPEC_A, SPEC_B]),
    "Mixed": (MIXED, "storage", [MIXED]),
}


@pytest.mark.gpu
@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.slow
def test_gpu_reads_what_was_packed(case, gpu_device):
    t, space, structs = CASES[case]
    value = _random_value(t, np.random.default_rng(11))
    declarations = "".join(s.wgsl() for s in structs)
    got, expected, exprs = _read_on_gpu(gpu_device, t, value, space, declarations)
    wrong = [f"{e}: {g:#010x} != {x:#010x}" for e, g, x in zip(exprs, got, expected) if g != x]
    assert not wrong, f"{len(wrong)} of {len(exprs)} scalars differ, first: {wrong[:3]}"


@pytest.mark.gpu
@pytest.mark.slow
def test_gpu_agrees_on_uniform_rules(gpu_device):
    import wgpu

    a16 = Struct("A16", SPEC_A.fields)
    cases = [
        ([SPEC_A, SPEC_B], SPEC_B),
        ([], Struct("W", [Field("weights", Array(F32, 4))])),
        ([a16], Struct("Spaced", [Field("first", vec4()), Field("a", a16), Field("after", F32)])),
        ([a16], Struct("Roomy", [Field("first", vec4()), Field("a", a16), Field("after", vec4())])),
        ([], FRAME),
        ([], MIXED),
    ]
    verdicts = []
    for needed, struct in cases:
        code = (
            "".join(s.wgsl() for s in needed if s is not struct) + struct.wgsl()
            + f"@group(0) @binding(0) var<uniform> src: {struct.name};\n"
            + "@compute @workgroup_size(1)\nfn main() {\n    let copy = src;\n}\n"
        )  # fmt: skip
        try:
            gpu_device.device.create_shader_module(code=code)
            accepted = True
        except wgpu.GPUValidationError:
            accepted = False
        verdicts.append((struct.name, accepted, not uniform_violations(struct)))
    gpu_device.take_errors()
    assert [v[1] for v in verdicts] == [v[2] for v in verdicts], verdicts
    assert [v[2] for v in verdicts] == [False, False, False, True, True, True]


def _read_texels_on_gpu(ctx, struct, values):
    """Upload ``struct.pack_array(values)`` as an rgba32uint texture, a row per element, and copy
    every scalar of every element out through the generated ``texel_reader_wgsl``."""
    import wgpu

    leaves = [list(_leaves(struct, f"e{i}", v)) for i, v in enumerate(values)]
    body = "".join(f"    let e{i} = read_element({i}u);\n" for i in range(len(values)))
    flat = [leaf for element in leaves for leaf in element]
    body += "\n".join(f"    dst[{k}] = bitcast<u32>({expr});" for k, (expr, _) in enumerate(flat))
    code = (
        struct.wgsl()
        + "@group(0) @binding(0) var elements: texture_2d<u32>;\n"
        + "@group(0) @binding(1) var<storage, read_write> dst: array<u32>;\n"
        + struct.texel_reader_wgsl("read_element", "elements")
        + f"@compute @workgroup_size(1)\nfn main() {{\n{body}\n}}\n"
    )
    device = ctx.device
    data = struct.pack_array(values)
    size = (struct.size // 16, len(values), 1)
    texture = device.create_texture(
        size=size, format=wgpu.TextureFormat.rgba32uint, usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST
    )
    device.queue.write_texture({"texture": texture}, data, {"bytes_per_row": struct.size, "rows_per_image": len(values)}, size)
    dst = device.create_buffer(size=4 * len(flat), usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)
    pipeline = device.create_compute_pipeline(
        layout="auto", compute={"module": device.create_shader_module(code=code), "entry_point": "main"}
    )
    group = device.create_bind_group(
        layout=pipeline.get_bind_group_layout(0),
        entries=[{"binding": 0, "resource": texture.create_view()}, {"binding": 1, "resource": {"buffer": dst}}],
    )
    encoder = device.create_command_encoder()
    compute = encoder.begin_compute_pass()
    compute.set_pipeline(pipeline)
    compute.set_bind_group(0, group)
    compute.dispatch_workgroups(1)
    compute.end()
    device.queue.submit([encoder.finish()])
    got = np.frombuffer(device.queue.read_buffer(dst), dtype="<u4")
    return got, np.array([bits for _, bits in flat], dtype="<u4"), [expr for expr, _ in flat]


@pytest.mark.gpu
@pytest.mark.slow
def test_gpu_texel_reader_reads_what_was_packed(gpu_device):
    """The lighting pass reads its lights from texture rows, not a storage buffer: every member of
    every row must come back bit for bit, including the u32 ``kind`` between two bitcast floats."""
    rng = np.random.default_rng(5)
    values = [_random_value(LIGHT, rng) for _ in range(4)]
    got, expected, exprs = _read_texels_on_gpu(gpu_device, LIGHT, values)
    gpu_device.take_errors()
    wrong = [f"{e}: {g:#010x} != {x:#010x}" for e, g, x in zip(exprs, got, expected) if g != x]
    assert not wrong, f"{len(wrong)} of {len(exprs)} scalars differ, first: {wrong[:3]}"


def test_texel_reader_refuses_what_texels_cannot_hold():
    # WGSL alignment keeps every scalar and vector inside one 16-byte texel; only a size that is
    # not whole texels, or a matrix, array or nested struct member, cannot be read this way.
    with pytest.raises(ValueError, match="not a whole number"):
        Struct("Odd", [Field("a", vec2())]).texel_reader_wgsl("f", "t")
    with pytest.raises(ValueError, match="within one texel"):
        Struct("Mat", [Field("m", mat4x4)]).texel_reader_wgsl("f", "t")
    with pytest.raises(ValueError, match="within one texel"):
        Struct("Arr", [Field("w", Array(vec4(), 2))]).texel_reader_wgsl("f", "t")
    text = LIGHT.texel_reader_wgsl("read_light", "light_texels")
    assert text.count("textureLoad(light_texels") == LIGHT.size // 16
    assert "bitcast<vec3<f32>>(t0.xyz), bitcast<f32>(t0.w), bitcast<vec3<f32>>(t1.xyz), t1.w," in text
    # Texels fetched elsewhere, a later one through a word of an earlier one.
    text = LIGHT.texel_reader_wgsl("f", fetch=lambda i: f"g(k, {i}u)" if i < 2 else f"g(t1.w, {i}u)", params="k: u32")
    assert "fn f(k: u32) -> Light {" in text and "let t1 = g(k, 1u);" in text and "let t3 = g(t1.w, 3u);" in text
