"""Fuzzed material files through ``atlasgen bake``: a documented exit status, at most one
line on stderr, no traceback; the atlas untouched on failure and finite on success."""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tests.fuzz.conftest import invoke
from tests.fuzz.strategies import FUZZ, check_finite_bake, check_result, material_toml, tree_hash

pytestmark = pytest.mark.slow

TYPES = ("lambert", "fresnel", "iridescent", "sss", "backlit", "toon", "separable")


@FUZZ
@given(texts=st.lists(material_toml(TYPES), min_size=1, max_size=3))
def test_fuzzed_materials_bake_or_fail_cleanly(texts):
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        library = root / "materials"
        library.mkdir()
        (library / "base.toml").write_text('type = "lambert"\n')
        out = root / "build" / "atlas.dds"
        assert invoke(["bake", library, "-o", out, "-q"]).exit_code == 0  # the atlas a failure must leave
        for i, text in enumerate(texts):
            (library / f"m{i}.toml").write_bytes(text)
        before = tree_hash(root / "build")
        result = invoke(["bake", library, "-o", out, "--cache", root / "cache", "-q"])
        check_result(result)
        if result.exit_code == 0:
            check_finite_bake(out)
        else:
            assert tree_hash(root / "build") == before
