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

Before any of that, importing wgpu-py's native backend parses the whole WebGPU header (``ffi.cdef``),
about 1 s of CPU in every such process. :func:`cached_declarations` keeps what that parse declares
(cffi's model types, pickled) in a private per-user cache, keyed by the header's text and the cffi,
pycparser and Python versions, and gives a fresh parser the same declarations on the next run.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import pickle
import re
import sys
from pathlib import Path

__all__ = ["install", "cached_declarations", "declarations_cache_dir"]

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


def declarations_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/atlasgen`` (``~/.cache/atlasgen``): where :func:`cached_declarations` keeps its entries."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "atlasgen"


def _private(folder: Path) -> bool:
    """Whether ``folder`` is ours alone (owner, no group or other write): a pickle is only read from such a one."""
    try:
        st = folder.stat()
    except OSError:
        return False
    return st.st_uid == os.getuid() and not st.st_mode & 0o022


@contextlib.contextmanager
def cached_declarations(cache_dir=None):
    """Within it, a cffi parser's first ``cdef`` of a source seen before loads that source's declarations
    from ``cache_dir`` (:func:`declarations_cache_dir` by default) instead of parsing it; an unseen one is
    parsed and stored. Only a parse into an empty parser with default options is cached; an entry that
    does not load is parsed again; a cache that cannot be written is skipped."""
    import cffi
    from cffi import cparser

    folder = Path(cache_dir) if cache_dir is not None else declarations_cache_dir()
    original = cparser.Parser.parse
    fields = ("_declarations", "_int_constants", "_included_declarations", "_anonymous_counter")

    def parse(self, csource, override=False, packed=False, pack=None, dllexport=False):
        if override or packed or pack or dllexport or self._declarations or not isinstance(csource, str):
            return original(self, csource, override, packed, pack, dllexport)
        versions = f"{cffi.__version__}:{cparser.pycparser.__version__}:{sys.version_info[:3]}:"
        key = hashlib.sha256(versions.encode() + csource.encode()).hexdigest()[:32]
        path = folder / f"cffi-declarations-{key}.pickle"
        if _private(folder):
            try:
                state = pickle.loads(path.read_bytes())
            except (OSError, pickle.UnpicklingError, EOFError, ValueError, TypeError, AttributeError):
                state = None
            # Checked whole before any field is set: a pickle of another shape (a damaged or foreign entry) set
            # half the parser, and the parse that followed failed on it (exit 1 on every render, for good).
            if isinstance(state, tuple) and [type(v) for v in state] == [type(getattr(self, f)) for f in fields]:
                for name, value in zip(fields, state, strict=True):
                    setattr(self, name, value)
                return None
        out = original(self, csource, override, packed, pack, dllexport)
        if not self._recomplete:
            with contextlib.suppress(OSError, pickle.PicklingError, TypeError, AttributeError):
                folder.mkdir(mode=0o700, parents=True, exist_ok=True)
                if _private(folder):
                    temporary = path.with_name(f".{path.name}.{os.getpid()}")
                    temporary.write_bytes(pickle.dumps(tuple(getattr(self, f) for f in fields), pickle.HIGHEST_PROTOCOL))
                    os.replace(temporary, path)
        return out

    cparser.Parser.parse = parse
    try:
        yield
    finally:
        cparser.Parser.parse = original
