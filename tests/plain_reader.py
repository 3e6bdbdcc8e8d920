"""What a reader that knows nothing of atlasgen sees of an output set (issue 24's plain reader)."""

from __future__ import annotations

from pathlib import Path


def read_plainly(folder: Path, names) -> dict:
    """The bytes at each documented path, following its link as any program would; None where it cannot open one."""
    seen = {}
    for name in names:
        try:
            seen[name] = (folder / name).read_bytes()
        except FileNotFoundError:
            seen[name] = None
    return seen
