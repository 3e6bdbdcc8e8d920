"""Damaged DDS files through ``atlasgen info`` and ``atlasgen render``: a documented exit
status, at most one line on stderr, no traceback, nothing allocated by a header's sizes."""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest
from hypothesis import given

from tests.fuzz.conftest import invoke
from tests.fuzz.strategies import FUZZ, check_result, damage_dds, dds_damage, tree_hash

pytestmark = pytest.mark.slow

SCENE = '[camera]\nposition = [0, 1, 5]\ntarget = [0, 0, 0]\n[image]\nwidth = 8\nheight = 6\n' \
        '[[lights]]\ntype = "directional"\ndirection = [0, 0, -1]\nintensity = 1\n' \
        '[[objects]]\nshape = "sphere"\nmaterial = "clay"\n'  # fmt: skip


@FUZZ
@given(damage=dds_damage)
def test_damaged_atlases_are_refused_in_one_line(baked_library, damage):
    damaged = damage_dds((baked_library / "atlas.dds").read_bytes(), damage)
    with tempfile.TemporaryDirectory(dir=baked_library) as tmp:
        root = Path(tmp)
        for suffix in (".json", ".wgsl"):
            (root / f"atlas{suffix}").write_bytes((baked_library / "atlas").with_suffix(suffix).read_bytes())
        (root / "atlas.dds").write_bytes(damaged)
        result = invoke(["info", root / "atlas.dds"])
        check_result(result, allowed={0, 3})
        (root / "scene.toml").write_text(SCENE)
        (root / "out").mkdir()
        before = tree_hash(root / "out")
        result = invoke(["render", root / "scene.toml", "--atlas", root / "atlas.dds", "-o", root / "out" / "r.exr"])
        check_result(result, allowed={0, 3, 5}, max_lines=1 if result.exit_code else 0)
        if result.exit_code:
            assert tree_hash(root / "out") == before
