"""Fuzzed combinations of output paths through ``atlasgen bake``: a documented exit
status, at most one line on stderr, no traceback; nothing at all changed on failure, and
no input changed on success."""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tests.fuzz.conftest import invoke, write_library
from tests.fuzz.strategies import FUZZ, check_finite_bake, check_result, tree_hash

pytestmark = pytest.mark.slow

#: Paths an output option may name: the usual ones, inputs, each other's, folders, a path
#: under a file, wrong and odd extensions.
PATHS = ("build/atlas.dds", "build/atlas.json", "build/atlas.wgsl", "build/atlas.timings.json", "build/p.png",
         "build/atlas.d", "build/x.ktx2", "build/X.DDS", "materials/clay.toml", "materials", "build", "folder.dds",
         "folder.png", "blocker/atlas.dds", "blocker", "x.json", "x", "cache/clay.npz", "scene.toml", "mesh.obj",
         "atlas.dds", "p.png")  # fmt: skip
CACHES = ("cache", "build", "materials", "blocker", "folder.dds")
SCENE = '[camera]\nposition = [0, 1, 5]\ntarget = [0, 0, 0]\n[[objects]]\nshape = "sphere"\nmaterial = "gloss"\n'


@st.composite
def bake_arguments(draw) -> list[str]:
    args = ["bake", draw(st.sampled_from(["materials", "materials/clay.toml", "empty", "materials/gloss.toml"]))]
    args += ["-o", draw(st.sampled_from(PATHS))]
    for option, choices in (("--preview", PATHS), ("--depfile", PATHS), ("--cache", CACHES),
                            ("--scene", ("scene.toml",)), ("--ids-from", PATHS)):  # fmt: skip
        if draw(st.integers(0, 2)) == 0:
            args += [option, draw(st.sampled_from(choices))]
    if draw(st.booleans()):
        args.append("--allow-empty")
    return args + ["-q"]


def _tree(root: Path) -> None:
    write_library(root)
    (root / "empty").mkdir()
    (root / "folder.dds").mkdir()
    (root / "folder.png").mkdir()
    (root / "blocker").write_text("a file")
    (root / "scene.toml").write_text(SCENE)
    result = invoke(["bake", root / "materials", "-o", root / "build" / "atlas.dds", "-q"])
    assert result.exit_code == 0, result.output


@FUZZ
@given(args=bake_arguments())
def test_output_paths_are_checked_before_anything_is_written(args):
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        _tree(root)
        before = tree_hash(root)
        # What the command reads: the materials (all of them, also with --scene), and the
        # scene and its mesh with --scene.
        read = ("materials/", "scene.toml", "mesh.obj") if "--scene" in args else ("materials/",)
        inputs = {p: h for p, h in before.items() if p.startswith(read) and p.endswith((".toml", ".obj"))}
        absolute = [str(root / a) if not a.startswith("-") and a != "bake" else a for a in args]
        result = invoke(absolute)
        check_result(result, allowed={0, 2, 3, 4})  # 2: an output named with another kind's extension
        after = tree_hash(root)
        if result.exit_code:
            assert after == before, args
            return
        assert {p: h for p, h in after.items() if p in inputs} == inputs, args
        out = root / args[args.index("-o") + 1]
        if out.suffix == ".dds":
            check_finite_bake(out)
