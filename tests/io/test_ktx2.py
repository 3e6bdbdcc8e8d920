"""The KTX2 container: checked with an independent parser (tests/ktx2_reader.py) against the
DDS of the same bake, the spec's constants, a golden file and damaged files."""

from __future__ import annotations

import hashlib
import json
import os
import struct
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import zstandard
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.cli.main import app
from atlasgen.errors import InputError
from atlasgen.io.atlas import read_atlas
from atlasgen.io.ktx2 import encode_ktx2, read_ktx2
from atlasgen.materials.material import read_materials
from tests import dds_reader, ktx2_reader

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = ROOT / "tests" / "resources" / "ktx2"
REGENERATE = os.environ.get("ATLASGEN_REGENERATE_GOLDEN") == "1"

# The spec's constants (KTX 2.0; Khronos Data Format 1.3, khr_df.h).
VK_FORMAT_R8G8B8A8_UNORM, VK_FORMAT_R8G8B8A8_SRGB = 37, 43
KHR_DF_MODEL_RGBSDA, KHR_DF_PRIMARIES_BT709 = 1, 1
KHR_DF_TRANSFER_LINEAR, KHR_DF_TRANSFER_SRGB = 1, 2
CHANNEL_R, CHANNEL_G, CHANNEL_B, CHANNEL_A = 0, 1, 2, 15

#: A small library for the tests of the container (not of the library): a LUT and a Fresnel LUT
#: with its alpha, quick to bake. The shipped library's whole atlas is the slow test's.
SMALL_LIBRARY = {"clay": 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n', "gloss": 'type = "fresnel"\n'}

#: (folder, layout, linear) -> BakeResult, baked once per process.
_BAKES: dict = {}


@pytest.fixture(scope="module")
def small_library(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("ktx2-library")
    for name, text in SMALL_LIBRARY.items():
        (folder / f"{name}.toml").write_text(text)
    return folder


def _bake(folder: Path, layout: str, linear: bool, cache_dir=None):
    key = (folder, layout, linear)
    if key not in _BAKES:
        _BAKES[key] = bake_atlas(read_materials([folder]), layout=layout, linear=linear, cache_dir=cache_dir)
    return _BAKES[key]


def _write(tmp_path, folder, layout="array", linear=False, zstd=False, cache_dir=None) -> tuple[Path, Path]:
    """The library in ``folder`` written as X.dds and as X.ktx2 (with its manifest beside it)."""
    result = _bake(folder, layout, linear, cache_dir)
    dds, ktx2 = tmp_path / "dds" / "atlas.dds", tmp_path / "ktx2" / "atlas.ktx2"
    write_bake(result, dds)
    write_bake(result, ktx2, zstd=zstd)
    return dds, ktx2


VARIANTS = [("array", False), ("array", True), ("volume", True)]


@pytest.mark.parametrize("zstd", [False, True], ids=["plain", "zstd"])
@pytest.mark.parametrize("layout,linear", VARIANTS, ids=[f"{lay}-{'linear' if lin else 'srgb'}" for lay, lin in VARIANTS])
@pytest.mark.slow
def test_every_layer_and_level_matches_the_dds(tmp_path, layout, linear, zstd, shipped_library_cache):
    # The shipped library: every slice of a real atlas, in every layout, against the DDS.
    dds_path, ktx2_path = _write(tmp_path, ROOT / "materials", layout, linear, zstd, shipped_library_cache)
    data = ktx2_path.read_bytes()
    f = ktx2_reader.parse(data)
    ktx2_reader.check_layout(f, data)
    reference = dds_reader.parse(dds_path.read_bytes())["levels"]
    assert len(f["levels"]) == len(reference) == (9 if layout == "volume" else 7)
    for k, (mine, ref) in enumerate(zip(f["levels"], reference)):
        assert mine.shape == ref.shape, k
        np.testing.assert_array_equal(mine, ref, err_msg=f"level {k}")
    h = f["header"]
    assert h == {
        "vkFormat": VK_FORMAT_R8G8B8A8_UNORM if linear else VK_FORMAT_R8G8B8A8_SRGB,
        "typeSize": 1, "pixelWidth": 64, "pixelHeight": 32,
        "pixelDepth": 256 if layout == "volume" else 0, "layerCount": 0 if layout == "volume" else 256,
        "faceCount": 1, "levelCount": len(reference), "supercompressionScheme": 2 if zstd else 0,
    }  # fmt: skip
    assert (f["index"]["sgdByteOffset"], f["index"]["sgdByteLength"]) == (0, 0)
    # The library reader agrees, level by level, and reports the same texture.
    image = read_ktx2(ktx2_path)
    assert (image.layout, image.layers, image.mip_count) == (layout, 256, len(reference))
    assert image.supercompression == (2 if zstd else 0)
    for mine, ref in zip(image.levels, reference):
        np.testing.assert_array_equal(mine, ref)


def test_level_index_and_file_order(tmp_path, small_library):
    """Level 0 is first in the index but last in the file; no padding between RGBA8 levels."""
    _, ktx2_path = _write(tmp_path, small_library)
    f = ktx2_reader.parse(ktx2_path.read_bytes())
    li = f["level_index"]
    offsets = [e["byteOffset"] for e in li]
    assert offsets == sorted(offsets, reverse=True)
    assert [e["byteLength"] for e in li] == [256 * (32 >> k or 1) * (64 >> k) * 4 for k in range(7)]
    assert li[0]["byteOffset"] + li[0]["byteLength"] == f["size"]
    assert f["size"] == li[-1]["byteOffset"] + 2_796_544


@pytest.mark.parametrize("linear", [False, True], ids=["srgb", "linear"])
def test_data_format_descriptor_is_the_basic_block_of_rgba8(tmp_path, small_library, linear):
    _, ktx2_path = _write(tmp_path, small_library, linear=linear)
    f = ktx2_reader.parse(ktx2_path.read_bytes())
    dfd = f["dfd"]
    assert dfd["dfdTotalSize"] == f["index"]["dfdByteLength"] == 4 + 24 + 4 * 16
    block = dfd["block"]
    samples = block.pop("samples")
    assert block == {
        "vendorId": 0, "descriptorType": 0, "versionNumber": 2, "descriptorBlockSize": 24 + 4 * 16,
        "colorModel": KHR_DF_MODEL_RGBSDA, "colorPrimaries": KHR_DF_PRIMARIES_BT709,
        "transferFunction": KHR_DF_TRANSFER_LINEAR if linear else KHR_DF_TRANSFER_SRGB,
        "flags": 0,  # KHR_DF_FLAG_ALPHA_STRAIGHT
        "texelBlockDimension": [1, 1, 1, 1], "bytesPlane": [4, 0, 0, 0, 0, 0, 0, 0],
    }  # fmt: skip
    assert [(s["channelType"], s["bitOffset"], s["bitLength"]) for s in samples] == [
        (CHANNEL_R, 0, 8), (CHANNEL_G, 8, 8), (CHANNEL_B, 16, 8), (CHANNEL_A, 24, 8)]  # fmt: skip
    for s in samples:
        assert (s["sampleLower"], s["sampleUpper"], s["samplePosition"]) == (0, 255, [0, 0, 0, 0])
        assert not (s["qualifierSigned"] or s["qualifierFloat"] or s["qualifierExponent"])
        # With the sRGB transfer function the alpha sample must be marked linear (KTX 2.0, Restrictions).
        assert s["qualifierLinear"] == (not linear and s["channelType"] == CHANNEL_A)


@pytest.mark.parametrize("zstd", [False, True], ids=["plain", "zstd"])
def test_key_value_data_names_the_writer_and_records_the_manifest_hash(tmp_path, small_library, zstd):
    _, ktx2_path = _write(tmp_path, small_library, zstd=zstd)
    f = ktx2_reader.parse(ktx2_path.read_bytes())
    kv = ktx2_reader.kvd_dict(f)
    manifest_bytes = ktx2_path.with_suffix(".json").read_bytes()
    assert kv["atlasgen.manifest_sha256"] == hashlib.sha256(manifest_bytes).hexdigest().encode()
    assert kv["KTXwriter"].decode().startswith("atlasgen ")
    assert ("KTXwriterScParams" in kv) == zstd
    # Every string value is NUL-terminated, and the library reader sees the same pairs.
    assert all(v.endswith(b"\0") for _, v in f["kvd"])
    assert read_ktx2(ktx2_path).key_values == dict(f["kvd"])


def test_zstd_file_is_far_smaller_and_levels_uncompressed_lengths_are_kept(tmp_path, small_library):
    dds_path, ktx2_path = _write(tmp_path, small_library, zstd=True)
    assert dds_path.stat().st_size > 2_796_544
    assert ktx2_path.stat().st_size < 100_000
    f = ktx2_reader.parse(ktx2_path.read_bytes())
    for k, e in enumerate(f["level_index"]):
        assert e["uncompressedByteLength"] == len(f["raw_levels"][k]) > e["byteLength"]


def test_the_siblings_are_those_of_the_dds_bake(tmp_path, small_library):
    dds_path, ktx2_path = _write(tmp_path, small_library)
    # The manifest records the texels' hash, the same in either container, so the manifest
    # and the includes (which record the manifest's hash) are byte-identical.
    for suffix in (".json", ".wgsl", ".glsl", ".hlsl"):
        assert ktx2_path.with_suffix(suffix).read_bytes() == dds_path.with_suffix(suffix).read_bytes(), suffix
    assert ktx2_path.with_name("atlas.timings.json").exists()


def test_read_atlas_accepts_either_container(tmp_path, small_library):
    dds_path, ktx2_path = _write(tmp_path, small_library)
    a, b = read_atlas(dds_path), read_atlas(ktx2_path)
    assert a.srgb and b.srgb and replace(a.manifest, atlas_sha256="") == replace(b.manifest, atlas_sha256="")
    first = b.manifest.materials[0].first_slice
    np.testing.assert_array_equal(a.decode_slice(first), b.decode_slice(first))
    from atlasgen.render.atlas_texture import read_render_atlas

    r = read_render_atlas(ktx2_path)
    assert r.srgb and [lv.shape for lv in r.levels] == [lv.shape for lv in a.image.levels]


def test_same_inputs_give_the_same_bytes(tmp_path, small_library):
    _, one = _write(tmp_path / "one", small_library, zstd=True)
    _, two = _write(tmp_path / "two", small_library, zstd=True)
    assert one.read_bytes() == two.read_bytes()


# ---- a tiny deterministic file, checked byte for byte ----------------------------------------


def _tiny_levels(volume: bool = False) -> list[np.ndarray]:
    """3 layers (or a depth of 4) of 4x2 RGBA8 and their mips down to 1x1, every byte distinct-ish."""
    n0 = 4 if volume else 3
    levels, value = [], 0
    for k in range(3):
        n = max(1, n0 >> k) if volume else n0
        shape = (n, max(1, 2 >> k), max(1, 4 >> k), 4)
        count = int(np.prod(shape))
        levels.append((np.arange(value, value + count) % 251).astype(np.uint8).reshape(shape))
        value += count
    return levels


TINY_KEYS = {"KTXwriter": "atlasgen test", "atlasgen.manifest_sha256": "0" * 64, "KTXorientation": "rd"}


@pytest.mark.parametrize("name,volume,srgb", [("tiny-array-srgb", False, True), ("tiny-volume-linear", True, False)])
def test_tiny_file_matches_the_golden_bytes(name, volume, srgb, tmp_path):
    produced = encode_ktx2(_tiny_levels(volume), "volume" if volume else "array", srgb, TINY_KEYS)
    golden = GOLDEN / f"{name}.ktx2"
    if REGENERATE:
        GOLDEN.mkdir(parents=True, exist_ok=True)
        golden.write_bytes(produced)
    assert produced == golden.read_bytes(), f"{name}.ktx2 differs from {golden.relative_to(ROOT)}"
    f = ktx2_reader.parse(produced)
    ktx2_reader.check_layout(f, produced)
    assert [k for k, _ in f["kvd"]] == ["KTXorientation", "KTXwriter", "atlasgen.manifest_sha256"]
    for mine, ref in zip(f["levels"], _tiny_levels(volume)):
        np.testing.assert_array_equal(mine, ref)


@settings(max_examples=40, deadline=None)
@given(
    layers=st.integers(1, 5), log_w=st.integers(0, 4), log_h=st.integers(0, 4), volume=st.booleans(),
    srgb=st.booleans(), zstd=st.booleans(), seed=st.integers(0, 2**32 - 1), data=st.data(),
)  # fmt: skip
def test_round_trip_of_any_small_chain(tmp_path_factory, layers, log_w, log_h, volume, srgb, zstd, seed, data):
    w, h = 1 << log_w, 1 << log_h
    n0 = 1 << (layers - 1) if volume else layers
    max_levels = max(w, h, n0 if volume else 1).bit_length()  # floor(log2(largest dimension)) + 1
    count = data.draw(st.integers(1, max_levels))
    rng = np.random.default_rng(seed)
    levels = [rng.integers(0, 256, (max(1, n0 >> k) if volume else n0, max(1, h >> k), max(1, w >> k), 4), np.uint8)
              for k in range(count)]  # fmt: skip
    blob = encode_ktx2(levels, "volume" if volume else "array", srgb, {"KTXwriter": "t"}, zstd)
    f = ktx2_reader.parse(blob)
    ktx2_reader.check_layout(f, blob)
    path = tmp_path_factory.mktemp("rt") / "x.ktx2"
    path.write_bytes(blob)
    image = read_ktx2(path)
    assert image.layout == ("volume" if volume else "array") and image.dxgi_format == (29 if srgb else 28)
    for a, b, c in zip(levels, f["levels"], image.levels):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(a, c)


# ---- damaged files ---------------------------------------------------------------------------


def _put(blob: bytes, offset: int, fmt: str, value) -> bytes:
    out = bytearray(blob)
    struct.pack_into(fmt, out, offset, value)
    return bytes(out)


def _tiny(zstd=False) -> bytes:
    return encode_ktx2(_tiny_levels(), "array", True, TINY_KEYS, zstd)


def _level0_offset(blob: bytes) -> int:
    return struct.unpack_from("<Q", blob, 80)[0]


def _kvd_offset(blob: bytes) -> int:
    return struct.unpack_from("<I", blob, 56)[0]


def _bomb(content_size: bool) -> bytes:
    """The tiny zstd file with its base level replaced by a frame that inflates to 10 MB."""
    blob = _tiny(True)
    frame = zstandard.ZstdCompressor(write_content_size=content_size).compress(bytes(10_000_000))
    start = _level0_offset(blob)
    return _put(blob[:start] + frame, 88, "<Q", len(frame))


def _base_frame(frame_of) -> bytes:
    """The tiny zstd file with its base level (the file's last bytes) replaced by ``frame_of(a checksummed frame of
    the level's own bytes)``."""
    blob = _tiny(True)
    frame = frame_of(zstandard.ZstdCompressor(write_checksum=True).compress(_tiny_levels()[0].tobytes()))
    start = _level0_offset(blob)
    return _put(blob[:start] + frame, 88, "<Q", len(frame))


#: The basic descriptor block of the tiny file: after the header, 3 level index entries and dfdTotalSize.
DFD_BLOCK = 80 + 3 * 24 + 4


def _twin_keys() -> bytes:
    """The manifest hash key twice, a wrong value first (written as ``...sha25X``, then renamed)."""
    keys = {"KTXwriter": "atlasgen test", "atlasgen.manifest_sha256": "f" * 64, "atlasgen.manifest_sha25X": "0" * 64}
    blob = encode_ktx2(_tiny_levels(), "array", True, keys)
    return blob.replace(b"atlasgen.manifest_sha25X", b"atlasgen.manifest_sha256", 1)


def _padding_offset(blob: bytes) -> int:
    """The first valuePadding byte of the tiny file's key/value data."""
    pos = _kvd_offset(blob)
    while True:
        (length,) = struct.unpack_from("<I", blob, pos)
        if length % 4:
            return pos + 4 + length
        pos += 4 + length


def _kvd_length(blob: bytes) -> int:
    return struct.unpack_from("<I", blob, 60)[0]


#: name -> (damaged bytes, text the one-line message must contain)
DAMAGED = {
    "empty": (lambda: b"", "not a KTX2 file"),
    "identifier": (lambda: b"\xabKTX 11\xbb" + _tiny()[8:], "not a KTX2 file"),
    "truncated header": (lambda: _tiny()[:79], "not a KTX2 file"),
    "truncated level index": (lambda: _tiny()[:100], "'levels'"),
    "truncated dfd": (lambda: _tiny()[:200], "'dfdByteLength'"),
    "truncated base level": (lambda: _tiny()[:-1], "'levels[0].byteLength'"),
    "truncated zstd level": (lambda: _tiny(True)[:-3], "'levels[0]"),
    # The level's bytes are all there: the stream reader stopped at them and took the frame as whole.
    "zstd checksum cut": (lambda: _base_frame(lambda f: f[:-2]), "'levels[0]': a Zstandard frame cut short"),
    "zstd frame then a partial one": (
        lambda: _base_frame(lambda f: f + f[:6]),
        "'levels[0]': a Zstandard frame cut short",
    ),  # fmt: skip
    "vkFormat": (lambda: _put(_tiny(), 12, "<I", 44), "'vkFormat'"),
    "typeSize": (lambda: _put(_tiny(), 16, "<I", 4), "'typeSize'"),
    "faceCount": (lambda: _put(_tiny(), 36, "<I", 6), "'faceCount'"),
    "2D without layers": (lambda: _put(_tiny(), 32, "<I", 0), "'pixelDepth'"),
    "levelCount": (lambda: _put(_tiny(), 40, "<I", 40), "'levelCount'"),
    "scheme": (lambda: _put(_tiny(), 44, "<I", 1), "'supercompressionScheme'"),
    "huge layerCount": (lambda: _put(_tiny(), 32, "<I", 0xFFFFFFFF), "'layerCount'"),
    "huge zstd layerCount": (lambda: _put(_tiny(True), 32, "<I", 0xFFFFFFFF), "'layerCount'"),
    # An offset past the file's end is named as the offset, not as the length after it.
    "dfdByteOffset": (lambda: _put(_tiny(), 48, "<I", 1 << 31), "'dfdByteOffset'"),
    "dfdByteLength is not dfdTotalSize": (lambda: _put(_tiny(), 52, "<I", 88), "'dfdByteOffset'"),
    "kvdByteLength": (lambda: _put(_tiny(), 60, "<I", 1 << 30), "'kvdByteLength'"),
    "keyAndValueByteLength": (lambda: _put(_tiny(), _kvd_offset(_tiny()), "<I", 10_000), "'keyAndValueByteLength'"),
    "key without NUL": (lambda: _put(_tiny(), _kvd_offset(_tiny()) + 4, "18s", b"A" * 18), "'keyAndValue'"),
    "sgdByteLength": (lambda: _put(_tiny(), 72, "<Q", 4), "'sgdByteLength'"),
    # KTX 2.0 3.11, read to the letter (each was read with exit 0): the sum of the entries and their padding is
    # kvdByteLength exactly, a key is UTF-8, padding is 0x00.
    "kvdByteLength short of the last padding": (lambda: _put(_tiny(), 60, "<I", _kvd_length(_tiny()) - 1), "'kvdByteLength'"),
    "kvdByteLength past the last padding": (lambda: _put(_tiny(), 60, "<I", _kvd_length(_tiny()) + 4), "'keyAndValueByteLength'"),
    "key not UTF-8": (lambda: _tiny().replace(b"KTXwriter\0", b"KTXwrit\xffr\0", 1), "expected UTF-8 without a byte order"),
    "valuePadding not zero": (lambda: _put(_tiny(), _padding_offset(_tiny()), "<B", 7), "'valuePadding': 0700 after"),
    # The base level ends the file (the independent reader, tests/ktx2_reader.py, holds it to that too).
    "bytes after the base level": (lambda: _tiny() + b"\0" * 16, "'levels': the last level stored ends at byte "),
    "bytes after the zstd base level": (lambda: _tiny(True) + b"x", "expected the base level to end the file"),
    # KTX 2.0 3.10: with no global data both are 0 (a flipped sgdByteOffset was read, exit 0).
    "sgdByteOffset without global data": (lambda: _put(_tiny(), 64, "<Q", 8), "'sgdByteOffset': 8; expected 0 where"),
    # A flipped extent shows first in the level index: the message gives the extents it was checked against.
    "pixelWidth within range": (
        lambda: _put(_tiny(), 20, "<I", 5),
        "'levels[0].uncompressedByteLength': 96; expected 120, the bytes of level 0 (3, 2, 5, 4) of "
        "pixelWidth 5, pixelHeight 2 and layerCount 3 (one of those header fields or this entry",
    ),
    "level byteOffset": (lambda: _put(_tiny(), 80, "<Q", 1 << 40), "'levels[0].byteOffset'"),
    "level byteLength": (lambda: _put(_tiny(), 88, "<Q", 1 << 62), "'levels[0].byteLength'"),
    "uncompressedByteLength": (lambda: _put(_tiny(), 96, "<Q", 1 << 40), "'levels[0].uncompressedByteLength'"),
    "corrupt zstd frame": (lambda: _put(_tiny(True), _level0_offset(_tiny(True)), "<I", 0xDEADBEEF), "corrupt Zstandard"),
    "uncompressedByteLength of a zstd level": (lambda: _put(_tiny(True), 96 + 24, "<Q", 5), "'levels[1].uncompressedByteLength'"),
    "zstd bomb": (lambda: _bomb(content_size=False), "inflates to more than"),
    "zstd bomb declaring its size": (lambda: _bomb(content_size=True), "inflates to more than"),
    # Issue 24: the DFD read field by field against vkFormat (its basic block starts at byte 156).
    "linear transfer in an sRGB file": (lambda: _put(_tiny(), DFD_BLOCK + 10, "<B", 1), "'dfd.transferFunction': 1; expected 2"),
    "sRGB transfer in a linear file": (lambda: _put(_tiny(), 12, "<I", 37), "'dfd.transferFunction': 2; expected 1"),
    "BC1 colour model": (lambda: _put(_tiny(), DFD_BLOCK + 8, "<B", 128), "'dfd.colorModel': 128; expected 1"),
    "bytesPlane0 = 0": (lambda: _put(_tiny(), DFD_BLOCK + 16, "<B", 0), "'dfd.bytesPlane0': 0; expected 4"),
    "16-bit alpha sample": (lambda: _put(_tiny(), DFD_BLOCK + 24 + 48 + 2, "<B", 15), "'dfd.samples[3].bitLength': 15"),
    "non-Khronos descriptor": (lambda: _put(_tiny(), DFD_BLOCK, "<I", 1), "'dfd.vendorId': 1; expected 0"),
    "block size past the end": (lambda: _put(_tiny(), DFD_BLOCK + 6, "<H", 200), "'dfd.descriptorBlockSize': 200 bytes run past"),
    "primaries": (lambda: _put(_tiny(), DFD_BLOCK + 9, "<B", 10), "'dfd.colorPrimaries': 10; expected 1"),
    "duplicated key, the wrong value first": (lambda: _twin_keys(), "key 'atlasgen.manifest_sha256' at byte"),
    "unsorted keys": (lambda: _tiny().replace(b"atlasgen.manifest", b"Atlasgen.manifest", 1), "comes after 'KTXwriter'"),
    "pixelWidth 0": (lambda: _put(_tiny(), 20, "<I", 0), "'pixelWidth': 0; expected 1 to 65536"),
    "pixelWidth 0xFFFFFFFF": (lambda: _put(_tiny(), 20, "<I", 0xFFFFFFFF), "'pixelWidth': 4294967295"),
    "pixelHeight 0": (lambda: _put(_tiny(), 24, "<I", 0), "'pixelHeight': 0"),
    # 110 MB inflated, of a few bytes: refused before any level is read (at 1 GiB, a 33 KB file took 2 GB).
    "layerCount beyond the limit": (
        lambda: _put(_tiny(), 32, "<I", 2_500_000),
        "'layerCount': 4x2x0 with 2500000 layers and 3 levels exceeds the 67108864-byte limit",
    ),
    "pixelHeight 0xFFFFFFFF": (lambda: _put(_tiny(), 24, "<I", 0xFFFFFFFF), "'pixelHeight': 4294967295"),
}


def test_the_damage_offsets_point_at_the_fields_they_name():
    blob = _tiny()
    f = ktx2_reader.parse(blob)
    assert _kvd_offset(blob) == f["index"]["kvdByteOffset"] and _level0_offset(blob) == f["level_index"][0]["byteOffset"]
    assert DFD_BLOCK == f["index"]["dfdByteOffset"] + 4 and blob[DFD_BLOCK + 10] == f["dfd"]["block"]["transferFunction"]
    assert blob[_kvd_offset(blob) + 4 :].startswith(b"KTXorientation\0")


@pytest.mark.parametrize("case", sorted(DAMAGED))
def test_damaged_files_are_refused_with_one_line(case, tmp_path):
    make, expected = DAMAGED[case]
    path = tmp_path / "bad.ktx2"
    path.write_bytes(make())
    with pytest.raises(InputError) as info:
        read_ktx2(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(path.as_posix() + ": "), message
    assert expected in message, message


@pytest.mark.parametrize("content_size", [False, True], ids=["unsized", "sized"])
def test_a_zstd_bomb_is_refused_without_inflating_it(content_size, tmp_path):
    """A 10 MB frame in place of a 96-byte level: the reader stops one byte past what the index allows."""
    import tracemalloc

    path = tmp_path / "bomb.ktx2"
    path.write_bytes(_bomb(content_size))
    tracemalloc.start()
    try:
        with pytest.raises(InputError, match="inflates to more than"):
            read_ktx2(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1_000_000


def test_a_missing_file_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="cannot read"):
        read_ktx2(tmp_path / "none.ktx2")


# ---- the command line ------------------------------------------------------------------------


@pytest.fixture
def library(write_material, tmp_path):
    write_material("clay", 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n')
    write_material("snow", 'type = "lambert"\nid = 9\n')
    return tmp_path / "materials"


def test_cli_bakes_ktx2_and_info_reads_it(library, tmp_path):
    runner = CliRunner()
    out = tmp_path / "atlas.ktx2"
    res = runner.invoke(app, ["bake", str(library), "-o", str(out), "--zstd"])
    assert res.exit_code == 0, res.output
    assert res.stdout.strip() == f"{out.as_posix()} (64x32, 7 mips, 256 layers, R8G8B8A8_SRGB, 2DArray, zstd)"
    text = runner.invoke(app, ["info", str(out)])
    assert text.exit_code == 0, text.output
    assert "vkFormat 43 (R8G8B8A8_SRGB), zstd supercompressed" in text.output and "snow" in text.output
    data = json.loads(runner.invoke(app, ["info", str(out), "--format", "json"]).output)
    assert data["header"]["container"] == "ktx2" and data["header"]["vk_format"] == 43
    assert data["header"]["layers"] == 256 and data["header"]["mip_count"] == 7
    assert data["manifest"]["slices_used"] == 2


def test_cli_volume_linear_ktx2(library, tmp_path):
    out = tmp_path / "v.ktx2"
    res = CliRunner().invoke(app, ["bake", str(library), "-o", str(out), "--layout", "volume", "--linear"])
    assert res.exit_code == 0, res.output
    assert res.stdout.strip() == f"{out.as_posix()} (64x32x256, 9 mips, R8G8B8A8_UNORM, 3D)"


def test_cli_refuses_other_suffixes_and_zstd_dds(library, tmp_path):
    runner = CliRunner()
    res = runner.invoke(app, ["bake", str(library), "-o", str(tmp_path / "atlas.png")])
    assert res.exit_code == 2  # a bad option value (docs/cli.md)
    assert (
        res.stderr.strip()
        == f"atlasgen: error: {(tmp_path / 'atlas.png').as_posix()}: the atlas (-o) must end in .dds or .ktx2, not '.png'"
    )
    res = runner.invoke(app, ["bake", str(library), "-o", str(tmp_path / "atlas.dds"), "--zstd"])
    assert res.exit_code == 2 and res.stderr.strip().endswith(
        f"--zstd needs a KTX2 output (-o X.ktx2), got -o {(tmp_path / 'atlas.dds').as_posix()}"
    )
    assert not list(tmp_path.glob("atlas.*"))
