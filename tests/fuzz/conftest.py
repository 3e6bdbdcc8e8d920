"""Fixtures of the fuzz suite: a small library and its atlas, made once per session."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

LIBRARY = {"clay": 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n', "gloss": 'type = "fresnel"\n'}
#: A triangle mesh the generated scenes may name.
MESH = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n"


def write_library(root) -> None:
    """``root/materials`` with :data:`LIBRARY`, and ``root/mesh.obj``."""
    folder = root / "materials"
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in LIBRARY.items():
        (folder / f"{name}.toml").write_text(text)
    (root / "mesh.obj").write_text(MESH)


def invoke(args):
    from atlasgen.cli.main import app

    return CliRunner().invoke(app, [str(a) for a in args])


@pytest.fixture(scope="session")
def baked_library(tmp_path_factory):
    """A folder with the library, ``mesh.obj`` and the library's atlas ``atlas.dds`` (+ json, wgsl)."""
    root = tmp_path_factory.mktemp("fuzz-library")
    write_library(root)
    result = invoke(["bake", root / "materials", "-o", root / "atlas.dds", "-q"])
    assert result.exit_code == 0, result.output
    return root
