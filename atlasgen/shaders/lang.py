"""One description of shader code, spelled in WGSL, GLSL (Vulkan 4.50) or HLSL (SM 5+).

The generated include is a list of declarations (:class:`Const`, :class:`Array`,
:class:`Function`) whose statements are small typed records and whose expressions
are written once in a neutral C-like dialect:

- types ``f32 u32 i32 bool vec2 vec3 vec4 uvec4``, the resource types
  ``texture_array texture_3d texture_2d sampler``, and, for parameters, fixed-size arrays
  ``T[N]`` (``array<T, N>`` in WGSL, ``T name[N]`` in GLSL and HLSL);
- calls to functions spelled alike in the three languages, plus ``atan2``, ``inverseSqrt`` and the
  pseudo-calls ``splat3(x)``, ``sample_array(t, s, uv, layer, lod)`` and
  ``sample_3d(t, s, uvw, lod)`` and ``sample_2d(t, s, uv, lod)``, which each language spells its own way.

:func:`emit` translates the list into one language; nothing else in the package
writes shader syntax for the include, so the three files cannot drift apart.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

__all__ = [
    "LANGUAGES",
    "split_call",
    "Const",
    "Array",
    "Storage",
    "Function",
    "Comment",
    "Let",
    "Var",
    "Assign",
    "If",
    "For",
    "Return",
    "Switch",
    "switch_lines",
    "SWITCH_CASES_MAX",
    "emit",
    "float_literal",
]

LANGUAGES = ("wgsl", "glsl", "hlsl")

_TYPES = {
    "wgsl": {"f32": "f32", "u32": "u32", "i32": "i32", "bool": "bool", "vec2": "vec2<f32>", "vec3": "vec3<f32>",
             "vec4": "vec4<f32>", "uvec4": "vec4<u32>", "texture_array": "texture_2d_array<f32>",
             "texture_3d": "texture_3d<f32>", "texture_2d": "texture_2d<f32>", "sampler": "sampler"},
    "glsl": {"f32": "float", "u32": "uint", "i32": "int", "bool": "bool", "vec2": "vec2", "vec3": "vec3",
             "vec4": "vec4", "uvec4": "uvec4", "texture_array": "texture2DArray", "texture_3d": "texture3D",
             "texture_2d": "texture2D", "sampler": "sampler"},
    "hlsl": {"f32": "float", "u32": "uint", "i32": "int", "bool": "bool", "vec2": "float2", "vec3": "float3",
             "vec4": "float4", "uvec4": "uint4", "texture_array": "Texture2DArray<float4>",
             "texture_3d": "Texture3D<float4>", "texture_2d": "Texture2D<float4>", "sampler": "SamplerState"},
}  # fmt: skip
#: Functions whose name differs by language (the rest are spelled alike in all three).
_RENAMES = {"glsl": {"atan2": "atan", "inverseSqrt": "inversesqrt"}, "hlsl": {"inverseSqrt": "rsqrt", "mix": "lerp"}, "wgsl": {}}


def float_literal(x: float) -> str:
    """A float literal every language parses to the nearest f32 of ``x`` (``repr`` round-trips float64)."""
    text = repr(float(x))
    if "e" in text:
        mantissa, exponent = text.split("e")
        return f"{mantissa if '.' in mantissa else mantissa + '.0'}e{int(exponent)}"
    return text if "." in text else text + ".0"


# -- declarations and statements ------------------------------------------------------------------
@dataclass(frozen=True)
class Comment:
    text: str


@dataclass(frozen=True)
class Const:
    name: str
    type: str
    value: str
    comment: str = ""


@dataclass(frozen=True)
class Array:
    """A table of constants, declared as a private global in every language, not ``const``.

    WGSL allows a runtime index only into a ``var<private>``. GLSL and HLSL would accept ``const``, but
    glslang then copies the whole constant array into a function variable before each runtime index,
    and lavapipe compiles that copy into every invocation: the include test's GLSL and HLSL compute
    shaders took over ten times as long with a cold Mesa cache (see the commit that made them private).
    """

    name: str
    type: str
    values: tuple
    per_line: int = 1


@dataclass(frozen=True)
class Storage:
    """A table the host binds as a buffer, WGSL only: the renderer's form of an :class:`Array` whose values
    change with each bake (a buffer is rewritten, a constant table is compiled).

    ``space`` is ``"storage"`` (a read-only storage buffer, any length) or ``"uniform"`` (a uniform buffer of
    ``length`` elements: lavapipe gathers a storage read lane by lane, a uniform one it reads as a block)."""

    name: str
    type: str
    group: int
    binding: int
    space: str = "storage"
    length: int | None = None


@dataclass(frozen=True)
class Function:
    name: str
    ret: str
    params: tuple  # ((name, type), ...)
    body: tuple
    comment: str = ""


@dataclass(frozen=True)
class Let:
    type: str
    name: str
    value: str


@dataclass(frozen=True)
class Var:
    type: str
    name: str
    value: str


@dataclass(frozen=True)
class Assign:
    target: str
    value: str
    op: str = "="


@dataclass(frozen=True)
class If:
    cond: str
    then: tuple
    otherwise: tuple = ()


@dataclass(frozen=True)
class For:
    """``for (u32 var = start; var < end; var += 1)``."""

    var: str
    start: str
    end: str
    body: tuple


@dataclass(frozen=True)
class Return:
    value: str


@dataclass(frozen=True)
class Switch:
    """``switch (value)`` over u32 ``cases`` ((label, statements), ...), then ``default``."""

    value: str
    cases: tuple
    default: tuple = field(default=())


# -- expressions ----------------------------------------------------------------------------------
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def split_call(text: str, start: int) -> tuple[list[str], int]:
    """The top-level comma-separated arguments of the call whose '(' is at ``start``, and the index after ')'."""
    depth, args, current = 0, [], start + 1
    for i in range(start, len(text)):
        c = text[i]
        if c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
            if depth == 0:
                args.append(text[current:i])
                return [a.strip() for a in args if a.strip()], i + 1
        elif c == "," and depth == 1:
            args.append(text[current:i])
            current = i + 1
    raise ValueError(f"unbalanced parentheses in {text!r}")


def _pseudo(lang: str, name: str, a: list[str]) -> str:
    if name == "splat3":
        return {"wgsl": f"vec3<f32>({a[0]})", "glsl": f"vec3({a[0]})", "hlsl": f"((float3)({a[0]}))"}[lang]
    if name == "sample_array":
        t, s, uv, layer, lod = a
        return {"wgsl": f"textureSampleLevel({t}, {s}, {uv}, {layer}, {lod})",
                "glsl": f"textureLod(sampler2DArray({t}, {s}), vec3({uv}, float({layer})), {lod})",
                "hlsl": f"{t}.SampleLevel({s}, float3({uv}, float({layer})), {lod})"}[lang]  # fmt: skip
    if name == "sample_2d":
        t, s, uv, lod = a
        return {"wgsl": f"textureSampleLevel({t}, {s}, {uv}, {lod})",
                "glsl": f"textureLod(sampler2D({t}, {s}), {uv}, {lod})",
                "hlsl": f"{t}.SampleLevel({s}, {uv}, {lod})"}[lang]  # fmt: skip
    t, s, uvw, lod = a  # sample_3d
    return {"wgsl": f"textureSampleLevel({t}, {s}, {uvw}, {lod})",
            "glsl": f"textureLod(sampler3D({t}, {s}), {uvw}, {lod})",
            "hlsl": f"{t}.SampleLevel({s}, {uvw}, {lod})"}[lang]  # fmt: skip


def expr(lang: str, text: str) -> str:
    """``text`` in the neutral dialect, spelled in ``lang``."""
    out, i = [], 0
    while i < len(text):
        m = _IDENT.match(text, i)
        if m is None:
            out.append(text[i])
            i += 1
            continue
        if i > 0 and (text[i - 1].isdigit() or text[i - 1] == "."):  # a swizzle or an exponent
            out.append(m.group())
            i = m.end()
            continue
        word, i = m.group(), m.end()
        if word in ("splat3", "sample_array", "sample_3d", "sample_2d"):
            args, i = split_call(text, i)
            out.append(_pseudo(lang, word, [expr(lang, a) for a in args]))
        else:
            out.append(_TYPES[lang].get(word, _RENAMES[lang].get(word, word)))
    return "".join(out)


# -- emitters -------------------------------------------------------------------------------------
def _decl(lang: str, type_: str, name: str, mutable: bool) -> str:
    if lang == "wgsl":
        return f"{'var' if mutable else 'let'} {name}: {_TYPES[lang][type_]}"
    return f"{_TYPES[lang][type_]} {name}"


_ARRAY_TYPE = re.compile(r"^(\w+)\[(\d+)\]$")


def _param(lang: str, name: str, type_: str) -> str:
    """One function parameter; ``T[N]`` is a fixed-size array, passed by value."""
    t = _TYPES[lang]
    m = _ARRAY_TYPE.match(type_)
    if m is None:
        return f"{name}: {t[type_]}" if lang == "wgsl" else f"{t[type_]} {name}"
    base, count = t[m[1]], m[2]
    return f"{name}: array<{base}, {count}>" if lang == "wgsl" else f"{base} {name}[{count}]"


def _statements(lang: str, body, indent: int) -> list[str]:
    pad = "    " * indent
    lines = []
    for st in body:
        if isinstance(st, Comment):
            lines += [f"{pad}// {line}" for line in st.text.splitlines()]
        elif isinstance(st, (Let, Var)):
            lines.append(f"{pad}{_decl(lang, st.type, st.name, isinstance(st, Var))} = {expr(lang, st.value)};")
        elif isinstance(st, Assign):
            lines.append(f"{pad}{st.target} {st.op} {expr(lang, st.value)};")
        elif isinstance(st, Return):
            lines.append(f"{pad}return {expr(lang, st.value)};")
        elif isinstance(st, If):
            lines.append(f"{pad}if ({expr(lang, st.cond)}) {{")
            lines += _statements(lang, st.then, indent + 1)
            if st.otherwise:
                lines.append(f"{pad}}} else {{")
                lines += _statements(lang, st.otherwise, indent + 1)
            lines.append(f"{pad}}}")
        elif isinstance(st, For):
            init = _decl(lang, "u32", st.var, True)
            lines.append(
                f"{pad}for ({init} = {expr(lang, st.start)}; {st.var} < {expr(lang, st.end)}; {st.var} = {st.var} + 1u) {{"
            )
            lines += _statements(lang, st.body, indent + 1)
            lines.append(f"{pad}}}")
        elif isinstance(st, Switch):
            cases = [(label, " ".join(line.strip() for line in _statements(lang, case, 0))) for label, case in st.cases]
            default = " ".join(line.strip() for line in _statements(lang, st.default, 0))
            lines += switch_lines(lang, expr(lang, st.value), cases, default, pad)
        else:
            raise TypeError(f"not a statement: {st!r}")
    return lines


#: The most cases one switch statement holds. Mesa's lavapipe (22.3, the project's software GPU) miscompiled a switch
#: of about 80 cases or more from WGSL or GLSL: its default returned case 1's value and cases 0 and 1 swapped, so a
#: library of 256 materials had 174 material IDs read with another's flags and scale (measured; 65 cases were right).
SWITCH_CASES_MAX = 32


def _switch_head(lang: str, value: str) -> str:
    return f"switch {value} {{" if lang == "wgsl" else f"switch ({value}) {{"


def switch_lines(lang: str, value: str, cases, default: str, pad: str = "") -> list[str]:
    """``switch`` over the u32 ``value`` in ``lang``: ``cases`` ((label, body text), ...), then ``default`` (body text).

    Over :data:`SWITCH_CASES_MAX` cases, an outer switch on ``value >> 5`` picks a switch of the (at most 32) labels
    that share those bits, each with the same default: the same function, in switches a driver compiles right."""
    if len(cases) <= SWITCH_CASES_MAX:
        return [pad + _switch_head(lang, value), *(f"{pad}    case {label}u: {{ {body} }}" for label, body in cases),
                f"{pad}    default: {{ {default} }}", f"{pad}}}"]  # fmt: skip
    shift = SWITCH_CASES_MAX.bit_length() - 1
    groups: dict[int, list] = {}
    for label, body in cases:
        groups.setdefault(int(label) >> shift, []).append((label, body))
    lines = [pad + _switch_head(lang, f"({value}) >> {shift}u")]
    for block, group in groups.items():
        lines.append(f"{pad}    case {block}u: {{")
        lines += switch_lines(lang, value, group, default, pad + "        ")
        lines.append(f"{pad}    }}")
    return [*lines, f"{pad}    default: {{ {default} }}", f"{pad}}}"]


def _declaration(lang: str, d) -> list[str]:
    t = _TYPES[lang]
    if isinstance(d, Comment):
        return [f"// {line}" if line else "" for line in d.text.split("\n")]
    if isinstance(d, Const):
        tail = f"  // {d.comment}" if d.comment else ""
        value = expr(lang, d.value)
        return [{"wgsl": f"const {d.name}: {t[d.type]} = {value};{tail}",
                 "glsl": f"const {t[d.type]} {d.name} = {value};{tail}",
                 "hlsl": f"static const {t[d.type]} {d.name} = {value};{tail}"}[lang]]  # fmt: skip
    if isinstance(d, Array):
        n = len(d.values)
        head = {"wgsl": f"var<private> {d.name}: array<{t[d.type]}, {n}> = array<{t[d.type]}, {n}>(",
                "glsl": f"{t[d.type]} {d.name}[{n}] = {t[d.type]}[{n}](",
                "hlsl": f"static {t[d.type]} {d.name}[{n}] = {{"}[lang]  # fmt: skip
        values = [expr(lang, v) for v in d.values]
        rows = [", ".join(values[i : i + d.per_line]) for i in range(0, n, d.per_line)]
        # GLSL forbids a trailing comma in a constructor; WGSL and HLSL allow it.
        body = [f"    {row}," for row in rows]
        if lang == "glsl":
            body[-1] = body[-1][:-1]
        return [head, *body, "};" if lang == "hlsl" else ");"]
    if isinstance(d, Storage):
        if lang != "wgsl":
            raise ValueError(f"{d.name}: a storage buffer table is WGSL only, not {lang}")
        head = f"@group({d.group}) @binding({d.binding})"
        if d.space == "uniform":
            return [f"{head} var<uniform> {d.name}: array<{t[d.type]}, {d.length}>;"]
        return [f"{head} var<storage, read> {d.name}: array<{t[d.type]}>;"]
    if isinstance(d, Function):
        comment = [f"// {line}" for line in d.comment.splitlines()]
        params = ", ".join(_param(lang, name, ty) for name, ty in d.params)
        if lang == "wgsl":
            head = f"fn {d.name}({params}) -> {t[d.ret]} {{"
        else:
            head = f"{t[d.ret]} {d.name}({params}) {{"
        return [*comment, head, *_statements(lang, d.body, 1), "}"]
    raise TypeError(f"not a declaration: {d!r}")


def emit(lang: str, declarations) -> str:
    """The source text of ``declarations`` in ``lang`` (one of :data:`LANGUAGES`), one blank line between them."""
    if lang not in LANGUAGES:
        raise ValueError(f"unknown shader language {lang!r}; expected one of {', '.join(LANGUAGES)}")
    blocks = []
    for d in declarations:
        lines = _declaration(lang, d)
        # Runs of one-line constants stay together; everything else is set apart.
        if blocks and isinstance(d, Const) and isinstance(blocks[-1][0], Const):
            blocks[-1][1].extend(lines)
        else:
            blocks.append((d, lines))
    return "\n\n".join("\n".join(lines) for _, lines in blocks) + "\n"
