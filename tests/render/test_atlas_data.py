"""The renderer's include: the bake's functions, with the per-bake tables in buffers."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from atlasgen.contract import LAYERS
from atlasgen.io.atlas import INCLUDE_HASH_PREFIX
from atlasgen.io.manifest import read_manifest
from atlasgen.models import get_model
from atlasgen.render.atlas_data import STORAGE, RendererInclude, manifest_scale_bias
from atlasgen.shaders.include import render_include

GOLDEN = Path(__file__).resolve().parents[1] / "resources" / "golden"


@pytest.fixture(scope="module")
def manifest():
    return read_manifest(GOLDEN / "array-srgb.json")


def _unstamped(text: str) -> str:
    first, rest = text.split("\n", 1)
    assert first.startswith(INCLUDE_HASH_PREFIX)
    return rest


def test_the_manifest_gives_back_the_scales_the_bake_compiled_in(manifest):
    # The shipped library's include, rebuilt from its manifest alone, is the committed golden byte for byte.
    got = render_include(manifest, *manifest_scale_bias(manifest), "wgsl", models=get_model)
    assert got == _unstamped((GOLDEN / "array-srgb.wgsl").read_text())


def test_the_renderer_include_reads_the_tables_from_buffers_holding_their_values(manifest):
    include = RendererInclude.of(manifest)
    scales, biases = manifest_scale_bias(manifest)
    declared = {
        "uniform": lambda name: f"var<uniform> {name}: array<vec4<f32>, {LAYERS}>;",
        "storage": lambda name: f"var<storage, read> {name}: array<vec4<f32>>;",
    }
    for name, (group, binding, space) in STORAGE.items():
        assert f"@group({group}) @binding({binding}) {declared[space](name)}" in include.text
        assert f"var<private> {name}" not in include.text
    # One row per slice, read as a block: a storage read is a gather per lane on lavapipe, once per pixel.
    assert STORAGE["ATLAS_SCALE_BIAS"][2] == "uniform"
    assert include.tables["ATLAS_SCALE_BIAS"].shape == (LAYERS, 4)
    np.testing.assert_array_equal(include.tables["ATLAS_SCALE_BIAS"], np.concatenate([scales, biases], axis=1))
    # The factor table is the side-car's rows (X.separable.bin: a 48-byte header, then float32 rows).
    sidecar = np.frombuffer((GOLDEN / "array-srgb.separable.bin").read_bytes()[48:], "<f4").reshape(-1, 4)
    np.testing.assert_array_equal(include.tables["SEPARABLE_TABLE"].astype(np.float32), sidecar)
    assert "return ATLAS_SCALE_BIAS[material_id];" in include.text


def test_a_new_scale_changes_the_tables_not_the_renderer_include(manifest):
    entries = list(manifest.materials)
    k, entry = next((i, e) for i, e in enumerate(entries) if e.factors is not None)
    scale = [[2.0 * s[0], s[1]] for s in entry.scale]
    bias = [[b[0] - 0.25, b[1] + 0.125] for b in entry.bias]
    factors = dataclasses.replace(entry.factors, factor_scale=(np.asarray(entry.factors.factor_scale) * 1.5).tolist())
    entries[k] = dataclasses.replace(entry, scale=scale, bias=bias, factors=factors)
    edited = dataclasses.replace(manifest, materials=entries)
    before, after = RendererInclude.of(manifest), RendererInclude.of(edited)
    assert after.text == before.text
    assert render_include(edited, *manifest_scale_bias(edited), models=get_model) != render_include(
        manifest, *manifest_scale_bias(manifest), models=get_model
    )
    rows = after.tables["ATLAS_SCALE_BIAS"][entry.first_slice : entry.first_slice + entry.slice_count]
    np.testing.assert_array_equal(rows, np.concatenate([scale, bias], axis=1))
    assert not np.array_equal(after.tables["SEPARABLE_TABLE"], before.tables["SEPARABLE_TABLE"])
