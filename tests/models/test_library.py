"""The shipped library and docs/materials.md: every LUT model has a valid example and documented parameters."""

import tomllib
from pathlib import Path

import numpy as np
import pytest

from atlasgen.contract import texel_grid
from atlasgen.materials.material import find_material_files, read_material
from atlasgen.models import get_model

ROOT = Path(__file__).resolve().parents[2]
LUT_MODELS = ["lambert", "fresnel", "iridescent", "sss", "backlit", "toon"]
# Read at collection, so only the LUT files: reading a separable material with a Mitsuba
# source loads Mitsuba, which the LUT tests must not need.
LIBRARY = [
    read_material(f)
    for f in find_material_files([ROOT / "materials"])
    if f.suffix == ".toml" and tomllib.loads(f.read_text()).get("type") in LUT_MODELS
]


def _format(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_format(v) for v in value) + "]"
    return str(value)


def test_every_lut_model_has_a_shipped_example():
    assert {m.type for m in LIBRARY} == set(LUT_MODELS)


@pytest.mark.parametrize("material", LIBRARY, ids=lambda m: m.name)
def test_shipped_materials_bake_to_finite_non_negative_slices(material, valid_slice):
    values = valid_slice(material.model, material.params)
    assert values[..., :3].max() > 0.0  # not an empty slice


@pytest.mark.parametrize("material", LIBRARY, ids=lambda m: m.name)
def test_bake_and_evaluate_agree_at_any_shape(material):
    # The renderer and validator call evaluate() directly, on full grids, on axes that
    # broadcast, or point by point; all must give the baked texels.
    model, params = material.model, material.params
    nl, nv = texel_grid()
    baked = model.bake(params).values[0]
    np.testing.assert_allclose(model.evaluate(params, nl, nv), baked, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(model.evaluate(params, nl[:1], nv[:, :1]), baked, rtol=1e-12, atol=1e-15)
    rng = np.random.default_rng(3)
    points = rng.uniform(-1.0, 1.0, 12), rng.uniform(0.0, 1.0, 12)
    together = model.evaluate(params, *points)
    assert together.shape == (12, 4)
    one_by_one = [model.evaluate(params, l, v) for l, v in zip(*points)]
    np.testing.assert_allclose(together, one_by_one, rtol=1e-12, atol=1e-15)


def test_the_talks_iridescent_with_back_lighting_is_shipped():
    material = next(m for m in LIBRARY if m.name == "iridescent-backlit")
    assert material.type == "iridescent" and material.params["backlight"] > 0
    lit_from_behind = material.model.evaluate(material.params, -1.0, 1.0)
    assert lit_from_behind[:3].max() > 0.1


def test_a_shipped_toon_asks_for_outlines():
    assert any(m.model.flags(m.params).get("outline") for m in LIBRARY if m.type == "toon")


@pytest.mark.parametrize("type_name", LUT_MODELS)
def test_materials_doc_lists_every_parameter_with_its_default_and_range(type_name):
    doc = (ROOT / "docs" / "materials.md").read_text(encoding="utf-8")
    section = doc.split(f"## `{type_name}`", 1)[1].split("\n## ", 1)[0]
    for p in get_model(type_name).params:
        row = f"| `{p.name}` | `{_format(p.default)}` | {p.expectation()} | {p.doc} |"
        assert row in section, f"docs/materials.md, {type_name}: missing or stale row\n{row}"
