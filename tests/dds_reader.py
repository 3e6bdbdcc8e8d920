"""An independent DDS parser for the tests, written from the DirectXTex spec (DDS.h).

It shares no code with atlasgen.io.dds on purpose: a bug in the writer must not be
mirrored by the reader that checks it.
"""

from __future__ import annotations

import struct

import numpy as np

HEADER_FIELDS = (
    "dwSize dwFlags dwHeight dwWidth dwPitchOrLinearSize dwDepth dwMipMapCount".split()
    + [f"dwReserved1_{i}" for i in range(11)]
    + "pf_dwSize pf_dwFlags pf_dwFourCC pf_dwRGBBitCount pf_dwRBitMask pf_dwGBitMask pf_dwBBitMask pf_dwABitMask".split()
    + "dwCaps dwCaps2 dwCaps3 dwCaps4 dwReserved2".split()
)
DX10_FIELDS = "dxgiFormat resourceDimension miscFlag arraySize miscFlags2".split()


def parse(data: bytes) -> dict:
    """Header dicts and the mip levels as uint8 arrays, element-major for arrays, level-major for volumes."""
    assert data[:4] == b"DDS ", "magic"
    values = struct.unpack("<31I", data[4:128])
    header = dict(zip(HEADER_FIELDS, values))
    header["pf_dwFourCC"] = data[84:88]
    dx10 = dict(zip(DX10_FIELDS, struct.unpack("<5I", data[128:148])))
    w, h, mips = header["dwWidth"], header["dwHeight"], header["dwMipMapCount"]
    pos = 148
    if dx10["resourceDimension"] == 4:
        depth = header["dwDepth"]
        levels = []
        for k in range(mips):
            shape = (max(depth >> k, 1), max(h >> k, 1), max(w >> k, 1), 4)
            n = int(np.prod(shape))
            levels.append(np.frombuffer(data, np.uint8, n, pos).reshape(shape))
            pos += n
    else:
        layers = dx10["arraySize"]
        per_level = [[] for _ in range(mips)]
        for _element in range(layers):
            for k in range(mips):
                shape = (max(h >> k, 1), max(w >> k, 1), 4)
                n = int(np.prod(shape))
                per_level[k].append(np.frombuffer(data, np.uint8, n, pos).reshape(shape))
                pos += n
        levels = [np.stack(lv) for lv in per_level]
    return {"header": header, "dx10": dx10, "levels": levels, "consumed": pos, "size": len(data)}


def srgb_to_linear(c):
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x):
    x = np.asarray(x, dtype=np.float64)
    return np.where(x <= 0.0031308, x * 12.92, 1.055 * x ** (1 / 2.4) - 0.055)
