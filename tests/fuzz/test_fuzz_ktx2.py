"""Every field of a KTX2's Data Format Descriptor, perturbed: the reader refuses the file with
one line naming that field (KTX 2.0: the DFD must describe ``vkFormat`` exactly; libktx decodes
by the DFD, so a file whose DFD disagrees would be read otherwise by an engine).

The field layout is written here from the Khronos Data Format Specification 1.3, section 5
(basic descriptor block), independently of atlasgen/io/ktx2.py.
"""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.errors import InputError
from atlasgen.io.ktx2 import encode_ktx2, read_ktx2
from tests import ktx2_reader
from tests.fuzz.strategies import FUZZ

#: (name as the reader reports it, byte offset from the start of the basic block, bit offset, bit width)
BLOCK = [("vendorId", 0, 0, 17), ("descriptorType", 0, 17, 15), ("versionNumber", 4, 0, 16),
         ("descriptorBlockSize", 6, 0, 16), ("colorModel", 8, 0, 8), ("colorPrimaries", 9, 0, 8),
         ("transferFunction", 10, 0, 8), ("flags", 11, 0, 8),
         *[(f"texelBlockDimension{i}", 12 + i, 0, 8) for i in range(4)],
         *[(f"bytesPlane{i}", 16 + i, 0, 8) for i in range(8)]]  # fmt: skip
SAMPLE = [("bitOffset", 0, 0, 16), ("bitLength", 2, 0, 8), ("channelType", 3, 0, 4), ("qualifierLinear", 3, 4, 1),
          ("qualifierExponent", 3, 5, 1), ("qualifierSigned", 3, 6, 1), ("qualifierFloat", 3, 7, 1),
          *[(f"samplePosition{i}", 4 + i, 0, 8) for i in range(4)], ("sampleLower", 8, 0, 32), ("sampleUpper", 12, 0, 32)]  # fmt: skip
FIELDS = BLOCK + [(f"samples[{k}].{name}", 24 + 16 * k + at, bit, width) for k in range(4) for name, at, bit, width in SAMPLE]


def _tiny(srgb: bool) -> bytes:
    levels = [np.full((2, max(1, 2 >> k), max(1, 4 >> k), 4), 7 * k, np.uint8) for k in range(3)]
    return encode_ktx2(levels, "array", srgb, {"KTXwriter": "fuzz"})


def _block_start(blob: bytes) -> int:
    return ktx2_reader.parse(blob)["index"]["dfdByteOffset"] + 4  # after dfdTotalSize


def _perturb(blob: bytes, at: int, bit: int, width: int, value: int) -> bytes:
    size = (bit + width + 7) // 8
    size = 4 if size > 2 else size
    fmt = {1: "<B", 2: "<H", 4: "<I"}[size]
    (word,) = struct.unpack_from(fmt, blob, at)
    mask = ((1 << width) - 1) << bit
    out = bytearray(blob)
    struct.pack_into(fmt, out, at, (word & ~mask) | (value << bit))
    return bytes(out)


def test_the_layout_here_reads_the_writers_dfd_as_the_independent_reader_does():
    for srgb in (False, True):
        blob = _tiny(srgb)
        block = ktx2_reader.parse(blob)["dfd"]["block"]
        start = _block_start(blob)
        read = {name: (int.from_bytes(blob[start + at : start + at + 4], "little") >> bit) & ((1 << width) - 1)
                for name, at, bit, width in FIELDS}  # fmt: skip
        assert read["transferFunction"] == block["transferFunction"] == (2 if srgb else 1)
        assert read["bytesPlane0"] == block["bytesPlane"][0] == 4
        assert read["samples[3].bitLength"] + 1 == block["samples"][3]["bitLength"] == 8
        assert read["samples[3].qualifierLinear"] == block["samples"][3]["qualifierLinear"] == srgb
        assert read["samples[3].channelType"] == block["samples"][3]["channelType"] == 15


@pytest.mark.slow
@FUZZ
@given(srgb=st.booleans(), field=st.sampled_from(FIELDS), data=st.data())
def test_every_perturbed_dfd_field_is_refused_naming_it(tmp_path_factory, srgb, field, data):
    name, at, bit, width = field
    blob = _tiny(srgb)
    start = _block_start(blob)
    original = (int.from_bytes(blob[start + at : start + at + 4], "little") >> bit) & ((1 << width) - 1)
    value = data.draw(st.integers(0, (1 << width) - 1).filter(lambda v: v != original), label="value")
    path = tmp_path_factory.mktemp("dfd") / "bad.ktx2"
    path.write_bytes(_perturb(blob, start + at, bit, width, value))
    with pytest.raises(InputError) as refused:
        read_ktx2(path)
    message = str(refused.value)
    assert "\n" not in message and message.startswith(f"{path.as_posix()}: KTX2 field 'dfd.{name}': "), message


@pytest.mark.parametrize("name", [name for name, *_ in FIELDS])
def test_each_dfd_field_once(tmp_path, name):
    """The fast subset: every field set to a value it never has in an RGBA8 DFD."""
    _, at, bit, width = next(f for f in FIELDS if f[0] == name)
    blob = _tiny(True)
    start = _block_start(blob)
    original = (int.from_bytes(blob[start + at : start + at + 4], "little") >> bit) & ((1 << width) - 1)
    path = tmp_path / "bad.ktx2"
    path.write_bytes(_perturb(blob, start + at, bit, width, original ^ 1))
    with pytest.raises(InputError, match=rf"KTX2 field 'dfd\.{name.replace('[', '.').replace(']', '.')}'"):
        read_ktx2(path)
