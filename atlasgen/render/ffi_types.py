"""Type lookups for wgpu-py's cffi without a C parse: a named typedef, a pointer to it, an array of it.

wgpu-py (cffi's ABI mode) allocates every descriptor with ``ffi.new("WGPUXxx *")``, and cffi parses
each type string it has not seen with pycparser, after a prelude declaring every typedef of the
WebGPU header so that the parser knows their names: about 25 ms a string. Opening the device,
building the pipelines and drawing a frame use some 75 strings, about 2 s of every process that
renders (each CLI command, each ``make`` job, each test worker, ``atlasgen preview``). A string
that only names a declared typedef, with at most one ``*`` and one ``[N]`` or ``[]``, needs no
parse: :func:`install` resolves it from cffi's own table of declarations, to the model type
``cffi.cparser.Parser._get_type_and_quals`` builds for it (the same calls, in the same order);
every other string goes to the parser as before. ``tests/render/test_ffi_types.py`` checks the
two agree over the header's typedefs. The same holds for a C primitive (``uint8_t []``,
``char []``, ``uintptr_t``, ``void *``: wgpu-py's buffers and handles, 0.25 s of CPU a process),
which the parser resolves after the typedefs, through cffi's table of common types.
"""

from __future__ import annotations

import re

__all__ = ["install"]

_SIMPLE = re.compile(r"\s*([A-Za-z_]\w*)\s*(\*?)\s*(?:\[\s*(\d*)\s*\])?\s*")


def install(ffi) -> None:
    """Give ``ffi``'s parser the fast path for plain typedef names (idempotent)."""
    from cffi import model
    from cffi.commontypes import resolve_common_type

    parser = ffi._parser
    if getattr(parser, "_atlasgen_fast_types", False):
        return
    parse = parser.parse_type_and_quals

    def parse_type_and_quals(cdecl):
        match = _SIMPLE.fullmatch(cdecl)
        found = parser._declarations.get("typedef " + match.group(1)) if match else None
        if found is None and match:  # as cparser's IdentifierType: void, else the common types' table
            name = match.group(1)
            if name == "void":
                found = model.void_type, 0
            elif name in model.PrimitiveType.ALL_PRIMITIVE_TYPES:
                found = resolve_common_type(parser, name)
        if found is None:
            return parse(cdecl)
        tp, quals = found
        if match.group(2):  # as cparser's PtrDecl: the pointer carries no qualifier of its own
            tp, quals = parser._get_type_pointer(tp, quals), 0
        if match.group(3) is not None:  # as its ArrayDecl: the item's qualifiers are kept
            tp = model.ArrayType(tp, int(match.group(3)) if match.group(3) else None)
        return tp, quals

    parser.parse_type_and_quals = parse_type_and_quals
    parser._atlasgen_fast_types = True
