"""The shape a JSON document read back must have, field by field, and the one line naming the first field that has not.

A report merge reads back what another atlasgen run wrote, and a hand edit can change any field. Checking fields one
by one where each is read named the wrong field when a type changed beneath it (a row's terms made null was blamed on
another row) and let others through (a relative RMS of -1 was printed as -100%). A shape states every field once:

>>> row = Fields({"terms": Count(), "relative_rms": Figure()})
>>> check_shape("r.json", "[0].rows", [{"terms": 2, "relative_rms": 0.1}], Items(row))
>>> check_shape("r.json", "[0].rows", [{"terms": 2, "relative_rms": -1}], Items(row))
Traceback (most recent call last):
atlasgen.errors.FieldError: r.json: field '[0].rows[0].relative_rms': expected a number >= 0, got -1
>>> check_shape("r.json", "[0].rows", [{"terms": True, "relative_rms": 0.1}], Items(row))
Traceback (most recent call last):
atlasgen.errors.FieldError: r.json: field '[0].rows[0].terms': expected a whole number >= 1, got True
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from atlasgen.errors import FieldError, shorten
from atlasgen.io.report_files import check_number

__all__ = ["Shape", "Figure", "Number", "Count", "Text", "Flag", "Items", "Fields", "Nullable", "check_shape"]


class Shape(Protocol):
    """What a field must be: ``check`` raises a one-line FieldError naming ``where`` in ``path`` where it is not."""

    def check(self, path, where: str, value) -> None: ...


def _refuse(path, where: str, expected: str, value) -> None:
    raise FieldError(Path(path).as_posix(), where, f"expected {expected}, got {shorten(repr(value))}")


@dataclass(frozen=True)
class Figure:
    """A measured figure: a finite number, at least ``minimum`` (0: errors, seconds, costs)."""

    minimum: float = 0.0

    def check(self, path, where: str, value) -> None:
        check_number(path, where, value, allow_none=False, minimum=self.minimum)


@dataclass(frozen=True)
class Number:
    """Any finite number (a position in pixels)."""

    def check(self, path, where: str, value) -> None:
        check_number(path, where, value, allow_none=False)


@dataclass(frozen=True)
class Count:
    """A whole number >= 1 (terms, a grid's size, pixels)."""

    def check(self, path, where: str, value) -> None:
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            _refuse(path, where, "a whole number >= 1", value)


@dataclass(frozen=True)
class Text:
    """A string, one of ``choices`` where given."""

    choices: tuple = ()

    def check(self, path, where: str, value) -> None:
        if not isinstance(value, str):
            _refuse(path, where, "a string", value)
        if self.choices and value not in self.choices:
            _refuse(path, where, f"one of {', '.join(self.choices)}", value)


@dataclass(frozen=True)
class Flag:
    """true or false."""

    def check(self, path, where: str, value) -> None:
        if not isinstance(value, bool):
            _refuse(path, where, "true or false", value)


@dataclass(frozen=True)
class Nullable:
    """null, or ``shape``."""

    shape: Shape

    def check(self, path, where: str, value) -> None:
        if value is not None:
            self.shape.check(path, where, value)


@dataclass(frozen=True)
class Items:
    """A list of ``item``; with ``unique``, no two items alike in those keys (each a row of a table keyed by them)."""

    item: Shape
    unique: tuple = ()

    def check(self, path, where: str, value) -> None:
        if not isinstance(value, list):
            _refuse(path, where, "a list", value)
        seen = set()
        for i, element in enumerate(value):
            self.item.check(path, f"{where}[{i}]", element)
            if self.unique:
                key = tuple(element[k] for k in self.unique)
                if key in seen:
                    _refuse(path, f"{where}[{i}]", f"one row per ({', '.join(self.unique)}), not a second", key)
                seen.add(key)


@dataclass(frozen=True)
class Fields:
    """An object with the ``required`` fields, any of the ``optional`` ones, and other keys (``keys`` where given) of
    shape ``others``; without ``others``, no other key."""

    required: dict[str, Any] = field(default_factory=dict)
    optional: dict[str, Any] = field(default_factory=dict)
    others: Shape | None = None
    keys: tuple = ()

    def check(self, path, where: str, value) -> None:
        if not isinstance(value, dict):
            _refuse(path, where, "an object", value)
        for key in self.required:
            if key not in value:
                raise FieldError(Path(path).as_posix(), f"{where}.{key}", "expected a value, got none (no such key)")
        for key, item in value.items():
            shape = self.required.get(key) or self.optional.get(key)
            if shape is None and (self.keys and key not in self.keys or self.others is None):
                known = [*self.required, *self.optional, *self.keys]
                _refuse(path, f"{where}.{key}", f"no such field (expected {', '.join(known) or 'none'})", item)
            (shape or self.others).check(path, f"{where}.{key}", item)  # type: ignore[union-attr]


def check_shape(path, where: str, value, shape: Shape) -> None:
    """Raise a one-line :class:`~atlasgen.errors.FieldError` naming ``path`` and the first field of ``value`` (found at
    ``where``) that is not of ``shape``."""
    shape.check(path, where, value)
