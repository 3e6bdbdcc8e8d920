"""Finding and reading the per-material ``report.json`` files that a report merge combines."""

from __future__ import annotations

import json
from pathlib import Path

from atlasgen.errors import InputError
from atlasgen.io.atomic import recover_commits

__all__ = ["report_json_paths", "read_report_json"]


def report_json_paths(sources, kind: str, command: str) -> list[Path]:
    """The ``report.json`` of each source, a folder or the JSON file itself.

    Raises
    ------
    InputError
        No sources at all; the message names the ``command`` that writes them.
    """
    paths = [Path(s) if Path(s).suffix == ".json" else Path(s) / "report.json" for s in sources]
    if not paths:
        raise InputError(f"no {kind} reports to merge; expected folders written by {command} -o")
    return paths


def read_report_json(path: Path, kind: str, command: str):
    """The parsed JSON of one report, or an :class:`InputError` naming the file and the fix."""
    path = Path(path)
    recover_commits(path.parent)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path.as_posix()}: no such {kind} report; run {command} -o {path.parent.as_posix()} first") from None
    except OSError as exc:
        raise InputError(f"{path.as_posix()}: cannot read ({exc.strerror})") from None
    except ValueError as exc:
        raise InputError(f"{path.as_posix()}: malformed JSON ({exc})") from None
