"""Which field of a JSON document a formatter was reading when it failed: the field a refusal of a hand-edited
report names.

A report's page is formatted from nested dicts and lists whose types a hand edit can change anywhere (a figure made
a string, a list made a number). Checking every field ahead would repeat the formatter as a schema; instead the
document is wrapped so that each read records its path (``[0].by_terms[2].relative_rms``), and where formatting
raises, the last field read is the one it stopped on.

>>> reads = FieldReads()
>>> doc = reads.track({"terms": [{"error": "big"}]}, "[0]")
>>> try:
...     sum(t["error"] for t in doc["terms"])
... except TypeError:
...     reads.last
('[0].terms[0].error', 'big')
>>> try:
...     doc["terms"][0]["scale"]
... except KeyError:
...     reads.last
('[0].terms[0].scale', nothing (the key is missing))
"""

from __future__ import annotations

import dataclasses
import re

from atlasgen.errors import describe_failure, shorten

__all__ = ["FieldReads", "ABSENT", "expected_written"]


#: The value :attr:`FieldReads.last` holds for a key that was asked for and is not there.
ABSENT = type("Missing", (), {"__repr__": lambda self: "nothing (the key is missing)"})()


def expected_written(value, exc: Exception, command: str, where: str = "") -> str:
    """A refusal's text for the field a formatter stopped on (:meth:`FieldReads.culprit`): the value ``command``
    writes there was expected, what the field holds instead (or that it is missing), and the failure, in ``where``."""
    got = "missing" if value is ABSENT else f"got {shorten(repr(value))}"
    tail = f"; {where}" if where else ""
    return f"expected the value {command} writes there, {got} ({describe_failure(exc)}{tail})"


class FieldReads:
    """The fields read through the values :meth:`track` wrapped: :attr:`last` the last ``(path, value)``, or None
    before any (the value is :data:`ABSENT` where the key read is not there), and :meth:`culprit` the one a failure
    most likely stopped on."""

    #: How many of the most recent reads :meth:`culprit` looks back over.
    LOOK_BACK = 512

    def __init__(self) -> None:
        self.last: tuple[str, object] | None = None
        self._history: list[tuple[str, object]] = []
        self._by_field: dict[str, list[tuple[str, str]]] = {}  # the path, list indices as [*] -> (path, kind) of each
        self._by_parent: dict[str, list[tuple[str, str]]] = {}  # a container's path -> (path, kind) of its members

    def note(self, path: str, value) -> None:
        self.last = (path, value)
        self._history.append((path, value))
        if len(self._history) > 2 * self.LOOK_BACK:
            del self._history[: self.LOOK_BACK]

    def missing(self, path: str, key) -> None:
        """A lookup of ``key`` that found nothing (or could not hash it): where the key is the value just read, it came
        from the document, and the field that gave it stays the one to name ("reference": "x" looked up in
        references); else the key at ``path`` is missing."""
        if self.last is not None and type(self.last[1]) is type(key) and self.last[1] == key:
            return
        self.note(path, ABSENT)

    def culprit(self) -> tuple[str, object] | None:
        """The field a failure most likely stopped on: a missing key where the last read found none; else, going back
        over the recent reads, the first value of another kind than the same field of the document's other list
        entries (``by_resolution[0].cost`` a string where every other row's is a number), or than its siblings where
        they are all numbers (a formatter reads a row's figures, then formats them: the last read may be a good
        one); else the last read."""
        if self.last is None or self.last[1] is ABSENT:
            return self.last
        for path, value in reversed(self._history[-self.LOOK_BACK :]):
            if value is not ABSENT and self._odd(path, value):
                return path, value
        return self.last

    def _odd(self, path: str, value) -> bool:
        kind = _kind(value)
        if kind == "null":
            return False
        peers = {k for p, k in self._by_field.get(_INDEX.sub("[*]", path), []) if p != path and k != "null"}
        if peers:
            return kind not in peers
        siblings = [k for p, k in self._by_parent.get(_parent(path), []) if p != path]
        return kind != "number" and len(siblings) >= 2 and set(siblings) == {"number"}

    def track(self, value, path: str = ""):
        """``value`` with its dicts and lists (and a dataclass's fields) recording each read of theirs here."""
        self._by_field.setdefault(_INDEX.sub("[*]", path), []).append((path, _kind(value)))
        self._by_parent.setdefault(_parent(path), []).append((path, _kind(value)))
        if isinstance(value, dict):
            return _Dict({k: self.track(v, _key_path(path, k)) for k, v in value.items()}, path, self)
        if isinstance(value, list):
            return _List([self.track(v, f"{path}[{i}]") for i, v in enumerate(value)], path, self)
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            fields = {f.name: self.track(getattr(value, f.name), _key_path(path, f.name)) for f in dataclasses.fields(value)}
            return _dataclass_tracked(type(value))(self, path, **fields)
        return value


#: A list index in a field's path.
_INDEX = re.compile(r"\[\d+\]")


def _parent(path: str) -> str:
    """The path of the container that holds the field at ``path``."""
    cut = max(path.rfind("."), path.rfind("["))
    return path[: max(cut, 0)]


def _kind(value) -> str:
    """What a JSON value is, as far as a formatter cares: a number (not a bool), text, a bool, null, a list or an object."""
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int | float):
        return "number"
    if value is None:
        return "null"
    if isinstance(value, str):
        return "text"
    return "list" if isinstance(value, list) else "object"


class _Untracked:
    """Where a copy made by its type (``dataclasses.asdict`` builds ``type(d)(items)``) notes its reads: nowhere."""

    @staticmethod
    def note(path: str, value) -> None:
        pass

    @staticmethod
    def missing(path: str, key) -> None:
        pass


def _key_path(path: str, key) -> str:
    return f"{path}.{key}" if path else str(key)


class _Dict(dict):
    def __init__(self, items=(), path="", reads=_Untracked):
        super().__init__(items)
        self._path, self._reads = path, reads

    def __getitem__(self, key):
        try:
            value = super().__getitem__(key)
        except (KeyError, TypeError):  # no such key, or one that cannot be one (a list)
            self._reads.missing(_key_path(self._path, key), key)
            raise
        self._reads.note(_key_path(self._path, key), value)
        return value

    def get(self, key, default=None):
        if key in self:
            return self[key]
        return default

    def items(self):
        return [(k, self[k]) for k in self]

    def values(self):
        return [self[k] for k in self]


class _List(list):
    def __init__(self, items=(), path="", reads=_Untracked):
        super().__init__(items)
        self._path, self._reads = path, reads

    def __getitem__(self, index):
        value = super().__getitem__(index)
        if isinstance(index, int):
            self._reads.note(f"{self._path}[{index % len(self) if self else index}]", value)
        return value

    def __iter__(self):
        for i, value in enumerate(list.__iter__(self)):
            self._reads.note(f"{self._path}[{i}]", value)
            yield value


# A formatter's own error messages name the types it was given ("'list' object has no attribute 'items'").
_Dict.__name__ = _Dict.__qualname__ = "dict"
_List.__name__ = _List.__qualname__ = "list"

_TRACKED_CLASSES: dict[type, type] = {}


def _dataclass_tracked(cls: type) -> type:
    """A subclass of the dataclass ``cls`` whose field reads are noted (its formatters take it for ``cls``)."""
    if cls not in _TRACKED_CLASSES:
        names = frozenset(f.name for f in dataclasses.fields(cls))

        def __init__(self, reads, path, **fields):
            object.__setattr__(self, "_reads", (reads, path))
            cls.__init__(self, **fields)

        def __getattribute__(self, name):
            value = object.__getattribute__(self, name)
            if name in names:
                reads, path = object.__getattribute__(self, "_reads")
                reads.note(_key_path(path, name), value)
            return value

        _TRACKED_CLASSES[cls] = type(cls.__name__, (cls,), {"__init__": __init__, "__getattribute__": __getattribute__})
    return _TRACKED_CLASSES[cls]
