"""Shared fixtures. Backend-gated fixtures skip cleanly where a backend is missing."""

from __future__ import annotations

import os
import sys
import textwrap
from pathlib import Path

import pytest

# Test helpers (the independent DDS reader) import as top-level modules.
sys.path.insert(0, str(Path(__file__).parent))

os.environ.setdefault("XDG_RUNTIME_DIR", "/tmp/atlasgen-xdg-%d" % os.getuid())
os.makedirs(os.environ["XDG_RUNTIME_DIR"], mode=0o700, exist_ok=True)


@pytest.fixture
def write_material(tmp_path):
    """Write a material TOML into ``tmp_path/materials`` and return its path."""
    folder = tmp_path / "materials"
    folder.mkdir(exist_ok=True)

    def write(name: str, text: str) -> Path:
        path = folder / f"{name}.toml"
        path.write_text(textwrap.dedent(text))
        return path

    return write
