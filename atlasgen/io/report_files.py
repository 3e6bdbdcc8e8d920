"""Finding and reading the per-material ``report.json`` files that a report merge combines,
and the checks that keep a hand-edited or damaged figure out of a merged report."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

from atlasgen.errors import FieldError, InputError, shorten
from atlasgen.io.output_paths import check_output_paths
from atlasgen.io.text import MISSING, decode_utf8, loads_json, path_kind, read_input_bytes

__all__ = [
    "rebase_path",
    "report_json_paths",
    "check_merge_output",
    "read_json_file",
    "read_report_json",
    "loads_finite_json",
    "check_number",
]


class _NonFinite:
    """Where the reader met a number JSON cannot hold: ``shown`` as the file has it, ``why`` it is refused."""

    def __init__(self, shown: str, why: str):
        self.shown, self.why = shown, why


def _non_finite_float(text: str):
    value = float(text)
    # 1e999: valid JSON, but beyond a double (Python reads it as inf).
    return value if math.isfinite(value) else _NonFinite(shorten(text), " (beyond a double's range)")


def _first_non_finite(value, field: str = ""):
    """``(field, marker)`` of the first :class:`_NonFinite` in ``value`` in the file's order (``results[0].psnr_db``), or None."""
    if isinstance(value, _NonFinite):
        return field, value
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, item in items:
        if not isinstance(key, int):  # a key's escaped control characters would break the one line
            key = key if key.isprintable() else json.dumps(key)[1:-1]
        found = _first_non_finite(item, f"{field}[{key}]" if isinstance(key, int) else f"{field}.{key}" if field else key)
        if found is not None:
            return found
    return None


def loads_finite_json(text: str, path) -> object:
    """``json.loads`` that refuses ``NaN``, ``Infinity`` and ``-Infinity`` (Python's extensions to JSON),
    and a number too large for a double (``1e999``, which Python would read as infinity), naming the field
    that holds the first of them (the reader meets them before it knows any field, so they are marked while
    reading and found after).

    Raises
    ------
    InputError
        One line naming the file: malformed JSON; or, a :class:`~atlasgen.errors.FieldError`, one of those
        numbers and the field that holds it.
    """
    path = Path(path)
    try:
        data = loads_json(text, parse_constant=lambda name: _NonFinite(name, f" (JSON has no {name})"),
                          parse_float=_non_finite_float)  # fmt: skip
    except ValueError as exc:
        raise InputError(f"{path.as_posix()}: malformed JSON ({exc})") from None
    found = _first_non_finite(data)
    if found is not None:
        field, marker = found
        raise FieldError(path.as_posix(), field or None, f"expected a finite number{marker.why}, got {marker.shown}")
    return data


def rebase_path(rel: str, start, folder) -> str:
    """``rel``, a path from ``start`` (a report's folder, or ``"."``: the working folder, where a path was typed),
    given from ``folder`` instead, POSIX; an absolute ``rel`` is given from ``folder`` too.

    >>> rebase_path("../atlas.dds", "v/materials/clay", "v"), rebase_path("atlas/a.dds", ".", "out/v")
    ('materials/atlas.dds', '../../atlas/a.dds')
    """
    return Path(os.path.relpath(Path(start) / rel, folder)).as_posix()


def check_number(path, field: str, value, allow_none: bool = True, minimum: float | None = None,
                 maximum: float | None = None):  # fmt: skip
    """``value`` if it is a finite number (or ``None``, with ``allow_none``), at least ``minimum`` and at most
    ``maximum`` where given; else a one-line :class:`~atlasgen.errors.FieldError` naming the file and the field.

    >>> check_number("t.json", "bake_s", 0.5), check_number("t.json", "bake_s", None)
    (0.5, None)
    >>> check_number("t.json", "flip", 1.5, minimum=0, maximum=1)
    Traceback (most recent call last):
    atlasgen.errors.FieldError: t.json: field 'flip': expected a number in [0, 1], got 1.5
    """
    if value is None and allow_none:
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise FieldError(Path(path).as_posix(), field, f"expected a finite number{' or null' * allow_none}, got {value!r}")
    if (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
        if maximum is None:
            bounds = f">= {minimum:g}"
        else:
            bounds = f"in [{'-inf' if minimum is None else format(minimum, 'g')}, {maximum:g}]"
        raise FieldError(Path(path).as_posix(), field, f"expected a number {bounds}, got {value!r}")
    return value


def report_json_paths(sources, kind: str, command: str) -> list[Path]:
    """The ``report.json`` of each source, a folder or the JSON file itself.

    Raises
    ------
    InputError
        No sources at all; the message names the ``command`` that writes them.
    """
    for s in sources:
        kind_of = path_kind(s)
        if Path(s).suffix != ".json" and kind_of not in ("a directory", MISSING):
            # Read as s/report.json, it failed with "cannot read (Not a directory)", saying nothing of what was wanted.
            raise InputError(f"{Path(s).as_posix()}: a --merge source is {kind_of or 'a file'}; expected a report folder "
                             f"{command} -o wrote, or its report.json")  # fmt: skip
    paths = [Path(s) if Path(s).suffix == ".json" else Path(s) / "report.json" for s in sources]
    if not paths:
        raise InputError(f"no {kind} reports to merge; expected folders written by {command} -o")
    return paths


def check_merge_output(paths, output) -> None:
    """Refuse a merge whose output folder is one of its sources (``--merge A B -o B``).

    The sources may live inside the output folder, but the merged ``report.json`` must not replace a
    source's own: the source would then hold the merge, and a later merge of it would count every
    material of the others twice.

    Raises
    ------
    OutputError
        One line naming the output and the source (exit 4), before anything is read or written.
    """
    check_output_paths([(Path(output) / "report.json", "the merged report")], [(p, "a --merge source") for p in paths])


#: Bytes a report's JSON may have: a merged library's is hundreds of kB; a 48 MB one took 1.27 GB to read.
REPORT_LIMIT = (64 << 20, "a report written by atlasgen")


def read_json_file(path, missing: str = "no such file"):
    """The parsed JSON of ``path`` (:func:`loads_finite_json`), a leading byte-order mark dropped.

    Raises
    ------
    InputError
        One line naming the file: missing (``path: {missing}``), a folder, a pipe or device,
        unreadable, over :data:`REPORT_LIMIT`, not UTF-8, malformed.
    """
    path = Path(path)
    data = read_input_bytes(path, missing, limit=REPORT_LIMIT)
    try:
        text = decode_utf8(data)
    except UnicodeDecodeError as exc:
        raise InputError(f"{path.as_posix()}: malformed JSON ({exc})") from None
    return loads_finite_json(text, path)


def read_report_json(path: Path, kind: str, command: str):
    """The parsed JSON of one report (no NaN or infinities), or an :class:`InputError` naming the file and the fix."""
    path = Path(path)
    return read_json_file(path, f"no such {kind} report; run {command} -o {path.parent.as_posix()} first")
