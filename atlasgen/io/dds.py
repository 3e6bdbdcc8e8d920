"""DirectDraw Surface files with a DX10 header: RGBA8 2D arrays and volumes with mip chains.

Written from DirectXTex ``DDS.h`` / ``DirectXTexDDS.cpp``: magic ``DDS ``, a 124-byte
``DDS_HEADER``, a 20-byte ``DDS_HEADER_DXT10`` (fourCC ``DX10``), then the texels at
byte 148. An array stores element-major (each element with its whole mip chain); a
volume stores level-major (each level with all its depth slices).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from atlasgen.errors import InputError
from atlasgen.io.atomic import write_file_atomically

__all__ = [
    "DXGI_FORMAT_R8G8B8A8_UNORM",
    "DXGI_FORMAT_R8G8B8A8_UNORM_SRGB",
    "DDSImage",
    "encode_dds",
    "write_dds",
    "read_dds",
    "describe_dds",
    "describe_texture",
]

DXGI_FORMAT_R8G8B8A8_UNORM = 28
DXGI_FORMAT_R8G8B8A8_UNORM_SRGB = 29
DXGI_NAMES = {28: "R8G8B8A8_UNORM", 29: "R8G8B8A8_UNORM_SRGB"}

MAGIC = b"DDS "
DDSD_CAPS, DDSD_HEIGHT, DDSD_WIDTH, DDSD_PITCH = 0x1, 0x2, 0x4, 0x8
DDSD_PIXELFORMAT, DDSD_MIPMAPCOUNT, DDSD_DEPTH = 0x1000, 0x20000, 0x800000
DDSCAPS_COMPLEX, DDSCAPS_TEXTURE, DDSCAPS_MIPMAP = 0x8, 0x1000, 0x400000
DDSCAPS2_VOLUME = 0x200000
DDPF_FOURCC = 0x4
DIMENSION_TEXTURE2D, DIMENSION_TEXTURE3D = 3, 4
#: The atlas's alpha is a specular scale, not coverage: DDS_ALPHA_MODE_CUSTOM, the last of the modes.
ALPHA_MODE_CUSTOM = 4
#: miscFlags2's alpha-mode bits, and miscFlag's cube-map bit (DDS_HEADER_DXT10).
DDS_ALPHA_MODE_MASK = 0x7
DDS_RESOURCE_MISC_TEXTURECUBE = 0x4


@dataclass
class DDSImage:
    """A parsed RGBA8 DDS. ``levels[k]`` is ``(layers_or_depth_k, h_k, w_k, 4)`` uint8."""

    width: int
    height: int
    depth: int
    array_size: int
    mip_count: int
    dxgi_format: int
    layout: str  # "array" or "volume"
    levels: list

    @property
    def format_name(self) -> str:
        return DXGI_NAMES.get(self.dxgi_format, str(self.dxgi_format))

    @property
    def layers(self) -> int:
        return self.array_size if self.layout == "array" else self.depth


def encode_dds(levels: list[np.ndarray], layout: str, dxgi_format: int) -> bytes:
    """Serialise an RGBA8 mip chain as DDS bytes.

    Parameters
    ----------
    levels
        uint8 arrays, level k shaped ``(n_k, h_k, w_k, 4)``: n_k is the array size
        (constant) for ``layout="array"``, the depth (halving) for ``"volume"``.
    layout
        ``"array"`` (Texture2DArray) or ``"volume"`` (Texture3D).
    dxgi_format
        28 (UNORM) or 29 (UNORM_SRGB).
    """
    n0, height, width, channels = levels[0].shape
    assert channels == 4 and all(lv.dtype == np.uint8 for lv in levels)
    mip_count = len(levels)
    volume = layout == "volume"
    flags = DDSD_CAPS | DDSD_HEIGHT | DDSD_WIDTH | DDSD_PIXELFORMAT | DDSD_PITCH | DDSD_MIPMAPCOUNT
    caps = DDSCAPS_TEXTURE | DDSCAPS_COMPLEX | DDSCAPS_MIPMAP
    caps2 = 0
    depth = 0
    if volume:
        flags |= DDSD_DEPTH
        caps2 |= DDSCAPS2_VOLUME
        depth = n0
    pitch = width * 4
    pixel_format = struct.pack("<II4sIIIII", 32, DDPF_FOURCC, b"DX10", 0, 0, 0, 0, 0)
    header = struct.pack(
        "<7I44s32s4I4x",
        124, flags, height, width, pitch, depth, mip_count,
        b"\0" * 44, pixel_format, caps, caps2, 0, 0,
    )  # fmt: skip
    dx10 = struct.pack(
        "<5I",
        dxgi_format,
        DIMENSION_TEXTURE3D if volume else DIMENSION_TEXTURE2D,
        0,
        1 if volume else n0,
        ALPHA_MODE_CUSTOM,
    )
    if volume:
        body = b"".join(np.ascontiguousarray(lv).tobytes() for lv in levels)
    else:
        # Element-major: each array element followed by its own mip chain.
        body = b"".join(np.ascontiguousarray(lv[e]).tobytes() for e in range(n0) for lv in levels)
    return MAGIC + header + dx10 + body


def write_dds(path, levels, layout: str, dxgi_format: int) -> None:
    """Write :func:`encode_dds` output atomically to ``path``."""
    write_file_atomically(path, encode_dds(levels, layout, dxgi_format))


def read_dds(path, data: bytes | None = None) -> DDSImage:
    """Parse an RGBA8 DX10 DDS written by :func:`write_dds` (2D array or volume).

    The file is untrusted: every size field of the header (width, height, depth,
    arraySize, mipMapCount) is checked against the others and against the file's length
    before anything is allocated, and any mismatch is an :class:`InputError` naming the
    file and the field. ``data``: the file's bytes, when the caller has read them already.
    """
    path = Path(path)
    shown = path.as_posix()
    if data is None:
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise InputError(f"{shown}: cannot read ({exc.strerror})") from None
    if len(data) < 148 or data[:4] != MAGIC:
        raise InputError(f"{shown}: not a DDS file (bad magic or truncated header)")
    size, flags, height, width, _pitch, depth, mip_count = struct.unpack_from("<7I", data, 4)
    # ddspf (DDS_PIXELFORMAT) at header offset 72, after the 4-byte magic: its size, flags and fourCC. DirectXTex
    # refuses a ddspf.size other than 32, and reads the DX10 header only where the DDPF_FOURCC flag is set.
    pf_size, pf_flags = struct.unpack_from("<2I", data, 76)
    fourcc = data[84:88]
    if size != 124 or fourcc != b"DX10":
        raise InputError(f"{shown}: expected a DDS with a DX10 header")
    if pf_size != 32:
        raise InputError(f"{shown}: header field ddspf.size is {pf_size}; expected 32")
    if not pf_flags & DDPF_FOURCC:
        raise InputError(f"{shown}: header field ddspf.flags is {pf_flags:#x}; expected the DDPF_FOURCC bit "
                         f"({DDPF_FOURCC:#x}), which makes fourCC 'DX10' name a DX10 header")  # fmt: skip
    dxgi_format, dimension, misc, array_size, misc2 = struct.unpack_from("<5I", data, 128)
    if dxgi_format not in DXGI_NAMES:
        raise InputError(f"{shown}: DXGI format {dxgi_format} is not RGBA8")
    volume = dimension == DIMENSION_TEXTURE3D
    mip_count = max(1, mip_count if flags & DDSD_MIPMAPCOUNT else 1)

    def bad(field, value, expected):
        raise InputError(f"{shown}: header field {field} is {value}; expected {expected}")

    # As DirectXTex reads a DX10 header (LoadFromDDSMemory): the resource dimension says what the texture is,
    # a 3D one needs the DDSD_DEPTH flag and one array element, and a cube flag makes a 2D one a cube map.
    # Anything else it refuses, or reads as another texture than the one returned here. caps2 it ignores.
    if dimension not in (DIMENSION_TEXTURE2D, DIMENSION_TEXTURE3D):
        bad("resourceDimension", dimension, f"{DIMENSION_TEXTURE2D} (a 2D array) or {DIMENSION_TEXTURE3D} (a volume)")
    if misc & DDS_RESOURCE_MISC_TEXTURECUBE:
        bad("miscFlag", hex(misc), "no TEXTURECUBE bit (0x4): the atlas is no cube map")
    if volume and not flags & DDSD_DEPTH:
        bad("flags", hex(flags), f"the DDSD_DEPTH bit ({DDSD_DEPTH:#x}) in a volume (resourceDimension {dimension})")
    if volume and array_size != 1:
        bad("arraySize", array_size, "1 in a volume")
    if misc2 & DDS_ALPHA_MODE_MASK > ALPHA_MODE_CUSTOM:
        bad("miscFlags2", hex(misc2), f"an alpha mode of 0 to {ALPHA_MODE_CUSTOM} in its low bits")

    if width < 1:
        bad("width", width, "at least 1")
    if height < 1:
        bad("height", height, "at least 1")
    if volume and depth < 1:
        bad("depth", depth, "at least 1 in a volume")
    if not volume and array_size < 1:
        bad("arraySize", array_size, "at least 1 in an array")
    # A chain ends at 1x1(x1): one level per halving of the largest dimension, plus one.
    longest = max(width, height, depth if volume else 1)
    if mip_count > longest.bit_length():
        bad("mipMapCount", mip_count, f"at most {longest.bit_length()} for {width}x{height}" + (f"x{depth}" if volume else ""))
    shapes = []
    for k in range(mip_count):
        n = max(1, depth >> k) if volume else array_size
        shapes.append((n, max(1, height >> k), max(1, width >> k), 4))
    # Python integers: no overflow, and nothing is allocated by this sum.
    expected = 148 + sum(a * b * c * d for a, b, c, d in shapes)
    if len(data) != expected:
        fields = "width, height, " + ("depth" if volume else "arraySize") + " and mipMapCount"
        raise InputError(f"{shown}: header fields {fields} describe {expected} bytes, the file has {len(data)}")
    body = np.frombuffer(data, dtype=np.uint8, offset=148)
    levels = []
    if volume:
        offset = 0
        for s in shapes:
            count = int(np.prod(s))
            levels.append(body[offset : offset + count].reshape(s))
            offset += count
    else:
        per_element = [int(np.prod(s[1:])) for s in shapes]
        chain = body.reshape(array_size, sum(per_element))
        start = 0
        for s, count in zip(shapes, per_element):
            levels.append(chain[:, start : start + count].reshape(s))
            start += count
    return DDSImage(width, height, depth if volume else 1, 1 if volume else array_size, mip_count,
                    dxgi_format, "volume" if volume else "array", levels)  # fmt: skip


def describe_texture(path, width, height, layers, mip_count, dxgi_format, layout) -> str:
    """texconv-style one-line summary, e.g. ``atlas.dds (64x32, 7 mips, 256 layers, R8G8B8A8_UNORM_SRGB, 2DArray)``."""
    name = DXGI_NAMES.get(dxgi_format, str(dxgi_format))
    if layout == "volume":
        return f"{Path(path).as_posix()} ({width}x{height}x{layers}, {mip_count} mips, {name}, 3D)"
    return f"{Path(path).as_posix()} ({width}x{height}, {mip_count} mips, {layers} layers, {name}, 2DArray)"


def describe_dds(image: DDSImage, path) -> str:
    """:func:`describe_texture` of a parsed file."""
    return describe_texture(path, image.width, image.height, image.layers, image.mip_count, image.dxgi_format, image.layout)
