"""Fixtures of the renderer tests: one fixture atlas and one renderer per session.

Creating pipelines costs seconds on lavapipe, so every render test shares them. Each
test also checks, on the way out, that the device reported no validation error.
"""

from __future__ import annotations

import textwrap
import tomllib

import pytest


@pytest.fixture(scope="session")
def fixture_atlas():
    from tests.render.atlas_fixture import build_fixture_atlas

    return build_fixture_atlas()


@pytest.fixture(scope="session")
def renderer(gpu_context, fixture_atlas):
    from atlasgen.render.renderer import Renderer

    return Renderer(fixture_atlas, gpu_context)


@pytest.fixture
def scene_from():
    """Parse scene TOML text (dedented) into a Scene."""
    from atlasgen.materials.scene import parse_scene

    def parse(text: str, path="test.toml", base=None):
        return parse_scene(tomllib.loads(textwrap.dedent(text)), path, base)

    return parse
