"""Fuzzed scene files through ``atlasgen bake --scene`` and ``atlasgen render``: a
documented exit status, at most one line on stderr, no traceback; outputs untouched on
failure; a render's pixels all finite on success."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given

from atlasgen.materials.scene import read_scene
from tests.fuzz.conftest import invoke, write_library
from tests.fuzz.strategies import FUZZ, check_finite_bake, check_result, scene_toml, tree_hash

pytestmark = pytest.mark.slow

GOOD_SCENE = '[camera]\nposition = [0, 1, 5]\ntarget = [0, 0, 0]\n[[objects]]\nshape = "box"\nmaterial = "clay"\n'


@FUZZ
@given(text=scene_toml())
def test_fuzzed_scenes_select_materials_or_fail_cleanly(text):
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        write_library(root)
        (root / "good.toml").write_text(GOOD_SCENE)
        out = root / "build" / "scene.dds"
        assert invoke(["bake", root / "materials", "--scene", root / "good.toml", "-o", out, "-q"]).exit_code == 0
        (root / "scene.toml").write_bytes(text)
        before = tree_hash(root / "build")
        result = invoke(["bake", root / "materials", "--scene", root / "scene.toml", "-o", out, "--depfile",
                         root / "build" / "scene.d", "--allow-empty", "-q"])  # fmt: skip
        check_result(result)
        if result.exit_code == 0:
            check_finite_bake(out)
        else:
            assert tree_hash(root / "build") == before


@pytest.mark.gpu
@FUZZ
@given(text=scene_toml())
def test_fuzzed_scenes_render_finite_pixels_or_fail_cleanly(baked_library, gpu_device, text):
    import OpenImageIO as oiio

    with tempfile.TemporaryDirectory(dir=baked_library) as tmp:
        root = Path(tmp)
        (root / "mesh.obj").write_text((baked_library / "mesh.obj").read_text())
        (root / "scene.toml").write_bytes(text)
        build = root / "build"
        build.mkdir()
        for name in ("r.exr", "r.png"):
            (build / name).write_bytes(b"an earlier render")
        before = tree_hash(build)
        result = invoke(["render", root / "scene.toml", "--atlas", baked_library / "atlas.dds", "-o", build / "r.exr"])
        check_result(result, max_lines=1)
        if result.exit_code == 0:
            # A rendered scene's only diagnostics are its own warnings (an unlit scene's, Scene.warnings).
            warnings = [f"atlasgen: warning: {w}" for w in read_scene(root / "scene.toml").warnings()]
            assert result.stderr.splitlines() == warnings, result.stderr
            pixels = oiio.ImageBuf(str(build / "r.exr")).get_pixels(oiio.FLOAT)
            assert np.isfinite(pixels).all()
        else:
            assert tree_hash(build) == before
