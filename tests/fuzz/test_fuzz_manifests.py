"""Damaged manifests beside a good atlas, through ``atlasgen info``, ``render`` and ``report
library``: a documented exit status, at most one line on stderr, no traceback, no output written
on a refusal."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tests.fuzz.conftest import invoke
from tests.fuzz.strategies import FUZZ, check_result, edge_numbers, tree_hash

pytestmark = pytest.mark.slow

SCENE = '[camera]\nposition = [0, 1, 5]\ntarget = [0, 0, 0]\n[image]\nwidth = 8\nheight = 6\n' \
        '[[objects]]\nshape = "sphere"\nmaterial = "clay"\n'  # fmt: skip

#: What replaces a value somewhere in the manifest: edge numbers, wrong types, nothing.
odd_values = st.one_of(edge_numbers, st.sampled_from([None, True, "", "x" * 300, [], {}, [1, 2], {"a": 1}]))


def _paths(value, prefix=()):
    """Every (path, value) in a JSON document, containers included."""
    yield prefix, value
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, child in items:
        yield from _paths(child, (*prefix, key))


@st.composite
def damaged_manifests(draw, text: str) -> str:
    """The manifest with one value replaced or one key dropped, or its text cut short."""
    data = json.loads(text)
    paths = [p for p, _ in _paths(data) if p]
    how = draw(st.sampled_from(["replace", "drop", "truncate"]))
    if how == "truncate":
        return text[: draw(st.integers(0, len(text) - 1))]
    path = draw(st.sampled_from(paths))
    parent = data
    for key in path[:-1]:
        parent = parent[key]
    if how == "drop" and isinstance(parent, dict):
        del parent[path[-1]]
    else:
        parent[path[-1]] = draw(odd_values)
    return json.dumps(data, allow_nan=True)


@FUZZ
@given(data=st.data())
def test_damaged_manifests_are_refused_in_one_line(baked_library, data):
    manifest = data.draw(damaged_manifests((baked_library / "atlas.json").read_text()))
    with tempfile.TemporaryDirectory(dir=baked_library) as tmp:
        root = Path(tmp)
        for suffix in (".dds", ".wgsl"):
            (root / f"atlas{suffix}").write_bytes((baked_library / "atlas").with_suffix(suffix).read_bytes())
        (root / "atlas.json").write_text(manifest)
        check_result(invoke(["info", root / "atlas.dds"]), allowed={0, 3})
        (root / "scene.toml").write_text(SCENE)
        (root / "out").mkdir()
        before = tree_hash(root / "out")
        result = invoke(["render", root / "scene.toml", "--atlas", root / "atlas.dds", "-o", root / "out" / "r.exr"])
        check_result(result, allowed={0, 3, 5}, max_lines=1 if result.exit_code else 0)
        result = invoke(["report", "library", "--atlas", root / "atlas.dds", "-o", root / "out" / "report", "-q"])
        check_result(result, allowed={0, 3}, max_lines=1 if result.exit_code else 0)
        if result.exit_code:
            assert tree_hash(root / "out") == before
