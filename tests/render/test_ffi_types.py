"""The fast typedef lookup gives cffi's own parse for every form it takes, and leaves the rest to it."""

from __future__ import annotations

import pytest

from atlasgen.render.ffi_types import install

wgpu_ffi = pytest.importorskip("wgpu.backends.wgpu_native._ffi")


#: A handle, a struct, an enum, a flags word, a callback and a function-pointer typedef of the header.
KINDS = ("WGPUTexture", "WGPUBufferDescriptor", "WGPUTextureFormat", "WGPUBufferUsage", "WGPUBufferMapCallback",
         "WGPUProcRenderPassEncoderDraw")  # fmt: skip


def _typedef_names(ffi, every: int = 45):
    names = sorted(k.split(" ", 1)[1] for k in ffi._parser._declarations if k.startswith("typedef "))
    assert set(KINDS) <= set(names)
    return sorted(set(names[::every]) | set(KINDS))


@pytest.mark.slow
def test_each_form_resolves_to_the_model_type_the_parser_builds():
    ffi = wgpu_ffi.ffi
    install(ffi)
    parser = ffi._parser
    fast = parser.parse_type_and_quals
    slow = type(parser).parse_type_and_quals.__get__(parser)  # cffi's own, which install() leaves on the class
    assert fast != slow
    names = _typedef_names(ffi)
    assert len(names) > 12
    for name in names:
        for form in (name, f"{name} *", f"{name}[]", f"{name}[3]", f"{name} *[2]", f" {name}  * "):
            assert fast(form) == slow(form), form


@pytest.mark.slow
def test_c_primitives_resolve_to_the_model_type_the_parser_builds():
    ffi = wgpu_ffi.ffi
    install(ffi)
    parser = ffi._parser
    fast = parser.parse_type_and_quals
    slow = type(parser).parse_type_and_quals.__get__(parser)
    # What wgpu-py allocates and casts besides the header's typedefs, and a few more.
    for name in ("uint8_t", "char", "uint32_t", "intptr_t", "uintptr_t", "int", "float", "double", "size_t", "int64_t"):
        for form in (name, f"{name} *", f"{name} []", f"{name}[4]"):
            assert fast(form) == slow(form), form
    for form in ("void *", "void"):
        assert fast(form) == slow(form), form


@pytest.mark.slow
def test_anything_else_goes_to_the_parser():
    ffi = wgpu_ffi.ffi
    install(ffi)
    parser = ffi._parser
    slow = type(parser).parse_type_and_quals.__get__(parser)
    # Not a plain typedef name with at most one * and one [N]: the parser's answer, whatever it is.
    for cdecl in ("unsigned int", "WGPUBufferDescriptor **", "WGPUBufferDescriptor *[2][3]", "void(*)(int)"):
        assert parser.parse_type_and_quals(cdecl) == slow(cdecl), cdecl
    assert ffi.typeof("WGPUBufferDescriptor *") is ffi.typeof("WGPUBufferDescriptor*")


HEADER = """
typedef struct Pair { int a; double b[3]; } Pair;
typedef enum Mode { MODE_A = 1, MODE_B = 7 } Mode;
typedef void (*Callback)(Pair const * pair, void * user);
int take(Pair * pair, Mode mode, Callback callback);
"""


def _declared(ffi) -> dict:
    return {name: (str(tp), quals) for name, (tp, quals) in ffi._parser._declarations.items()}


def test_cached_declarations_give_a_fresh_parser_what_the_parse_declared(tmp_path, monkeypatch):
    import cffi
    from cffi import cparser

    from atlasgen.render.ffi_types import cached_declarations

    cache = tmp_path / "cache"
    parsed = cffi.FFI()
    parsed.cdef(HEADER)  # no cache: cffi's own parse, the reference
    with cached_declarations(cache):
        first = cffi.FFI()
        first.cdef(HEADER)  # parsed, and stored
    (entry,) = cache.iterdir()
    calls = []
    monkeypatch.setattr(cparser.Parser, "_internal_parse", lambda self, source: calls.append(source))
    with cached_declarations(cache):
        loaded = cffi.FFI()
        loaded.cdef(HEADER)  # from the cache: no parse at all
        assert not calls
        other = cffi.FFI()
        other.cdef("typedef int Other;")  # another source: parsed
        assert len(calls) == 1
    assert _declared(loaded) == _declared(first) == _declared(parsed)
    assert loaded.sizeof("Pair") == parsed.sizeof("Pair") and loaded.cast("Mode", 7) == parsed.cast("Mode", 7)
    assert str(loaded.cast("Mode", 7)) == "<cdata 'Mode' 7: MODE_B>"
    assert str(loaded.typeof("Callback")) == str(parsed.typeof("Callback"))
    monkeypatch.undo()

    # A damaged entry is parsed again (and replaced), as is a pickle of another shape, which used to set half the
    # parser before failing (exit 1 on every render); a folder others may write to is never read.
    import pickle

    for damage in (b"not a pickle", pickle.dumps({"a": 1}), pickle.dumps((1, 2, 3, 4)), pickle.dumps(("x",))):
        entry.write_bytes(damage)
        with cached_declarations(cache):
            again = cffi.FFI()
            again.cdef(HEADER)
        assert _declared(again) == _declared(parsed) and entry.read_bytes() != damage
    cache.chmod(0o777)
    monkeypatch.setattr("pickle.loads", lambda data: pytest.fail("read a pickle from a shared folder"))
    with cached_declarations(cache):
        cffi.FFI().cdef(HEADER)
