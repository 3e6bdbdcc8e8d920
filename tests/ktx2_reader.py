"""An independent KTX 2.0 parser for the tests, written from the Khronos KTX File Format
Specification 2.0 and the Khronos Data Format Specification 1.3 (basic descriptor block).

It shares no code with atlasgen.io.ktx2 on purpose: a bug in the writer must not be
mirrored by the reader that checks it. It asserts the layout rules the spec states
("levels are stored smallest first", "mipPadding", "sorted keys", ...) and returns
every field, so tests can compare them with the spec's constants.
"""

from __future__ import annotations

import math

import numpy as np

IDENTIFIER = bytes([0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A])
HEADER_NAMES = ("vkFormat typeSize pixelWidth pixelHeight pixelDepth layerCount faceCount levelCount "
                "supercompressionScheme").split()  # fmt: skip
INDEX_NAMES = "dfdByteOffset dfdByteLength kvdByteOffset kvdByteLength sgdByteOffset sgdByteLength".split()


def _u32(data: bytes, pos: int) -> int:
    return int.from_bytes(data[pos : pos + 4], "little")


def _u64(data: bytes, pos: int) -> int:
    return int.from_bytes(data[pos : pos + 8], "little")


def parse_dfd(data: bytes, offset: int, length: int) -> dict:
    """``dfdTotalSize`` and the first descriptor block, bit fields decoded (KDF 1.3, section 5)."""
    total = _u32(data, offset)
    pos = offset + 4
    word0, word1, word2, word3 = (_u32(data, pos + 4 * i) for i in range(4))
    block = {
        "vendorId": word0 & 0x1FFFF,
        "descriptorType": word0 >> 17,
        "versionNumber": word1 & 0xFFFF,
        "descriptorBlockSize": word1 >> 16,
        "colorModel": word2 & 0xFF,
        "colorPrimaries": (word2 >> 8) & 0xFF,
        "transferFunction": (word2 >> 16) & 0xFF,
        "flags": word2 >> 24,
        "texelBlockDimension": [((word3 >> (8 * i)) & 0xFF) + 1 for i in range(4)],
        "bytesPlane": list(data[pos + 16 : pos + 24]),
    }
    samples = []
    for s in range((block["descriptorBlockSize"] - 24) // 16):
        at = pos + 24 + 16 * s
        w = _u32(data, at)
        samples.append({
            "bitOffset": w & 0xFFFF,
            "bitLength": ((w >> 16) & 0xFF) + 1,
            "channelType": (w >> 24) & 0xF,
            "qualifierLinear": bool(w >> 28 & 1),
            "qualifierExponent": bool(w >> 29 & 1),
            "qualifierSigned": bool(w >> 30 & 1),
            "qualifierFloat": bool(w >> 31 & 1),
            "samplePosition": list(data[at + 4 : at + 8]),
            "sampleLower": _u32(data, at + 8),
            "sampleUpper": _u32(data, at + 12),
        })  # fmt: skip
    block["samples"] = samples
    return {"dfdTotalSize": total, "block": block, "length": length}


def parse_kvd(data: bytes, offset: int, length: int) -> tuple[list, list]:
    """``[(key, value bytes)]`` in file order, and each entry's valuePadding bytes."""
    entries, paddings = [], []
    pos = offset
    while pos < offset + length:
        n = _u32(data, pos)
        body = data[pos + 4 : pos + 4 + n]
        key, _, value = body.partition(b"\0")
        entries.append((key.decode("utf-8"), value))
        pad = (4 - (pos + 4 + n) % 4) % 4
        paddings.append(data[pos + 4 + n : pos + 4 + n + pad])
        pos += 4 + n + pad
    assert pos == offset + length, "kvdByteLength is not the sum of the padded entries"
    return entries, paddings


def _zstd_inflate(blob: bytes) -> bytes:
    import zstandard

    return zstandard.ZstdDecompressor().decompress(blob)


def parse(data: bytes) -> dict:
    """Every field of a KTX2 file, and its levels as uint8 ``(layers or depth_p, h_p, w_p, 4)`` arrays."""
    assert data[:12] == IDENTIFIER, "identifier"
    header = {name: _u32(data, 12 + 4 * i) for i, name in enumerate(HEADER_NAMES)}
    index = {name: _u32(data, 48 + 4 * i) for i, name in enumerate(INDEX_NAMES[:4])}
    index["sgdByteOffset"], index["sgdByteLength"] = _u64(data, 64), _u64(data, 72)
    n_levels = max(1, header["levelCount"])
    level_index = [
        {"byteOffset": _u64(data, 80 + 24 * p), "byteLength": _u64(data, 88 + 24 * p),
         "uncompressedByteLength": _u64(data, 96 + 24 * p)}
        for p in range(n_levels)
    ]  # fmt: skip
    dfd = parse_dfd(data, index["dfdByteOffset"], index["dfdByteLength"])
    kvd, kvd_padding = parse_kvd(data, index["kvdByteOffset"], index["kvdByteLength"])

    width, height, depth = header["pixelWidth"], header["pixelHeight"], header["pixelDepth"]
    layers = max(1, header["layerCount"])
    block_bytes = dfd["block"]["bytesPlane"][0]
    scheme = header["supercompressionScheme"]
    levels, raw_levels = [], []
    for p, entry in enumerate(level_index):
        w, h, d = max(1, width >> p), max(1, height >> p), max(1, depth >> p)
        blob = data[entry["byteOffset"] : entry["byteOffset"] + entry["byteLength"]]
        raw = _zstd_inflate(blob) if scheme == 2 else blob
        raw_levels.append(raw)
        assert len(raw) == entry["uncompressedByteLength"] == layers * d * h * w * block_bytes
        count = d if depth else layers
        levels.append(np.frombuffer(raw, np.uint8).reshape(count, h, w, block_bytes))
    return {"header": header, "index": index, "level_index": level_index, "dfd": dfd, "kvd": kvd,
            "kvd_padding": kvd_padding, "levels": levels, "raw_levels": raw_levels, "size": len(data)}  # fmt: skip


def check_layout(f: dict, data: bytes) -> None:
    """The placement rules of the spec: section order, alignment, padding, level order and coverage."""
    h, ix, li = f["header"], f["index"], f["level_index"]
    n = len(li)
    assert ix["dfdByteOffset"] == 80 + 24 * n, "the DFD follows the level index"
    assert f["dfd"]["dfdTotalSize"] == ix["dfdByteLength"], "dfdByteLength equals dfdTotalSize"
    assert ix["kvdByteLength"] == 0 or ix["kvdByteOffset"] == ix["dfdByteOffset"] + ix["dfdByteLength"]
    assert ix["kvdByteLength"] > 0 or ix["kvdByteOffset"] == 0, "kvdByteOffset is 0 when there is no kvd"
    assert ix["sgdByteLength"] == 0 or ix["sgdByteOffset"] % 8 == 0
    assert ix["sgdByteLength"] > 0 or ix["sgdByteOffset"] == 0, "sgdByteOffset is 0 when there is no sgd"
    keys = [k for k, _ in f["kvd"]]
    assert keys == sorted(set(keys), key=lambda k: [ord(c) for c in k]), "keys sorted by code point, no repeats"
    assert all(p == b"\0" * len(p) for p in f["kvd_padding"]), "valuePadding is zero bytes"
    scheme = h["supercompressionScheme"]
    block = f["dfd"]["block"]["bytesPlane"][0]
    alignment = math.lcm(block, 4) if scheme == 0 else 1
    # Levels are stored from the smallest (p = n - 1) to the base (p = 0), each after its mipPadding.
    end_of_metadata = (
        (ix["sgdByteOffset"] + ix["sgdByteLength"])
        if ix["sgdByteLength"]
        else (ix["kvdByteOffset"] + ix["kvdByteLength"] if ix["kvdByteLength"] else ix["dfdByteOffset"] + ix["dfdByteLength"])
    )
    pos = end_of_metadata
    for p in reversed(range(n)):
        start = li[p]["byteOffset"]
        assert start % alignment == 0, f"level {p} is aligned to {alignment}"
        assert 0 <= start - pos < alignment, f"level {p} follows level {p + 1} after only mipPadding"
        assert data[pos:start] == b"\0" * (start - pos), "mipPadding is zero bytes"
        pos = start + li[p]["byteLength"]
        if scheme == 0:
            assert li[p]["byteLength"] == li[p]["uncompressedByteLength"]
    assert pos == len(data), "the base level ends the file"
    for p in range(n):
        assert li[p]["uncompressedByteLength"] % (h["faceCount"] * max(1, h["layerCount"])) == 0


def kvd_dict(f: dict) -> dict:
    """Key -> value with one trailing NUL removed (string values are NUL-terminated)."""
    return {k: (v[:-1] if v.endswith(b"\0") else v) for k, v in f["kvd"]}
