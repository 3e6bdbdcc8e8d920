"""``representation = "auto"``: the cheapest candidate in run-time cost that meets the budget."""

from __future__ import annotations

import json

import pytest
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.separable.auto import choose_representation, read_lighting_cost

_costs = st.floats(0.1, 1000.0, allow_nan=False)
_errors = st.floats(0.0, 1.0, allow_nan=False)
_tables = st.lists(st.tuples(_costs, _errors), min_size=1, max_size=12)


def _candidates(table):
    return [{"representation": f"c{i}", "cost": c, "error": e} for i, (c, e) in enumerate(table)]


@given(_tables, st.floats(1e-4, 1.0))
def test_auto_picks_the_cheapest_candidate_meeting_the_budget(table, budget):
    best, annotated = choose_representation(_candidates(table), budget)
    meeting = [c for c in annotated if c["error"] <= budget]
    assert [c["meets_budget"] for c in annotated] == [c["error"] <= budget for c in annotated]
    if meeting:
        assert annotated[best]["error"] <= budget
        assert annotated[best]["cost"] == min(c["cost"] for c in meeting)
    else:
        assert annotated[best]["error"] == min(c["error"] for c in annotated)


@given(_tables, st.floats(1e-4, 1.0), st.floats(1e-4, 1.0))
@pytest.mark.slow
def test_a_tighter_budget_never_yields_a_larger_error(table, a, b):
    tight, loose = sorted((a, b))
    candidates = _candidates(table)
    at_tight, ann = choose_representation(candidates, tight)
    at_loose, _ = choose_representation(candidates, loose)
    assert ann[at_tight]["error"] <= ann[at_loose]["error"]


def test_the_shipped_cost_table_names_its_device_and_ranks_eight_terms_above_one():
    table = read_lighting_cost()
    assert table.device and table.unit == "ns per pixel per light"
    assert all(v > 0 for v in table.costs.values())
    assert table.cost("separable:8") > table.cost("separable:1")


@pytest.mark.slow
def test_auto_bake_records_its_choice_and_every_candidate(write_material, tmp_path):
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.io.manifest import AnalyticRepresentation, SeparableRepresentation
    from atlasgen.materials.material import read_materials

    write_material("metal", 'type = "separable"\nsource = "ggx"\nalpha = 0.3\nrepresentation = "auto"\nerror_budget = 0.05\n')
    write_material("gold", 'type = "separable"\nsource = "mitsuba"\nbsdf = {type = "roughconductor", alpha = 0.3, material = "Au"}\n'
                           'representation = "auto"\nerror_budget = 0.05\n')  # fmt: skip
    manifest = bake_atlas(read_materials([tmp_path / "materials"])).manifest
    table = read_lighting_cost()
    metal, gold = manifest.entry_named("metal").representation, manifest.entry_named("gold").representation
    # A GGX source: its closed form is exact, and cheaper than any K in the shipped table.
    assert isinstance(metal, AnalyticRepresentation) and metal.auto["chosen"] == "analytic:ggx"
    assert metal.auto["cost_device"] == table.device
    # A Mitsuba BSDF has no closed form in the shader, and a coloured conductor's highlight is
    # beyond one slice (A is a scalar): K separable terms, the cheapest meeting 5%.
    assert isinstance(gold, SeparableRepresentation) and gold.auto["chosen"] == f"separable:{gold.terms}"
    candidates = gold.auto["candidates"]
    assert [c["representation"] for c in candidates] == ["lut"] + [f"separable:{k}" for k in range(1, 9)]
    assert not candidates[0]["meets_budget"]
    assert all(c["cost"] == table.cost(c["representation"]) for c in candidates)
    meeting = [c for c in candidates if c["meets_budget"]]
    assert meeting and gold.auto["chosen"] == min(meeting, key=lambda c: c["cost"])["representation"]
    json.dumps(gold.auto)
