"""WGSL declarations written once in Python: struct layouts and integer constants.

A struct that the CPU fills and a shader reads is declared here as a list of fields with
WGSL types; its WGSL text, its byte size and its packing all come from that one
declaration, so the two sides cannot drift apart. Likewise an :class:`enum.IntEnum`
shared with a shader gives both the Python names and the WGSL ``const`` lines.

Layout rules are those of the WGSL specification, section "Memory Layout"
(https://www.w3.org/TR/WGSL/#memory-layouts):

==========================  =====================  ==============================
type                        AlignOf                SizeOf
==========================  =====================  ==============================
f32, u32, i32               4                      4
vec2<T>                     8                      8
vec3<T>                     16                     12
vec4<T>                     16                     16
matCxR<f32>                 AlignOf(vecR)          C * roundUp(AlignOf(vecR), SizeOf(vecR))
array<E, N>                 AlignOf(E)             N * roundUp(AlignOf(E), SizeOf(E))
struct S                    max AlignOf(member)    roundUp(AlignOf(S), end of last member)
==========================  =====================  ==============================

Each member's offset is the end of the previous member rounded up to the member's
alignment. The ``uniform`` address space adds constraints (same section, "Address
Space Layout Constraints"): struct and array members align to 16, array strides are
multiples of 16, and a struct member is followed by at least roundUp(16, its size)
bytes before the next member.

Matrices are given and returned in the usual maths convention (``m[row, col]``);
WGSL stores them column by column, which :meth:`Matrix.encode` takes care of.
"""

from __future__ import annotations

import enum
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

__all__ = [
    "Scalar",
    "Vector",
    "Matrix",
    "Array",
    "Field",
    "Struct",
    "F32",
    "U32",
    "I32",
    "vec2",
    "vec3",
    "vec4",
    "mat3x3",
    "mat4x4",
    "round_up",
    "uniform_violations",
    "wgsl_constant",
    "wgsl_constants",
]


def round_up(k: int, n: int) -> int:
    """roundUp(k, n) of the WGSL specification: the smallest multiple of k that is >= n."""
    return -(-n // k) * k


class WgslType(Protocol):
    """What every type here provides: its WGSL name, alignment and size, and its byte encoding."""

    @property
    def name(self) -> str: ...
    @property
    def align(self) -> int: ...
    @property
    def size(self) -> int: ...
    def encode(self, value: Any) -> bytes: ...
    def decode(self, data: bytes) -> Any: ...


@dataclass(frozen=True)
class Scalar:
    """A 32-bit scalar type: ``f32``, ``u32`` or ``i32``."""

    name: str
    dtype: str  # little-endian numpy type of one value
    suffix: str  # WGSL literal suffix

    align = 4
    size = 4

    def literal(self, value) -> str:
        """A WGSL literal of this type, e.g. ``3u``."""
        return repr(float(value)) if self.name == "f32" else f"{int(value)}{self.suffix}"

    def array(self, value, shape: tuple) -> np.ndarray:
        """``value`` as an array of this type with ``shape``; integers must be integral and in range."""
        raw = np.asarray(value)
        if raw.shape != shape:
            raise ValueError(f"{self.name}: expected shape {shape}, got {raw.shape}")
        if self.name != "f32":
            if raw.dtype.kind not in "iub":
                raise TypeError(f"{self.name}: expected integers, got {raw.dtype}")
            info = np.iinfo(self.dtype)
            if raw.size and (raw.min() < info.min or raw.max() > info.max):
                raise ValueError(f"{self.name}: values outside [{info.min}, {info.max}]")
        return raw.astype(self.dtype)

    def encode(self, value) -> bytes:
        return self.array(value, ()).tobytes()

    def decode(self, data: bytes):
        return np.frombuffer(data, dtype=self.dtype, count=1)[0]


F32 = Scalar("f32", "<f4", "")
U32 = Scalar("u32", "<u4", "u")
I32 = Scalar("i32", "<i4", "i")


@dataclass(frozen=True)
class Vector:
    """``vecN<T>``: N components of scalar type T (N = 2, 3 or 4)."""

    count: int
    scalar: Scalar = F32

    @property
    def name(self) -> str:
        return f"vec{self.count}<{self.scalar.name}>"

    @property
    def align(self) -> int:
        return 8 if self.count == 2 else 16

    @property
    def size(self) -> int:
        return 4 * self.count

    def encode(self, value) -> bytes:
        return self.scalar.array(value, (self.count,)).tobytes()

    def decode(self, data: bytes) -> np.ndarray:
        return np.frombuffer(data, dtype=self.scalar.dtype, count=self.count).copy()


def vec2(scalar: Scalar = F32) -> Vector:
    return Vector(2, scalar)


def vec3(scalar: Scalar = F32) -> Vector:
    return Vector(3, scalar)


def vec4(scalar: Scalar = F32) -> Vector:
    return Vector(4, scalar)


@dataclass(frozen=True)
class Array:
    """``array<E, N>``: N elements of type E, each padded to the element's alignment."""

    element: WgslType
    count: int

    @property
    def name(self) -> str:
        return f"array<{self.element.name}, {self.count}>"

    @property
    def align(self) -> int:
        return self.element.align

    @property
    def stride(self) -> int:
        return round_up(self.element.align, self.element.size)

    @property
    def size(self) -> int:
        return self.count * self.stride

    def encode(self, value) -> bytes:
        if len(value) != self.count:
            raise ValueError(f"{self.name}: expected {self.count} elements, got {len(value)}")
        pad = bytes(self.stride - self.element.size)
        return b"".join(self.element.encode(v) + pad for v in value)

    def decode(self, data: bytes):
        items = [self.element.decode(data[i * self.stride : i * self.stride + self.element.size]) for i in range(self.count)]
        return items if isinstance(self.element, Struct) else np.stack(items)


@dataclass(frozen=True)
class Matrix:
    """``matCxR<f32>``: C columns of ``vecR<f32>``, laid out exactly as ``array<vecR<f32>, C>``."""

    columns: int
    rows: int

    @property
    def name(self) -> str:
        return f"mat{self.columns}x{self.rows}<f32>"

    @property
    def as_array(self) -> Array:
        return Array(Vector(self.rows, F32), self.columns)

    @property
    def align(self) -> int:
        return self.as_array.align

    @property
    def size(self) -> int:
        return self.as_array.size

    def encode(self, value) -> bytes:
        """``value[row, col]`` (maths convention) written column by column."""
        return self.as_array.encode(F32.array(value, (self.rows, self.columns)).T)

    def decode(self, data: bytes) -> np.ndarray:
        return self.as_array.decode(data).T


mat3x3 = Matrix(3, 3)
mat4x4 = Matrix(4, 4)


@dataclass(frozen=True)
class Field:
    """One struct member: its name, WGSL type and a one-line comment for the WGSL text."""

    name: str
    type: WgslType
    doc: str = ""


class Struct:
    """A WGSL struct declared once: its text (:meth:`wgsl`), layout and packing.

    Parameters
    ----------
    name
        The struct's WGSL name.
    fields
        The members, in order.
    address_space
        ``"uniform"`` checks the uniform address space's extra constraints now and
        raises ``ValueError`` if the struct breaks one; ``"storage"`` checks nothing more.
    doc
        Comment lines written above the WGSL declaration.
    """

    def __init__(self, name: str, fields: Sequence[Field], address_space: str = "storage", doc: str = ""):
        if address_space not in ("uniform", "storage"):
            raise ValueError(f"address_space must be 'uniform' or 'storage', not {address_space!r}")
        names = [f.name for f in fields]
        if len(set(names)) != len(names) or not names:
            raise ValueError(f"struct {name}: member names must be unique and at least one, got {names}")
        self.name = name
        self.fields = tuple(fields)
        self.doc = doc
        offsets, end = {}, 0
        for f in self.fields:
            offsets[f.name] = round_up(f.type.align, end)
            end = offsets[f.name] + f.type.size
        #: Byte offset of each member.
        self.offsets = offsets
        self.align = max(f.type.align for f in self.fields)
        self.size = round_up(self.align, end)
        if address_space == "uniform":
            problems = uniform_violations(self)
            if problems:
                raise ValueError(f"struct {name} breaks the uniform layout rules: " + "; ".join(problems))

    def __repr__(self) -> str:
        return f"Struct({self.name!r}, size={self.size}, align={self.align})"

    def wgsl(self) -> str:
        """The WGSL declaration, with each member's offset and comment."""
        decls = [f"    {f.name}: {f.type.name}," for f in self.fields]
        width = max(len(d) for d in decls)
        lines = [f"// {line}" if line else "//" for line in self.doc.splitlines()]
        lines.append(f"// Generated by atlasgen.shaders.structs: size {self.size}, align {self.align}.")
        lines.append(f"struct {self.name} {{")
        for d, f in zip(decls, self.fields):
            comment = f"// {self.offsets[f.name]:>3}" + (f": {f.doc}" if f.doc else "")
            lines.append(f"{d.ljust(width)}  {comment}")
        lines.append("};")
        return "\n".join(lines) + "\n"

    def texel_of(self, name: str) -> tuple[int, int]:
        """``(texel, first component)`` of 32-bit scalar member ``name`` in the element's 16-byte texels.

        >>> Struct("S", [Field("a", vec3()), Field("b", U32)]).texel_of("b")
        (0, 3)
        """
        offset = self.offsets[name]
        return offset // 16, offset % 16 // 4

    def texel_reader_wgsl(self, function: str, texture: str = "", fetch=None, params: str = "index: u32") -> str:
        """WGSL ``fn FUNCTION(index: u32) -> NAME`` reading element ``index`` of an array of this struct
        stored as the rows of ``texture``, a ``texture_2d<u32>`` of format ``rgba32uint``: row ``index``
        holds the element's bytes (as :meth:`pack_array` packs them), 16 to a texel.

        ``fetch(i)``, if given, is instead the WGSL expression of the element's texel ``i`` (a
        ``vec4<u32>``; it may name ``params`` and the texels ``t0 .. t{i-1}`` read before it), and
        ``params`` the function's parameters: for elements stored elsewhere than rows of one texture.

        Why a texture: a software GPU (lavapipe) loads a storage-buffer member at a per-pixel index
        lane by lane with a bounds check each, where a texel fetch is one vector gather; and a
        texel fetch has no side effect, so the compiler drops the fetches of members a caller
        never reads. Every member must be 32-bit scalars lying within one texel.
        """
        if self.size % 16:
            raise ValueError(f"struct {self.name}: size {self.size} is not a whole number of 16-byte texels")
        args = []
        for f in self.fields:
            scalar = getattr(f.type, "scalar", f.type)
            count = getattr(f.type, "count", 1)
            offset = self.offsets[f.name]
            if (
                not isinstance(scalar, Scalar)
                or not isinstance(f.type, (Scalar, Vector))
                or offset // 16 != (offset + 4 * count - 1) // 16
            ):
                raise ValueError(f"struct {self.name}: member {f.name} is not 32-bit scalars within one texel")
            first = offset % 16 // 4
            value = f"t{offset // 16}.{'xyzw'[first : first + count]}"
            args.append(value if scalar is U32 else f"bitcast<{f.type.name}>({value})")
        if fetch is None:
            where = f"element `index` of a {self.name} array, one row of {texture}"

            def fetch(i):
                return f"textureLoad({texture}, vec2<u32>({i}u, index), 0)"
        else:
            where = f"a {self.name}, its texels as {fetch(0)}"
        texels = [f"    let t{i} = {fetch(i)};" for i in range(self.size // 16)]
        return "\n".join([
            f"// Generated by atlasgen.shaders.structs: {where}.",
            f"fn {function}({params}) -> {self.name} {{", *texels,
            f"    return {self.name}({', '.join(args)});", "}",
        ]) + "\n"  # fmt: skip

    def encode(self, value: Mapping) -> bytes:
        """The struct's bytes (``size`` of them) from a mapping of every member's value."""
        missing = [f.name for f in self.fields if f.name not in value]
        unknown = sorted(set(value) - set(self.offsets))
        if missing or unknown:
            raise ValueError(f"struct {self.name}: missing members {missing}, unknown members {unknown}")
        data = bytearray(self.size)
        for f in self.fields:
            offset = self.offsets[f.name]
            data[offset : offset + f.type.size] = f.type.encode(value[f.name])
        return bytes(data)

    def pack(self, **values) -> bytes:
        """:meth:`encode` with the members as keyword arguments."""
        return self.encode(values)

    def pack_array(self, items: Sequence[Mapping]) -> bytes:
        """The bytes of ``array<S>`` holding ``items``: each element ``size`` bytes apart."""
        return b"".join(self.encode(item) for item in items)

    def decode(self, data: bytes) -> dict:
        """The members' values from the struct's bytes: the inverse of :meth:`encode`."""
        if len(data) < self.size:
            raise ValueError(f"struct {self.name}: expected {self.size} bytes, got {len(data)}")
        return {f.name: f.type.decode(data[self.offsets[f.name] : self.offsets[f.name] + f.type.size]) for f in self.fields}

    unpack = decode


def uniform_violations(struct: Struct) -> list[str]:
    """Where ``struct`` breaks the uniform address space's layout constraints (WGSL spec).

    RequiredAlignOf(T, uniform) is roundUp(16, AlignOf(T)) for structs and arrays and
    AlignOf(T) otherwise; array strides must be multiples of 16; a struct-typed member
    must be followed by roundUp(16, its size) bytes before the next member starts.
    """
    problems = []

    def check_type(t, where):
        if isinstance(t, Array):
            if t.stride % 16:
                problems.append(f"{where}: array stride {t.stride} is not a multiple of 16")
            check_type(t.element, f"{where}[]")
        elif isinstance(t, Struct):
            fields = t.fields
            for i, f in enumerate(fields):
                required = round_up(16, f.type.align) if isinstance(f.type, (Array, Struct)) else f.type.align
                offset = t.offsets[f.name]
                if offset % required:
                    problems.append(f"{where}.{f.name}: offset {offset} is not a multiple of {required}")
                if isinstance(f.type, Struct) and i + 1 < len(fields):
                    gap = t.offsets[fields[i + 1].name] - offset
                    if gap < round_up(16, f.type.size):
                        problems.append(f"{where}.{f.name}: next member {gap} bytes on, needs {round_up(16, f.type.size)}")
                check_type(f.type, f"{where}.{f.name}")

    check_type(struct, struct.name)
    return problems


def wgsl_constant(name: str, scalar: Scalar, value, doc: str = "") -> str:
    """One ``const NAME: T = value;`` line, after an optional comment line."""
    line = f"const {name}: {scalar.name} = {scalar.literal(value)};"
    return f"// {doc}\n{line}\n" if doc else line + "\n"


def wgsl_constants(values: type[enum.IntEnum], prefix: str, scalar: Scalar = U32) -> str:
    """``const PREFIX_MEMBER: T = value;`` for each member of an integer enumeration, in order."""
    if scalar is F32:
        raise TypeError("enumeration constants must be u32 or i32")
    return "".join(wgsl_constant(f"{prefix}{member.name}", scalar, int(member)) for member in values)
