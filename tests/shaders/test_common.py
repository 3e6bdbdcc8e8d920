"""The shared helpers: one half vector for every caller, and what it returns on either side of its threshold."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from atlasgen.io.manifest import MaterialEntry, SeparableFactors, read_manifest
from atlasgen.models import get_model
from atlasgen.models.separable import LUT_F_COS
from atlasgen.shaders.common import HALF_VECTOR, HALF_VECTOR_MIN_LENGTH2, common_declarations
from atlasgen.shaders.include import render_include
from atlasgen.shaders.lang import LANGUAGES, emit, float_literal
from atlasgen.shaders.separable import separable_declarations
from atlasgen.shaders.separable_analytic import analytic_declarations
from atlasgen.shaders.specular import specular_declarations
from tests.shaders.gpu_compute import run_compute

GOLDEN = Path(__file__).parents[1] / "resources" / "golden"


def _every_unit() -> list:
    """The declarations of every emitter that shades with a half vector, one separable material included."""
    factors = SeparableFactors(parametrization="half_diff", target="f_cos", factor_scale=[[[1.0] * 3, [1.0] * 3]],
                               factor_bias=[[[0.0] * 3, [0.0] * 3]])  # fmt: skip
    entry = MaterialEntry(name="m", id=0, constant="M", first_slice=0, slice_count=1, type="separable", factors=factors)
    return [*common_declarations(), *specular_declarations(), *separable_declarations([entry]), *analytic_declarations(),
            LUT_F_COS]  # fmt: skip


@pytest.mark.parametrize("lang", LANGUAGES)
def test_every_half_vector_is_the_helpers(lang):
    text = emit(lang, _every_unit())
    # The one sum l + v is the helper's; every unit that needs h calls it, none normalizes its own.
    assert len(re.findall(r"=\s*l \+ v;", text)) == 1 and "normalize(l + v)" not in text
    body = text[text.index(" atlas_half_vector(") :]
    assert body.index("l + v;") < body.index("}")
    assert text.count("atlas_half_vector(l, v, ") == 3  # the lobe, the separable angles, the analytic BRDF
    assert text.count(float_literal(HALF_VECTOR_MIN_LENGTH2)) == 1  # one threshold, the helper's


@pytest.mark.parametrize("lang", LANGUAGES)
def test_the_include_declares_the_helper_once_before_its_first_call(lang):
    manifest = read_manifest(GOLDEN / "array-srgb.json")
    text = render_include(manifest, np.ones((256, 2)), np.zeros((256, 2)), lang, models=get_model)
    declared = {"wgsl": "fn atlas_half_vector(", "glsl": "vec3 atlas_half_vector(", "hlsl": "float3 atlas_half_vector("}[lang]
    # GLSL and HLSL need a function declared before its first call.
    assert text.count(declared) == 1 and text.index(declared) < text.index("atlas_half_vector(l, v, ")


@pytest.mark.gpu
@pytest.mark.slow
def test_gpu_half_vector_is_the_normalized_sum_above_the_threshold_and_the_fallback_below(gpu_device):
    rng = np.random.default_rng(5)
    l = rng.normal(size=(40, 3))
    v = rng.normal(size=(40, 3))
    l, v = l / np.linalg.norm(l, axis=1, keepdims=True), v / np.linalg.norm(v, axis=1, keepdims=True)
    # Opposite pairs: exactly, and offset across the threshold |l + v| = 1e-6 (exact in f32: l.x + v.x = 0).
    offsets = [0.0, 2e-7, 9e-7, 1.1e-6, 4e-6, 1e-3]
    l = np.concatenate([l, np.tile([0.6, 0.0, 0.8], (len(offsets), 1))]).astype(np.float32)
    v = np.concatenate([v, -l[len(v) :] + np.array([[0.0, d, 0.0] for d in offsets])]).astype(np.float32)
    fallback = np.tile(np.float32([0.25, -0.5, 0.75]), (len(l), 1))
    src = np.zeros((len(l), 3, 4), np.float32)
    src[:, 0, :3], src[:, 1, :3], src[:, 2, :3] = l, v, fallback
    count = len(l)
    lines = "\n".join(
        f"    h = atlas_half_vector(src[{3 * i}].xyz, src[{3 * i + 1}].xyz, src[{3 * i + 2}].xyz);"
        f" dst[{3 * i}] = bitcast<u32>(h.x); dst[{3 * i + 1}] = bitcast<u32>(h.y); dst[{3 * i + 2}] = bitcast<u32>(h.z);"
        for i in range(count)
    )
    code = (
        f"{emit('wgsl', [HALF_VECTOR])}\n@group(0) @binding(0) var<storage, read> src: array<vec4<f32>, {3 * count}>;\n"
        "@group(0) @binding(1) var<storage, read_write> dst: array<u32>;\n"
        f"@compute @workgroup_size(1)\nfn main() {{\n    var h: vec3<f32>;\n{lines}\n}}\n"
    )
    got = run_compute(gpu_device, code, src.tobytes(), False, 3 * count).view(np.float32).reshape(count, 3)
    s = l.astype(np.float64) + v.astype(np.float64)
    s2 = (s * s).sum(1)
    above = s2 > HALF_VECTOR_MIN_LENGTH2
    assert above.tolist() == [True] * 40 + [False, False, False, True, True, True]
    np.testing.assert_allclose(got[above], s[above] / np.sqrt(s2[above])[:, None], atol=2e-6)
    np.testing.assert_array_equal(got[~above], fallback[~above])


def test_the_docs_give_the_helpers_threshold():
    root = Path(__file__).parents[2]
    mantissa, exponent = f"{np.sqrt(HALF_VECTOR_MIN_LENGTH2):.0e}".split("e")
    for doc in ("docs/atlas-format.md", "docs/engine-integration.md"):
        text = (root / doc).read_text()
        assert "atlas_half_vector(l, v, fallback)" in text, doc
        assert f"|l + v| <= {mantissa}e{int(exponent)}" in text, doc
