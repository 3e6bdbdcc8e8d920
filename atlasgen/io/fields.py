"""Typed, validated material parameters: the schema each model declares for its TOML keys.

Every number crosses into float32 (the atlas's scales, the include's constants, the
shaders), so a parameter must be finite there too, and keep its bounds once rounded to
float32: ``rgb_scale = 1e300`` or ``alpha = 1e-50`` would become infinity or zero there.
Integers must fit a shader's ``i32``.
"""

from __future__ import annotations

import datetime
import math
import string
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

from atlasgen.errors import FieldError, MaterialError, did_you_mean, shorten
from atlasgen.optics.quantize import dequantize_rgba

__all__ = [
    "Param",
    "is_number",
    "check_keys",
    "validate_params",
    "parse_colour",
    "FLOAT32_MAX",
    "INT32_MAX",
    "fits_float32",
    "FLOAT32_MIN_NORMAL",
    "to_float32",
    "shown",
    "counted",
    "check_table_bounds",
    "MAX_TABLE_DEPTH",
    "MAX_TABLE_ENTRIES",
]

#: The largest finite float32, 3.4028235e38 (IEEE 754 binary32).
FLOAT32_MAX = struct.unpack("<f", b"\xff\xff\x7f\x7f")[0]
#: The smallest normal float32, 2^-126 = 1.1754944e-38: GPUs flush smaller (subnormal) values to 0.
FLOAT32_MIN_NORMAL = struct.unpack("<f", b"\x00\x00\x80\x00")[0]
#: The largest i32, what WGSL integer constants hold.
INT32_MAX = 2**31 - 1


def is_number(value) -> bool:
    """True for an int or a float, not a bool (which Python counts as an int).

    >>> is_number(1), is_number(2.5), is_number(True), is_number("1")
    (True, True, False, False)
    """
    return isinstance(value, int | float) and not isinstance(value, bool)


def fits_float32(value) -> bool:
    """True for an int or float (not a bool) that float32 holds finitely: abs(x) <= FLOAT32_MAX."""
    if not is_number(value):
        return False
    if isinstance(value, int):
        return abs(value) <= FLOAT32_MAX  # compared exactly: a 400-digit integer is no float
    return math.isfinite(value) and abs(value) <= FLOAT32_MAX


def to_float32(value) -> float:
    """``value`` rounded to the nearest float32 (``value`` must satisfy :func:`fits_float32`)."""
    return struct.unpack("<f", struct.pack("<f", float(value)))[0]


def counted(count: int, noun: str) -> str:
    """``count`` and ``noun``, plural unless the count is 1 (every noun here takes an s).

    >>> counted(1, "material"), counted(0, "light"), counted(3, "slice")
    ('1 material', '0 lights', '3 slices')
    """
    return f"{count} {noun}{'' if count == 1 else 's'}"


def shown(value, limit: int = 80) -> str:
    """``repr(value)`` for a one-line message, shortened when long (a 400-digit integer); a TOML date or time,
    and a boolean, as the file wrote it, not as Python's repr.

    >>> shown(datetime.date(1979, 5, 27)), shown([0.5, 2]), shown(True)
    ('a date 1979-05-27', '[0.5, 2]', 'true')
    >>> shown(16 ** 5000)  # beyond what Python writes out as digits
    'an integer of 20001 bits (about 6021 digits)'
    >>> shown("b" * 250)  # the string's own length, not its repr's (with the quotes)
    "'bbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbbb'... (250 characters)"
    """
    if isinstance(value, bool):
        return "true" if value else "false"
    for kind, cls in (("date and time", datetime.datetime), ("date", datetime.date), ("time", datetime.time)):
        if isinstance(value, cls):  # a datetime is a date too: it is tried first
            return shorten(f"a {kind} {value.isoformat()}", limit)
    if isinstance(value, str) and len(repr(value)) > limit:
        return f"{repr(value[: limit - 14])}... ({len(value)} characters)"
    return shorten(_written(value), limit)


def _written(value, budget: int = 400, depth: int = 0) -> str:
    """``repr(value)``, but an integer too long to write out (in a list or table too) by its size, and a list or table
    written only as far as a line shows (about ``budget`` characters, ``...`` for the rest; ``[...]`` below
    :data:`_DEPTH_SHOWN` levels).

    Python refuses to write an integer of over 4300 digits (``sys.int_max_str_digits``), which a 3.6 kB TOML hex
    literal is: its repr raised ValueError, an internal error where the field's line was due. A list nested 500 deep
    exceeded the recursion limit (an internal error too), and one of 33 million numbers was written out whole to show
    80 characters of it.

    >>> _written([16 ** 5000, 0.5]), _written({"a": -(2 ** 4001)})
    ('[an integer of 20001 bits (about 6021 digits), 0.5]', "{'a': -an integer of 4002 bits (about 1205 digits)}")
    >>> nested = 1
    >>> for _ in range(21):
    ...     nested = [nested]
    >>> _written(nested), len(_written(list(range(10 ** 6))))
    ('[[[[[[[[[[[[[[[[[[[[[...]]]]]]]]]]]]]]]]]]]]]', 410)
    """
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > _INT_BITS_SHOWN:
        return f"{'-' if value < 0 else ''}an integer of {value.bit_length()} bits (about {_decimal_digits(value)} digits)"
    if isinstance(value, (list, tuple, dict)):
        opening, closing = "[]" if isinstance(value, list) else "()" if isinstance(value, tuple) else "{}"
        if depth >= _DEPTH_SHOWN:
            return f"{opening}...{closing}"
        parts, used = [], 0
        items = value.items() if isinstance(value, dict) else value
        for item in items:
            if used > budget:
                parts.append("...")
                break
            if isinstance(value, dict):
                k, v = item
                text = f"{_written(k, budget - used, depth + 1)}: {_written(v, budget - used, depth + 1)}"
            else:
                text = _written(item, budget - used, depth + 1)
            parts.append(text)
            used += len(text) + 2
        tail = "," if isinstance(value, tuple) and len(value) == 1 else ""
        return opening + ", ".join(parts) + tail + closing
    return repr(value)


#: Lists and tables nested deeper than this are shown as ``[...]``.
_DEPTH_SHOWN = 20


#: Integers up to this many bits are shown as written (about 1200 digits, cut to the line's limit); longer ones by size.
_INT_BITS_SHOWN = 4000


def _decimal_digits(value: int) -> int:
    """The decimal digits of ``|value|`` (``value != 0``), to within one, without writing it out: floor(log10 |value|) + 1.

    >>> _decimal_digits(10**5000), _decimal_digits(-999)
    (5001, 3)
    """
    return math.floor(math.log10(abs(value))) + 1


def parse_colour(value, path, name, error: type[FieldError] = MaterialError):
    """A colour as ``[r, g, b]`` linear floats in [0, 1], or an sRGB hex string ``"#rrggbb"``.

    Hex colours are what artists copy from a picker, so they are decoded from sRGB
    (IEC 61966-2-1) to the linear values the models work in.
    """
    if isinstance(value, str):
        text = value.strip()
        if len(text) == 7 and text[0] == "#" and all(c in string.hexdigits for c in text[1:]):
            codes = np.frombuffer(bytes.fromhex(text[1:]), dtype=np.uint8)
            return tuple(float(c) for c in dequantize_rgba(codes, srgb=True))
        raise error(path, name, f"expected a colour [r, g, b] or '#rrggbb', got {shown(value)}")
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise error(path, name, f"expected a colour [r, g, b] of 3 numbers in [0, 1], got {shown(value)}")
    out = []
    for c in value:
        if not fits_float32(c) or not 0.0 <= c <= 1.0:
            raise error(path, name, f"expected a colour [r, g, b] of 3 finite numbers in [0, 1], got {shown(value)}")
        out.append(float(c) + 0.0)  # -0.0 as 0.0, as Param._check_number
    return tuple(out)


@dataclass(frozen=True)
class Param:
    """One model parameter.

    ``kind`` is one of ``float``, ``int``, ``bool``, ``colour``, ``choice``, ``vec3``,
    ``float_list``, ``colour_list``, ``table`` (a free-form TOML table the model checks itself).
    Bounds are inclusive unless ``lo_open`` / ``hi_open``; a ``vec3``'s bounds hold per component.

    Material parameters and scene fields alike are checked by :meth:`coerce`, which raises
    ``error`` (:class:`~atlasgen.errors.MaterialError` or :class:`~atlasgen.errors.SceneError`).
    """

    name: str
    default: Any
    kind: str = "float"
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple = ()
    doc: str = ""
    required: bool = False
    nonzero: bool = False  # vec3: not all components zero
    alternative: str | None = None  # a word accepted as well, e.g. "auto"

    def expectation(self) -> str:
        if self.kind == "choice":
            return "one of " + ", ".join(repr(c) for c in self.choices)
        if self.kind == "bool":
            return "true or false"
        if self.kind == "colour":
            return "a colour [r, g, b] in [0, 1] or '#rrggbb'"
        parts = []
        if self.lo is not None:
            parts.append(f"{'>' if self.lo_open else '>='} {self.lo:g}")
        if self.hi is not None:
            parts.append(f"{'<' if self.hi_open else '<='} {self.hi:g}")
        noun = {"int": "an integer", "float_list": "a list of finite numbers", "colour_list": "a list of colours",
                "vec3": "[x, y, z] of 3 finite float32 numbers"}.get(self.kind, "a finite number")  # fmt: skip
        text = noun + (" " + " and ".join(parts) if parts else "")
        text += ", not all zero" if self.nonzero else ""
        return f'"{self.alternative}" or {text}' if self.alternative is not None else text

    def _out_of_bounds(self, value, in_float32=False) -> bool:
        """Outside the bounds; ``in_float32``: the value and the bounds rounded to float32."""
        lo, hi = self.lo, self.hi
        if in_float32:
            value = to_float32(value)
            lo = None if lo is None else to_float32(lo)
            hi = None if hi is None else to_float32(hi)
        lo_bad = lo is not None and (value <= lo if self.lo_open else value < lo)
        hi_bad = hi is not None and (value >= hi if self.hi_open else value > hi)
        return lo_bad or hi_bad

    def _check_number(self, value, path, name, integer=False, error: type[FieldError] = MaterialError):
        """A number within the bounds, in float32 too (ints: within i32)."""
        if isinstance(value, bool) or not isinstance(value, (int, float)) or (integer and not isinstance(value, int)):
            raise error(path, name, f"expected {self.expectation()}, got {shown(value)}")
        if integer:
            if abs(value) > INT32_MAX or self._out_of_bounds(value):
                raise error(path, name, f"expected {self.expectation()}, got {shown(value)}")
            return int(value)
        if not fits_float32(value):
            what = "beyond float32's range" if isinstance(value, int) or math.isfinite(value) else "not finite"
            raise error(path, name, f"expected {self.expectation()}, got {shown(value)} ({what})")
        if self._out_of_bounds(value):
            raise error(path, name, f"expected {self.expectation()}, got {shown(value)}")
        if self._out_of_bounds(value, in_float32=True):
            raise error(path, name, f"expected {self.expectation()}, got {shown(value)} "
                                            f"({to_float32(value):g} in float32)")  # fmt: skip
        # + 0.0 turns -0.0 into 0.0 (IEEE 754 round to nearest) and leaves every other value as it is: the same
        # material written with -0.0 echoed "-0.0" into the manifest, other bytes for the same texels.
        return float(value) + 0.0

    def coerce(self, value, path, error: type[FieldError] = MaterialError, name: str | None = None):
        """Check ``value`` against this schema; return it normalised (floats, tuples).

        ``name`` is the field as the message shows it (default: the parameter's name).
        """
        name = self.name if name is None else name
        if self.alternative is not None and value == self.alternative:
            return value
        if self.kind == "vec3":
            parts = value if isinstance(value, (list, tuple)) else None
            if parts is None or len(parts) != 3:
                raise error(path, name, f"expected {self.expectation()}, got {shown(value)}")
            scalar = Param(name, None, "float", self.lo, self.hi, self.lo_open, self.hi_open)
            try:
                out = tuple(scalar._check_number(c, path, name, error=error) for c in parts)
            except FieldError:
                raise error(path, name, f"expected {self.expectation()}, got {shown(value)}") from None
            if self.nonzero and not any(out):
                raise error(path, name, f"expected {self.expectation()}, got {shown(value)}")
            return out
        if self.kind == "float":
            return self._check_number(value, path, name, error=error)
        if self.kind == "int":
            return self._check_number(value, path, name, integer=True, error=error)
        if self.kind == "bool":
            if not isinstance(value, bool):
                raise error(path, name, f"expected true or false, got {shown(value)}")
            return value
        if self.kind == "colour":
            return parse_colour(value, path, name, error)
        if self.kind == "choice":
            if value not in self.choices:
                raise error(path, name, f"expected {self.expectation()}, got {shown(value)}")
            return value
        if self.kind == "float_list":
            if not isinstance(value, list):
                raise error(path, name, f"expected {self.expectation()}, got {shown(value)}")
            return tuple(self._check_number(v, path, f"{name}[{i}]", error=error) for i, v in enumerate(value))
        if self.kind == "colour_list":
            if not isinstance(value, list) or not value:
                raise error(path, name, f"expected a non-empty list of colours, got {shown(value)}")
            return tuple(parse_colour(v, path, f"{name}[{i}]", error) for i, v in enumerate(value))
        if self.kind == "table":
            if not isinstance(value, dict):
                raise error(path, name, f"expected a table, got {shown(value)}")
            check_table_bounds(value, path, name, error)
            return value
        raise AssertionError(f"unknown parameter kind {self.kind}")


#: A table parameter (a Mitsuba BSDF dict) nests at most this many tables below its own: the
#: deepest real BSDF (a blend of two-sided plastics with a bitmap texture) needs 5, and loading
#: a deeper one costs time and memory that grow about 1.5x per level (60 nested ``twosided``
#: plugins reached 3.9 GB).
MAX_TABLE_DEPTH = 8
#: ... and holds at most this many keys and list items in all.
MAX_TABLE_ENTRIES = 256


def check_table_bounds(table: dict, path, name: str, error: type[FieldError] = MaterialError) -> None:
    """Refuse a table nested deeper than :data:`MAX_TABLE_DEPTH` or larger than :data:`MAX_TABLE_ENTRIES`,
    naming the first field past the bound; iterative, so no input can exhaust the stack.

    >>> check_table_bounds({"type": "twosided", "bsdf": {"type": "diffuse"}}, "m.toml", "bsdf")
    """
    entries = 0
    pending: list[tuple[dict | list, str, int]] = [(table, name, 0)]
    while pending:
        node, where, depth = pending.pop()
        items = node.items() if isinstance(node, dict) else ((f"[{i}]", v) for i, v in enumerate(node))
        for key, value in items:
            entries += 1
            field = f"{where}{key}" if isinstance(node, list) else f"{where}.{key}"
            if entries > MAX_TABLE_ENTRIES:
                raise error(path, field, f"expected a table of at most {MAX_TABLE_ENTRIES} keys and list items in all")
            if isinstance(value, (dict, list)):
                if isinstance(value, dict) and depth + 1 > MAX_TABLE_DEPTH:
                    raise error(path, field, f"expected tables nested at most {MAX_TABLE_DEPTH} deep under '{name}'")
                pending.append((value, field, depth + (1 if isinstance(value, dict) else 0)))


def check_keys(raw: dict, allowed, path, prefix: str = "", error: type[FieldError] = MaterialError) -> None:
    """Refuse a key of the table ``raw`` not in ``allowed`` (usually a typo), suggesting the closest."""
    for key in raw:
        if key not in allowed:
            names = ", ".join(sorted(allowed)) or "none"
            where = f"{prefix}.{key}" if prefix else key
            raise error(path, where, f"unknown key{did_you_mean(key, allowed)}; expected one of: {names}")


def validate_params(schema: tuple[Param, ...], raw: dict, path) -> dict:
    """Fill defaults and validate every key; unknown keys are errors (they are usually typos)."""
    known = {p.name: p for p in schema}
    check_keys(raw, known, path)
    out = {}
    for p in schema:
        if p.name in raw:
            out[p.name] = p.coerce(raw[p.name], path)
        elif p.required:
            raise MaterialError(path, p.name, f"missing; expected {p.expectation()}")
        else:
            out[p.name] = p.default
    return out
