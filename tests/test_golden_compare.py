"""The golden comparison's tolerances: what it lets through and what it catches (tests/golden_compare.py)."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from atlasgen.io.atlas import INCLUDE_HASH_PREFIX
from atlasgen.io.dds import encode_dds
from tests import golden_compare as gc


def _levels(layers: int = 4, volume: bool = False) -> list[np.ndarray]:
    """An RGBA8 chain of 8x4 texels, down to 1x1 (and, for a volume, halving depth)."""
    rng = np.random.default_rng(7)
    out = []
    for k in range(4):
        depth = max(layers >> k, 1) if volume else layers
        out.append(rng.integers(10, 240, (depth, max(4 >> k, 1), max(8 >> k, 1), 4), dtype=np.uint8))
    return out


def _dds(levels, volume=False) -> bytes:
    return encode_dds(levels, "volume" if volume else "array", 28)


def _bumped(levels, k, layer, by):
    out = [lv.copy() for lv in levels]
    out[k][layer, 0, 0, 0] += by
    return out


@pytest.mark.parametrize("k", [0, 2])
def test_a_jit_slice_may_move_one_code_and_no_more(k):
    levels = _levels()
    golden = _dds(levels)
    assert gc.compare_dds(_dds(_bumped(levels, k, 1, 1)), golden, {1}) == []
    assert gc.compare_dds(_dds(_bumped(levels, k, 1, 2)), golden, {1}) == [
        f"level {k} slice 1: texels differ by up to 2 codes (allowed 1)"
    ]


def test_a_numpy_slice_must_not_move_at_all():
    levels = _levels()
    problems = gc.compare_dds(_dds(_bumped(levels, 0, 2, 1)), _dds(levels), {1})
    assert problems == ["level 0 slice 2: texels differ by up to 1 codes (allowed 0)"]


def test_a_volume_mip_is_tolerant_where_it_blends_a_jit_slice():
    levels = _levels(volume=True)
    golden = _dds(levels, volume=True)
    # Level 1's slice 0 blends level-0 slices 0 and 1; slice 1 blends 2 and 3.
    assert gc.compare_dds(_dds(_bumped(levels, 1, 0, 1), volume=True), golden, {1}) == []
    assert gc.compare_dds(_dds(_bumped(levels, 1, 1, 1), volume=True), golden, {1}) != []


def test_a_header_difference_is_never_tolerated():
    levels = _levels()
    other = encode_dds(levels, "array", 29)  # sRGB instead of linear
    assert gc.compare_dds(other, _dds(levels), {0, 1, 2, 3})[0].startswith("the dx10 differs")


MANIFEST = {
    "format_version": 5,
    "atlas_sha256": "a" * 64,
    "materials": [
        {"name": "gold", "scale": [[1.25, 0.5]], "figure": 0.0174, "figure_se": 0.0002, "curve": [0.16, 0.06],
         "curve_se": [0.001, 0.0006], "label": "x"},
        {"name": "clay", "scale": [[0.8, 1.0]], "quantization_error": {"max": 0.002, "rms": 0.001}},
    ],
}  # fmt: skip


def _changed(path, value):
    data = copy.deepcopy(MANIFEST)
    node = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return data


def test_jit_figures_move_within_their_standard_errors_and_others_not_at_all():
    assert gc.compare_manifest(MANIFEST, MANIFEST, {"gold"}) == []
    # 3 SE of the difference of two estimates: 3 sqrt(2) 0.0002 = 0.00085.
    assert gc.compare_manifest(_changed(("materials", 0, "figure"), 0.0180), MANIFEST, {"gold"}) == []
    assert gc.compare_manifest(_changed(("materials", 0, "figure"), 0.0190), MANIFEST, {"gold"}) != []
    assert gc.compare_manifest(_changed(("materials", 0, "curve", 1), 0.0605), MANIFEST, {"gold"}) == []
    assert gc.compare_manifest(_changed(("materials", 0, "curve", 1), 0.07), MANIFEST, {"gold"}) != []
    # Without an SE, only rounding: a doubled scale is caught, a last-digit change is not.
    assert gc.compare_manifest(_changed(("materials", 0, "scale", 0, 0), 1.2500001), MANIFEST, {"gold"}) == []
    assert gc.compare_manifest(_changed(("materials", 0, "scale", 0, 0), 2.5), MANIFEST, {"gold"}) != []
    # A NumPy material is exact but for another SIMD width's last digits, and a JIT material's text is exact.
    assert gc.compare_manifest(_changed(("materials", 1, "quantization_error", "rms"), 0.0010001), MANIFEST, {"gold"}) != []
    assert gc.compare_manifest(_changed(("materials", 1, "quantization_error", "rms"), 0.0010000000000000002), MANIFEST,
                               {"gold"}) == []  # fmt: skip
    assert gc.compare_manifest(_changed(("materials", 1, "quantization_error", "rms"), 0.0010000001), MANIFEST, {"gold"}) != []
    # A JIT material's quantization error may move by its texels' float32 rounding, ~1e-7, not more.
    assert gc.compare_manifest(_changed(("materials", 1, "quantization_error", "max"), 0.0020002), MANIFEST, {"clay"}) == []
    assert gc.compare_manifest(_changed(("materials", 1, "quantization_error", "max"), 0.0020010), MANIFEST, {"clay"}) != []
    assert gc.compare_manifest(_changed(("materials", 0, "label"), "y"), MANIFEST, {"gold"}) != []


def test_figures_over_every_slice_are_tolerant_only_where_a_slice_went_through_the_jit():
    bleed = {**MANIFEST, "volume_bleed": [{"rms": 0.18492152932947895, "max": 0.5456279516220093}]}
    moved = copy.deepcopy(bleed)
    moved["volume_bleed"][0].update(rms=0.18492153302103953, max=0.5456278920173645)  # float32 rounding of a JIT slice
    assert gc.compare_manifest(moved, bleed, {"gold"}) == []
    assert gc.compare_manifest(moved, bleed, set()) != []
    moved["volume_bleed"][0]["rms"] = 0.2
    assert gc.compare_manifest(moved, bleed, {"gold"}) != []


def test_the_atlas_digest_is_left_to_the_link_check():
    assert gc.compare_manifest(_changed(("atlas_sha256",), "b" * 64), MANIFEST, set()) == []


def test_an_includes_manifest_digest_is_left_to_the_link_check():
    body = "// Generated by atlasgen\nconst ATLAS_WIDTH: u32 = 64u;\n"
    mine, golden = f"{INCLUDE_HASH_PREFIX}{'a' * 64}\n{body}", f"{INCLUDE_HASH_PREFIX}{'b' * 64}\n{body}"
    assert gc.compare_text(mine, golden) == []
    assert gc.compare_text(mine.replace("64u", "32u"), golden) != []


def test_text_must_match_between_its_numbers():
    golden = "const SCALE: array<vec4<f32>, 2> = array(vec4(1.0391510725021362, 0.5), vec4(2.0, 0.0));\n"
    assert gc.compare_text(golden.replace("1.0391510725021362", "1.0391510725"), golden) == []
    assert gc.compare_text(golden.replace("1.0391510725021362", "2.0783021450042724"), golden) != []
    assert gc.compare_text(golden.replace("SCALE", "SCALES"), golden) == ["line 1 differs in more than its numbers"]


def test_the_links_are_recomputed_from_the_produced_files():
    import hashlib
    import json

    levels = _levels()
    dds = _dds(levels)
    digest = hashlib.sha256(b"".join(np.ascontiguousarray(lv).tobytes() for lv in levels)).hexdigest()
    outputs = {".dds": dds, ".json": json.dumps({"atlas_sha256": digest}).encode()}
    assert gc.check_links(outputs) == []
    outputs[".json"] = json.dumps({"atlas_sha256": "0" * 64}).encode()
    assert gc.check_links(outputs) == ["the manifest's atlas_sha256 is not the produced atlas's texels'"]
    outputs[".json"] = json.dumps({"atlas_sha256": digest}).encode()
    outputs[".wgsl"] = f"{INCLUDE_HASH_PREFIX}{hashlib.sha256(outputs['.json']).hexdigest()}\nconst X = 1;\n".encode()
    assert gc.check_links(outputs) == []
    outputs[".wgsl"] = f"{INCLUDE_HASH_PREFIX}{'0' * 64}\nconst X = 1;\n".encode()
    assert gc.check_links(outputs) == ["the .wgsl include does not record the produced manifest's SHA-256 on its first line"]
