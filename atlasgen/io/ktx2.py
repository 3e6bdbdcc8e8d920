"""KTX 2.0 files: RGBA8 2D arrays and volumes with mip chains, optionally Zstandard-supercompressed.

Written from the Khronos *KTX File Format Specification 2.0* (``ktxspec.adoc``) and the
basic descriptor block of the *Khronos Data Format Specification 1.3*:

- an 80-byte header (identifier, nine u32, the index: four u32 and two u64), then the
  level index, three u64 per level with **level 0 first**;
- the Data Format Descriptor (``dfdTotalSize`` then one basic block), then the
  key/value data sorted by key, each entry padded to 4 bytes;
- the mip levels stored **smallest first**. Without supercompression each level starts
  on a multiple of lcm(texel block size, 4) = 4 bytes (``mipPadding``); with
  Zstandard (scheme 2) each level is one independent frame, unaligned, and the
  index keeps its ``uncompressedByteLength``.

A 2D array has ``pixelDepth`` 0 and ``layerCount`` = layers, and a level holds every
layer in turn; a volume has ``pixelDepth`` = depth, ``layerCount`` 0, and its depth
halves at each level like its width and height.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import zstandard

from atlasgen.errors import InputError, shorten

__all__ = [
    "KTX2_IDENTIFIER",
    "VK_FORMAT_R8G8B8A8_UNORM",
    "VK_FORMAT_R8G8B8A8_SRGB",
    "SUPERCOMPRESSION_NONE",
    "SUPERCOMPRESSION_ZSTD",
    "ZSTD_LEVEL",
    "KTX2Image",
    "encode_ktx2",
    "read_ktx2",
    "describe_ktx2",
]

KTX2_IDENTIFIER = b"\xabKTX 20\xbb\r\n\x1a\n"
VK_FORMAT_R8G8B8A8_UNORM = 37
VK_FORMAT_R8G8B8A8_SRGB = 43
VK_NAMES = {VK_FORMAT_R8G8B8A8_UNORM: "R8G8B8A8_UNORM", VK_FORMAT_R8G8B8A8_SRGB: "R8G8B8A8_SRGB"}
#: The DXGI format with the same texels (DXGI_FORMAT_R8G8B8A8_UNORM(_SRGB)), so code
#: written against :class:`atlasgen.io.dds.DDSImage` reads either container.
DXGI_EQUIVALENT = {VK_FORMAT_R8G8B8A8_UNORM: 28, VK_FORMAT_R8G8B8A8_SRGB: 29}
SUPERCOMPRESSION_NONE = 0
SUPERCOMPRESSION_ZSTD = 2
SUPERCOMPRESSION_NAMES = {SUPERCOMPRESSION_NONE: "none", SUPERCOMPRESSION_ZSTD: "zstd"}
#: Level 19 gets within 0.2 % of level 22 on the shipped library at half the time.
ZSTD_LEVEL = 19
#: RGBA8: the texel block is one 4-byte texel, so levels align to lcm(4, 4) = 4.
TEXEL_BLOCK_SIZE = 4
#: A reader refuses files whose levels would inflate to more than this (a decompression bomb): 64 MiB holds a
#: 4096x4096 RGBA8 texture, and the atlas is 2.8 MB. At 1 GiB a 33 KB file took 2 GB of memory, inflated and copied.
MAX_UNCOMPRESSED_BYTES = 64 << 20
#: The largest width, height or depth a reader accepts (Vulkan's ``maxImageDimension2D`` is
#: at least 4096, and 16384 on desktop GPUs; 65536 leaves room).
MAX_EXTENT = 1 << 16

# identifier, vkFormat, typeSize, pixelWidth/Height/Depth, layerCount, faceCount, levelCount,
# supercompressionScheme, dfdByteOffset/Length, kvdByteOffset/Length, sgdByteOffset/Length.
HEADER = struct.Struct("<12s9I4I2Q")
LEVEL_INDEX_ENTRY = struct.Struct("<3Q")

# Khronos Data Format Specification 1.3 (khr_df.h): the basic descriptor block.
KHR_DF_VENDORID_KHRONOS = 0
KHR_DF_KHR_DESCRIPTORTYPE_BASICFORMAT = 0
KHR_DF_VERSIONNUMBER_1_3 = 2
KHR_DF_MODEL_RGBSDA = 1
KHR_DF_PRIMARIES_BT709 = 1
KHR_DF_TRANSFER_LINEAR = 1
KHR_DF_TRANSFER_SRGB = 2
KHR_DF_FLAG_ALPHA_STRAIGHT = 0
KHR_DF_CHANNEL_RGBSDA_RED, KHR_DF_CHANNEL_RGBSDA_GREEN, KHR_DF_CHANNEL_RGBSDA_BLUE = 0, 1, 2
KHR_DF_CHANNEL_RGBSDA_ALPHA = 15
#: Qualifier bit of a sample's channelType byte: this sample is not sRGB-encoded.
KHR_DF_SAMPLE_DATATYPE_LINEAR = 0x10
BASIC_BLOCK_HEADER_BYTES = 24
SAMPLE_BYTES = 16


@dataclass
class KTX2Image:
    """A parsed RGBA8 KTX2. ``levels[k]`` is ``(layers_or_depth_k, h_k, w_k, 4)`` uint8, as in DDSImage."""

    width: int
    height: int
    depth: int
    array_size: int
    mip_count: int
    vk_format: int
    layout: str  # "array" or "volume"
    levels: list
    supercompression: int = SUPERCOMPRESSION_NONE
    key_values: dict = field(default_factory=dict)  # key -> raw value bytes

    @property
    def format_name(self) -> str:
        return VK_NAMES.get(self.vk_format, str(self.vk_format))

    @property
    def dxgi_format(self) -> int:
        """The equivalent DXGI format (28 or 29)."""
        return DXGI_EQUIVALENT[self.vk_format]

    @property
    def supercompression_name(self) -> str:
        return SUPERCOMPRESSION_NAMES.get(self.supercompression, str(self.supercompression))

    @property
    def layers(self) -> int:
        return self.array_size if self.layout == "array" else self.depth


def _basic_descriptor(srgb: bool) -> bytes:
    """``dfdTotalSize`` and the basic block of R8G8B8A8_UNORM / _SRGB.

    Samples R, G, B, A at bit offsets 0, 8, 16, 24, 8 bits each (bitLength stores
    length - 1), sampleLower 0 and sampleUpper 255. With the sRGB transfer function the
    alpha sample carries KHR_DF_SAMPLE_DATATYPE_LINEAR (KTX 2.0, "Restrictions").
    """
    channels = (KHR_DF_CHANNEL_RGBSDA_RED, KHR_DF_CHANNEL_RGBSDA_GREEN, KHR_DF_CHANNEL_RGBSDA_BLUE,
                KHR_DF_CHANNEL_RGBSDA_ALPHA)  # fmt: skip
    samples = b""
    for i, channel in enumerate(channels):
        qualifiers = KHR_DF_SAMPLE_DATATYPE_LINEAR if srgb and channel == KHR_DF_CHANNEL_RGBSDA_ALPHA else 0
        samples += struct.pack("<HBB4BII", 8 * i, 8 - 1, channel | qualifiers, 0, 0, 0, 0, 0, 255)
    block_size = BASIC_BLOCK_HEADER_BYTES + len(samples)
    block = struct.pack(
        "<IHH4B4B8B",
        (KHR_DF_KHR_DESCRIPTORTYPE_BASICFORMAT << 17) | KHR_DF_VENDORID_KHRONOS,
        KHR_DF_VERSIONNUMBER_1_3, block_size,
        KHR_DF_MODEL_RGBSDA, KHR_DF_PRIMARIES_BT709, KHR_DF_TRANSFER_SRGB if srgb else KHR_DF_TRANSFER_LINEAR,
        KHR_DF_FLAG_ALPHA_STRAIGHT,
        0, 0, 0, 0,  # texelBlockDimension0..3 store size - 1: a 1x1x1 block
        TEXEL_BLOCK_SIZE, 0, 0, 0, 0, 0, 0, 0,  # bytesPlane0..7
    )  # fmt: skip
    return struct.pack("<I", 4 + block_size) + block + samples


def _key_value_data(key_values: dict) -> bytes:
    """Entries sorted by the code points of their keys, each ``length, key NUL value`` padded to 4.

    A ``str`` value is written as NUL-terminated UTF-8, a ``bytes`` value as is.
    """
    out = b""
    for key in sorted(key_values):
        if not key or "\0" in key:
            raise ValueError(f"KTX2 key {key!r} must be non-empty and without NUL")
        value = key_values[key]
        value = value.encode() + b"\0" if isinstance(value, str) else bytes(value)
        entry = key.encode() + b"\0" + value
        out += struct.pack("<I", len(entry)) + entry + b"\0" * (-len(entry) % 4)
    return out


def encode_ktx2(levels: list[np.ndarray], layout: str, srgb: bool, key_values: dict, zstd: bool = False) -> bytes:
    """Serialise an RGBA8 mip chain as KTX 2.0 bytes.

    Parameters
    ----------
    levels
        uint8 arrays, level k shaped ``(n_k, h_k, w_k, 4)``: n_k is the layer count
        (constant) for ``layout="array"``, the depth (halving) for ``"volume"``.
    layout
        ``"array"`` (2D array: ``layerCount`` = n_0, ``pixelDepth`` 0) or ``"volume"``
        (3D: ``pixelDepth`` = n_0, ``layerCount`` 0).
    srgb
        ``VK_FORMAT_R8G8B8A8_SRGB`` (43) with the sRGB transfer function, or
        ``VK_FORMAT_R8G8B8A8_UNORM`` (37) with the linear one.
    key_values
        ``{key: str or bytes}`` for the key/value data (e.g. ``KTXwriter``). With
        ``zstd`` and a ``KTXwriter``, ``KTXwriterScParams`` records the level.
    zstd
        Supercompress each level as one Zstandard frame (scheme 2).
    """
    if layout not in ("array", "volume"):
        raise ValueError(f"layout must be 'array' or 'volume', not {layout!r}")
    n0, height, width, channels = levels[0].shape
    assert channels == 4 and all(lv.dtype == np.uint8 for lv in levels)
    volume = layout == "volume"
    if not 1 <= len(levels) <= max(width, height, n0 if volume else 1).bit_length():
        raise ValueError(f"{len(levels)} levels for {width}x{height}x{n0 if volume else 1}")
    for k, lv in enumerate(levels):
        expected = (max(1, n0 >> k) if volume else n0, max(1, height >> k), max(1, width >> k), 4)
        if lv.shape != expected:
            raise ValueError(f"level {k} has shape {lv.shape}; expected {expected}")
    raw = [np.ascontiguousarray(lv).tobytes() for lv in levels]
    key_values = dict(key_values)
    if zstd:
        compressor = zstandard.ZstdCompressor(level=ZSTD_LEVEL)
        stored = [compressor.compress(data) for data in raw]
        if "KTXwriter" in key_values:
            key_values.setdefault("KTXwriterScParams", f"--zstd {ZSTD_LEVEL}")
    else:
        stored = raw
    dfd = _basic_descriptor(srgb)
    kvd = _key_value_data(key_values)
    dfd_offset = HEADER.size + LEVEL_INDEX_ENTRY.size * len(levels)
    kvd_offset = dfd_offset + len(dfd)
    alignment = 1 if zstd else TEXEL_BLOCK_SIZE  # lcm(texel block size, 4), or 1 when supercompressed
    body = b""
    position = kvd_offset + len(kvd)  # no supercompression global data: no sgdPadding either
    offsets = [0] * len(levels)
    for k in reversed(range(len(levels))):  # smallest level first in the file
        padding = -position % alignment
        body += b"\0" * padding + stored[k]
        offsets[k] = position + padding
        position = offsets[k] + len(stored[k])
    header = HEADER.pack(
        KTX2_IDENTIFIER,
        VK_FORMAT_R8G8B8A8_SRGB if srgb else VK_FORMAT_R8G8B8A8_UNORM,
        1,  # typeSize: 8-bit components
        width, height, n0 if volume else 0, 0 if volume else n0,
        1,  # faceCount
        len(levels),
        SUPERCOMPRESSION_ZSTD if zstd else SUPERCOMPRESSION_NONE,
        dfd_offset, len(dfd), kvd_offset if kvd else 0, len(kvd),
        0, 0,  # sgdByteOffset, sgdByteLength
    )  # fmt: skip
    index = b"".join(LEVEL_INDEX_ENTRY.pack(offsets[k], len(stored[k]), len(raw[k])) for k in range(len(levels)))
    return header + index + dfd + kvd + body


#: The byte layout of the basic descriptor block (Khronos Data Format 1.3, section 5), after
#: ``dfdTotalSize``: ``(field, byte offset in the block, byte size, bit shift, bit width)``.
_BLOCK_FIELDS = (
    ("vendorId", 0, 4, 0, 17), ("descriptorType", 0, 4, 17, 15),
    ("versionNumber", 4, 2, 0, 16), ("descriptorBlockSize", 6, 2, 0, 16),
    ("colorModel", 8, 1, 0, 8), ("colorPrimaries", 9, 1, 0, 8), ("transferFunction", 10, 1, 0, 8), ("flags", 11, 1, 0, 8),
    *((f"texelBlockDimension{i}", 12 + i, 1, 0, 8) for i in range(4)),
    *((f"bytesPlane{i}", 16 + i, 1, 0, 8) for i in range(8)),
)  # fmt: skip
#: One sample's fields, at byte ``24 + 16 * sample`` of the block. The qualifiers are the
#: high four bits of the channelType byte: linear, exponent, signed, float.
_SAMPLE_FIELDS = (
    ("bitOffset", 0, 2, 0, 16), ("bitLength", 2, 1, 0, 8), ("channelType", 3, 1, 0, 4),
    ("qualifierLinear", 3, 1, 4, 1), ("qualifierExponent", 3, 1, 5, 1), ("qualifierSigned", 3, 1, 6, 1),
    ("qualifierFloat", 3, 1, 7, 1), *((f"samplePosition{i}", 4 + i, 1, 0, 8) for i in range(4)),
    ("sampleLower", 8, 4, 0, 32), ("sampleUpper", 12, 4, 0, 32),
)  # fmt: skip


def _descriptor_fields(dfd: bytes) -> list[tuple[str, int]]:
    """``(name, value)`` of every field of a DFD's basic block and its samples, in file order.

    ``dfd`` starts at ``dfdTotalSize``; the samples are as many as ``descriptorBlockSize``
    says, as far as the bytes go (a short block is the caller's to refuse).
    """
    block = dfd[4:]

    def value(base: int, offset: int, size: int, shift: int, width: int) -> int:
        return (int.from_bytes(block[base + offset : base + offset + size], "little") >> shift) & ((1 << width) - 1)

    fields = [(name, value(0, *layout)) for name, *layout in _BLOCK_FIELDS]
    block_size = dict(fields)["descriptorBlockSize"]
    for k in range(max(0, min(block_size, len(block)) - BASIC_BLOCK_HEADER_BYTES) // SAMPLE_BYTES):
        base = BASIC_BLOCK_HEADER_BYTES + SAMPLE_BYTES * k
        fields += [(f"samples[{k}].{name}", value(base, *layout)) for name, *layout in _SAMPLE_FIELDS]
    return fields


def _check_descriptor(path: Path, dfd: bytes, vk_format: int) -> None:
    """Refuse a DFD that is not, field by field, the basic block of ``vk_format``.

    KTX 2.0 requires the DFD to describe ``vkFormat`` exactly, and libktx decodes by the
    DFD: a transfer function, colour model, plane size or sample that disagrees would be
    read otherwise by an engine. The one DFD each of R8G8B8A8_UNORM and _SRGB has is
    :func:`_basic_descriptor`'s; the first field that differs is named.
    """
    expected = _basic_descriptor(vk_format == VK_FORMAT_R8G8B8A8_SRGB)
    block_size = int.from_bytes(dfd[10:12], "little") if len(dfd) >= 12 else 0
    if len(dfd) < 4 + BASIC_BLOCK_HEADER_BYTES:
        raise _field_error(path, "dfdByteLength", f"{len(dfd)}; expected {len(expected)} for {VK_NAMES[vk_format]}")
    if 4 + block_size > len(dfd):
        raise _field_error(path, "dfd.descriptorBlockSize", f"{block_size} bytes run past the {len(dfd)}-byte DFD")
    got, want = _descriptor_fields(dfd), dict(_descriptor_fields(expected))
    for name, value in got:
        if name not in want:
            raise _field_error(path, f"dfd.{name}", f"a sample {VK_NAMES[vk_format]} does not have (it has 4: R, G, B, A)")
        if value != want[name]:
            raise _field_error(
                path, f"dfd.{name}", f"{value}; expected {want[name]} for vkFormat {vk_format} ({VK_NAMES[vk_format]})"
            )
    if len(got) != len(want):
        raise _field_error(path, "dfd.descriptorBlockSize", f"{block_size}; expected {len(expected) - 4} (4 samples: R, G, B, A)")
    if len(dfd) != len(expected):
        raise _field_error(path, "dfdByteLength", f"{len(dfd)}; expected {len(expected)} (one basic block)")


def _field_error(path: Path, name: str, problem: str) -> InputError:
    return InputError(f"{path.as_posix()}: KTX2 field '{name}': {problem}")


def _check_span(path: Path, name: str, offset: int, length: int, size: int, offset_name: str | None = None) -> None:
    """Refuse a span past the end of the file, naming ``offset_name`` (the span's offset field) where the offset
    itself lies past it, else ``name`` (its length field)."""
    if offset + length > size:
        field = offset_name if offset_name is not None and offset > size else name
        raise _field_error(path, field, f"bytes {offset}..{offset + length} lie past the end of the {size}-byte file")


def _read_key_values(path: Path, data: bytes, offset: int, length: int) -> dict:
    """The key/value entries, read to KTX 2.0's section 3.11: keys UTF-8 without a BOM, NUL-terminated, unique
    and sorted by code point (UTF-8 byte order); each entry's valuePadding 0x00 bytes; and kvdByteLength exactly
    the entries with their padding ("any file that does not meet the above condition is invalid"). Values are
    not required to end in NUL (readers "must not rely on NUL termination")."""
    key_values: dict[str, bytes] = {}
    previous = None
    pos, end = offset, offset + length
    while pos < end:
        if pos + 4 > end:
            raise _field_error(path, "keyAndValueByteLength", f"truncated at byte {pos}")
        (entry_length,) = struct.unpack_from("<I", data, pos)
        if entry_length < 2 or pos + 4 + entry_length > end:
            raise _field_error(path, "keyAndValueByteLength", f"{entry_length} at byte {pos} overruns kvdByteLength {length}")
        entry = data[pos + 4 : pos + 4 + entry_length]
        nul = entry.find(b"\0")
        if nul < 1:
            raise _field_error(path, "keyAndValue", f"entry at byte {pos} has no NUL-terminated key")
        key = entry[:nul]
        try:
            if key.startswith(b"\xef\xbb\xbf"):
                raise UnicodeError
            key.decode("utf-8")
        except UnicodeError:
            raise _field_error(path, "keyAndValue", f"key {shorten(repr(key))} at byte {pos}; expected UTF-8 without a "
                                                    "byte order mark (KTX 2.0)") from None  # fmt: skip
        if previous is not None and key <= previous:
            problem = "appears twice" if key == previous else f"comes after {previous.decode('utf-8', 'replace')!r}"
            raise _field_error(path, "keyAndValue", f"key {key.decode('utf-8', 'replace')!r} at byte {pos} {problem}; "
                                                    "expected unique keys sorted by code point (KTX 2.0)")  # fmt: skip
        previous = key
        key_values[key.decode("utf-8")] = entry[nul + 1 :]
        padding = data[pos + 4 + entry_length : min(pos + 4 + entry_length + (-entry_length % 4), end)]
        if any(padding):
            raise _field_error(path, "valuePadding", f"{padding.hex()} after the entry at byte {pos}; expected 0x00 bytes")
        pos += 4 + entry_length + (-entry_length % 4)
    if pos != end:
        raise _field_error(path, "kvdByteLength", f"{length}; expected {pos - offset}, its entries with their "
                                                  "valuePadding (KTX 2.0: any other length makes the file invalid)")  # fmt: skip
    return key_values


def _inflate(path: Path, level: int, frame: bytes, expected: int) -> bytes:
    """One level's Zstandard frames, inflated to at most ``expected + 1`` bytes."""
    name = f"levels[{level}]"
    try:
        reader = zstandard.ZstdDecompressor().stream_reader(frame, read_across_frames=True)
        out = bytearray()
        while len(out) <= expected:
            chunk = reader.read(expected + 1 - len(out))
            if not chunk:
                break
            out += chunk
    except zstandard.ZstdError as exc:
        raise _field_error(path, name, f"corrupt Zstandard data ({exc})") from None
    except MemoryError:  # within the limit, yet more than this machine has free
        raise _field_error(path, name, f"cannot inflate {expected} bytes in the memory available") from None
    if len(out) > expected:
        raise _field_error(path, name, f"inflates to more than uncompressedByteLength {expected} bytes")
    if len(out) < expected:
        raise _field_error(path, name, f"inflates to {len(out)} bytes; expected {expected}")
    _check_whole_frames(path, name, frame)
    return bytes(out)


def _check_whole_frames(path: Path, name: str, data: bytes) -> None:
    """Refuse a level whose last Zstandard frame is cut short: the stream reader above stops once it has the level's
    bytes, and a frame missing its checksum, or followed by the start of another, passed as whole. Each frame is
    decoded again up to its end (the data inflated to the level's size already, so this is bounded)."""
    rest = data
    while rest:
        decoder = zstandard.ZstdDecompressor().decompressobj()
        try:
            decoder.decompress(rest)
        except zstandard.ZstdError as exc:
            raise _field_error(path, name, f"corrupt Zstandard data ({exc})") from None
        if not decoder.eof:
            raise _field_error(path, name, f"a Zstandard frame cut short at byte {len(data)} of the level; expected "
                                           "whole frames")  # fmt: skip
        rest = decoder.unused_data


def read_ktx2(path, data: bytes | None = None) -> KTX2Image:
    """Parse an RGBA8 KTX2 2D array or 3D texture, uncompressed or Zstandard-supercompressed.

    Every offset and length is checked against the file before anything is sliced or
    inflated; a bad one raises a one-line :class:`InputError` naming the file and field.
    The Data Format Descriptor must be, field by field, the one ``vkFormat`` has
    (:func:`_check_descriptor`), and the key/value keys unique and sorted.
    ``data``: the file's bytes, when the caller has read them already.
    """
    path = Path(path)
    if data is None:
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise InputError(f"{path.as_posix()}: cannot read ({exc.strerror})") from None
    size = len(data)
    if size < HEADER.size or data[:12] != KTX2_IDENTIFIER:
        raise InputError(f"{path.as_posix()}: not a KTX2 file (bad identifier or truncated header)")
    (_, vk_format, type_size, width, height, depth, layer_count, face_count, level_count, scheme,
     dfd_offset, dfd_length, kvd_offset, kvd_length, sgd_offset, sgd_length) = HEADER.unpack_from(data)  # fmt: skip
    if vk_format not in VK_NAMES:
        raise _field_error(path, "vkFormat", f"{vk_format} is not R8G8B8A8_UNORM (37) or R8G8B8A8_SRGB (43)")
    if type_size != 1:
        raise _field_error(path, "typeSize", f"{type_size}; expected 1 for 8-bit components")
    if face_count != 1:
        raise _field_error(path, "faceCount", f"{face_count}; expected 1 (no cubemaps)")
    for name, extent in (("pixelWidth", width), ("pixelHeight", height), ("pixelDepth", depth)):
        if extent > MAX_EXTENT or (extent == 0 and name != "pixelDepth"):
            raise _field_error(
                path, name, f"{extent}; expected 1 to {MAX_EXTENT}" + " (0 for a 2D array)" * (name == "pixelDepth")
            )
    if (depth == 0) == (layer_count == 0):
        raise _field_error(
            path,
            "pixelDepth",
            f"{width}x{height}x{depth} with layerCount {layer_count}; "
            "expected a 2D array (pixelDepth 0, layerCount > 0) or a 3D texture (the reverse)",
        )
    volume = depth > 0
    max_levels = max(width, height, depth).bit_length()  # floor(log2(max)) + 1
    mip_count = max(1, level_count)
    if mip_count > max_levels:
        raise _field_error(path, "levelCount", f"{level_count} exceeds the {max_levels} levels of {width}x{height}x{depth}")
    if scheme not in SUPERCOMPRESSION_NAMES:
        raise _field_error(path, "supercompressionScheme", f"{scheme}; expected 0 (none) or 2 (Zstandard)")
    index_end = HEADER.size + LEVEL_INDEX_ENTRY.size * mip_count
    _check_span(path, "levels", HEADER.size, index_end - HEADER.size, size)
    _check_span(path, "dfdByteLength", dfd_offset, dfd_length, size, "dfdByteOffset")
    _check_span(path, "kvdByteLength", kvd_offset, kvd_length, size, "kvdByteOffset")
    _check_span(path, "sgdByteLength", sgd_offset, sgd_length, size, "sgdByteOffset")
    if dfd_offset < index_end or dfd_length < 4 or struct.unpack_from("<I", data, dfd_offset)[0] != dfd_length:
        raise _field_error(path, "dfdByteOffset", f"no Data Format Descriptor of {dfd_length} bytes at byte {dfd_offset}")
    _check_descriptor(path, data[dfd_offset : dfd_offset + dfd_length], vk_format)
    if sgd_length != 0:
        raise _field_error(path, "sgdByteLength", f"{sgd_length}; expected 0 (no global data for this scheme)")
    if sgd_offset != 0:  # KTX 2.0, 3.10: with no supercompression global data both are 0
        raise _field_error(path, "sgdByteOffset", f"{sgd_offset}; expected 0 where sgdByteLength is 0")
    key_values = _read_key_values(path, data, kvd_offset, kvd_length)

    levels = []
    total = 0
    for k in range(mip_count):
        offset, length, uncompressed = LEVEL_INDEX_ENTRY.unpack_from(data, HEADER.size + LEVEL_INDEX_ENTRY.size * k)
        n = max(1, depth >> k) if volume else layer_count
        shape = (n, max(1, height >> k), max(1, width >> k), 4)
        expected = n * shape[1] * shape[2] * 4
        name = f"levels[{k}]"
        total += expected
        if total > MAX_UNCOMPRESSED_BYTES:
            raise _field_error(
                path,
                "layerCount",
                f"{width}x{height}x{depth} with {layer_count} layers and "
                f"{mip_count} levels exceeds the {MAX_UNCOMPRESSED_BYTES}-byte limit",
            )
        if uncompressed != expected:
            # The header's extents or this entry: a flipped pixelWidth shows here first, so both are named.
            extent = f"pixelDepth {depth}" if volume else f"layerCount {layer_count}"
            raise _field_error(path, f"{name}.uncompressedByteLength", f"{uncompressed}; expected {expected}, the bytes of "
                               f"level {k} {shape} of pixelWidth {width}, pixelHeight {height} and {extent} (one of those "
                               "header fields or this entry is wrong)")  # fmt: skip
        _check_span(path, f"{name}.byteLength", offset, length, size, f"{name}.byteOffset")
        if scheme == SUPERCOMPRESSION_NONE:
            if length != expected:
                raise _field_error(path, f"{name}.byteLength", f"{length}; expected {expected}")
            if offset % TEXEL_BLOCK_SIZE:
                raise _field_error(path, f"{name}.byteOffset", f"{offset} is not a multiple of {TEXEL_BLOCK_SIZE}")
            texels = np.frombuffer(data, np.uint8, expected, offset)
        else:
            texels = np.frombuffer(_inflate(path, k, data[offset : offset + length], expected), np.uint8)
        levels.append(texels.reshape(shape))
    # The base level ends the file (KTX 2.0, "File Structure": levels follow, smallest first): bytes appended after
    # it were read without a word, where the DDS reader refuses them.
    entries = [LEVEL_INDEX_ENTRY.unpack_from(data, HEADER.size + LEVEL_INDEX_ENTRY.size * k) for k in range(mip_count)]
    end = max(offset + length for offset, length, _ in entries)
    if end != size:
        raise _field_error(path, "levels", f"the last level stored ends at byte {end}, the file has {size} bytes; "
                           "expected the base level to end the file")  # fmt: skip
    return KTX2Image(width, height, depth if volume else 1, 1 if volume else layer_count, mip_count, vk_format,
                     "volume" if volume else "array", levels, scheme, key_values)  # fmt: skip


def describe_ktx2(path, width, height, layers, mip_count, vk_format, layout, supercompression=SUPERCOMPRESSION_NONE) -> str:
    """One-line summary, e.g. ``atlas.ktx2 (64x32, 7 mips, 256 layers, R8G8B8A8_SRGB, 2DArray, zstd)``."""
    name = VK_NAMES.get(vk_format, str(vk_format))
    scheme = "" if supercompression == SUPERCOMPRESSION_NONE else f", {SUPERCOMPRESSION_NAMES.get(supercompression)}"
    shown = Path(path).as_posix()
    if layout == "volume":
        return f"{shown} ({width}x{height}x{layers}, {mip_count} mips, {name}, 3D{scheme})"
    return f"{shown} ({width}x{height}, {mip_count} mips, {layers} layers, {name}, 2DArray{scheme})"
