"""Which command's report a folder's ``report.json`` is, so that one command never writes over another's.

``atlasgen validate`` (and its merge) and ``atlasgen report separable`` (and its merge) both name their set
by ``report.json``: their outputs share a store, and the commit's check for another set's links
(:func:`atlasgen.io.atomic.refuse_another_sets`) cannot tell them apart. The file's own shape does: a
validation report is an object with ``results``, a separable report a list of studies.
"""

from __future__ import annotations

import json
from pathlib import Path

from atlasgen.errors import OutputError
from atlasgen.io.text import path_kind

__all__ = ["report_kind", "folder_report_kind", "refuse_another_report"]

#: A report.json larger than this is no report of ours to recognise (the commit refuses it, or replaces it).
_MAX_BYTES = 256 << 20


def report_kind(data) -> str | None:
    """``"validation"``, ``"separable"`` or None for parsed ``report.json`` contents. A separable report studies at
    least one material (``atlasgen report separable`` refuses a library without one): ``[]`` is none of ours, and was
    linked from the library page as the factorisation report.

    >>> report_kind({"results": [], "settings": {}}), report_kind([{"name": "gold"}]), report_kind({"a": 1})
    ('validation', 'separable', None)
    >>> report_kind([]) is None
    True
    """
    if isinstance(data, dict) and "results" in data:
        return "validation"
    if isinstance(data, list) and data and all(isinstance(study, dict) and "name" in study for study in data):
        return "separable"
    return None


def folder_report_kind(folder) -> str | None:
    """:func:`report_kind` of ``folder/report.json``; None where there is none, or it is no report of ours."""
    path = Path(folder) / "report.json"
    if path_kind(path) is not None:
        return None
    try:
        if path.stat().st_size > _MAX_BYTES:
            return None
        return report_kind(json.loads(path.read_text(encoding="utf-8")))
    except (OSError, ValueError, RecursionError):  # RecursionError: arrays nested too deeply for the decoder
        return None


def refuse_another_report(folder, kind: str) -> None:
    """Refuse to write a ``kind`` report into ``folder`` where its ``report.json`` is the other command's: the
    set would be replaced whole (exit 0), and what read the folder as that command's report then failed."""
    path = Path(folder) / "report.json"
    found = folder_report_kind(folder)
    if found is not None and found != kind:
        raise OutputError(f"{path.as_posix()}: already written by another command's outputs (a {found} report); "
                          f"expected a folder of its own for each command's outputs; nothing was replaced")  # fmt: skip
