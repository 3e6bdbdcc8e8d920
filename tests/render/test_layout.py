"""The renderer's shared declarations: their sizes, and what ``declaration_wgsl`` refuses.

The layout rules themselves are tests/shaders/test_structs.py's; where the shader files take
these declarations, tests/shaders/test_passes.py's.
"""

from __future__ import annotations

import pytest

from atlasgen.render.layout import FRAME, LIGHT, OBJECT, OBJECT_UNIFORM_STRIDE, declaration_wgsl


def test_shared_structs_sizes():
    # Frame: a mat4x4 and eleven vec4s; Object: two mat4x4 and two vec4s; Light: three (vec3, 4-byte scalar)
    # pairs, then a vec2 and a u32 (the struct padded to its 16-byte alignment).
    assert FRAME.size == 64 + 11 * 16
    assert OBJECT.size == 2 * 64 + 2 * 16 and OBJECT_UNIFORM_STRIDE == 256
    assert LIGHT.offsets == {"position": 0, "range": 12, "radiant": 16, "index": 28, "direction": 32, "cos_outer": 44,
                             "cone": 48, "kind": 56}  # fmt: skip
    assert LIGHT.size == 64


def test_an_unknown_declaration_is_refused():
    with pytest.raises(ValueError, match="no shared WGSL declaration 'Nope'"):
        declaration_wgsl("Nope")
