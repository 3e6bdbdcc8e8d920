"""Typed, validated material parameters: the schema each model declares for its TOML keys."""

from __future__ import annotations

import math
import string
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from atlasgen.errors import MaterialError, did_you_mean
from atlasgen.optics.quantize import dequantize_rgba

__all__ = ["Param", "validate_params", "parse_colour"]


def parse_colour(value, path, name):
    """A colour as ``[r, g, b]`` linear floats in [0, 1], or an sRGB hex string ``"#rrggbb"``.

    Hex colours are what artists copy from a picker, so they are decoded from sRGB
    (IEC 61966-2-1) to the linear values the models work in.
    """
    if isinstance(value, str):
        text = value.strip()
        if len(text) == 7 and text[0] == "#" and all(c in string.hexdigits for c in text[1:]):
            codes = np.frombuffer(bytes.fromhex(text[1:]), dtype=np.uint8)
            return tuple(float(c) for c in dequantize_rgba(codes, srgb=True))
        raise MaterialError(path, name, f"expected a colour [r, g, b] or '#rrggbb', got {value!r}")
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise MaterialError(path, name, f"expected a colour [r, g, b] of 3 numbers in [0, 1], got {value!r}")
    out = []
    for c in value:
        if isinstance(c, bool) or not isinstance(c, (int, float)) or not math.isfinite(c) or not 0.0 <= c <= 1.0:
            raise MaterialError(path, name, f"expected a colour [r, g, b] of 3 finite numbers in [0, 1], got {value!r}")
        out.append(float(c))
    return tuple(out)


@dataclass(frozen=True)
class Param:
    """One model parameter.

    ``kind`` is one of ``float``, ``int``, ``bool``, ``colour``, ``choice``,
    ``float_list``, ``colour_list``, ``table`` (a free-form TOML table the model checks itself).
    Bounds are inclusive unless ``lo_open`` / ``hi_open``.
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
        noun = {"int": "an integer", "float_list": "a list of finite numbers", "colour_list": "a list of colours"}.get(
            self.kind, "a finite number"
        )
        return noun + (" " + " and ".join(parts) if parts else "")

    def _check_number(self, value, path, name, integer=False):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise MaterialError(path, name, f"expected {self.expectation()}, got {value!r}")
        if integer and not isinstance(value, int):
            raise MaterialError(path, name, f"expected {self.expectation()}, got {value!r}")
        if not math.isfinite(value):
            raise MaterialError(path, name, f"expected {self.expectation()}, got {value}")
        lo_bad = self.lo is not None and (value <= self.lo if self.lo_open else value < self.lo)
        hi_bad = self.hi is not None and (value >= self.hi if self.hi_open else value > self.hi)
        if lo_bad or hi_bad:
            raise MaterialError(path, name, f"expected {self.expectation()}, got {value!r}")
        return int(value) if integer else float(value)

    def coerce(self, value, path):
        """Check ``value`` against this schema; return it normalised (floats, tuples)."""
        name = self.name
        if self.kind == "float":
            return self._check_number(value, path, name)
        if self.kind == "int":
            return self._check_number(value, path, name, integer=True)
        if self.kind == "bool":
            if not isinstance(value, bool):
                raise MaterialError(path, name, f"expected true or false, got {value!r}")
            return value
        if self.kind == "colour":
            return parse_colour(value, path, name)
        if self.kind == "choice":
            if value not in self.choices:
                raise MaterialError(path, name, f"expected {self.expectation()}, got {value!r}")
            return value
        if self.kind == "float_list":
            if not isinstance(value, list):
                raise MaterialError(path, name, f"expected {self.expectation()}, got {value!r}")
            return tuple(self._check_number(v, path, f"{name}[{i}]") for i, v in enumerate(value))
        if self.kind == "colour_list":
            if not isinstance(value, list) or not value:
                raise MaterialError(path, name, f"expected a non-empty list of colours, got {value!r}")
            return tuple(parse_colour(v, path, f"{name}[{i}]") for i, v in enumerate(value))
        if self.kind == "table":
            if not isinstance(value, dict):
                raise MaterialError(path, name, f"expected a table, got {value!r}")
            return value
        raise AssertionError(f"unknown parameter kind {self.kind}")


def validate_params(schema: tuple[Param, ...], raw: dict, path) -> dict:
    """Fill defaults and validate every key; unknown keys are errors (they are usually typos)."""
    known = {p.name: p for p in schema}
    for key in raw:
        if key not in known:
            names = ", ".join(sorted(known)) or "none"
            raise MaterialError(path, key, f"unknown key{did_you_mean(key, known)}; expected one of: {names}")
    out = {}
    for p in schema:
        if p.name in raw:
            out[p.name] = p.coerce(raw[p.name], path)
        elif p.required:
            raise MaterialError(path, p.name, f"missing; expected {p.expectation()}")
        else:
            out[p.name] = p.default
    return out
