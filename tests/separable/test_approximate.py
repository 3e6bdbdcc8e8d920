"""Choosing the representation: terms, sampling grid and target against an error budget."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.separable.approximate import GRID_RESOLUTIONS, _choose, approximate_brdf
from tests.separable.separable_helpers import analytic

errors = st.floats(min_value=1e-4, max_value=1.0)


@st.composite
def candidate_tables(draw):
    grids = draw(st.lists(st.sampled_from((8, 16, 24, 32, 48)), min_size=1, max_size=4, unique=True))
    k = draw(st.integers(1, 8))
    return [
        {"grid": g, "target": t, "errors": [{"terms": i + 1, "relative_rms": draw(errors)} for i in range(k)]}
        for g in sorted(grids)
        for t in ("f_cos", "f_proxy")
    ]


def _chosen_error(table, budget):
    i, k, met = _choose(table, None, budget)
    error = table[i]["errors"][k - 1]["relative_rms"]
    assert met == (error <= budget)
    return error


@given(candidate_tables(), errors, errors)
@pytest.mark.slow
def test_a_tighter_budget_never_yields_a_larger_error(table, a, b):
    tight, loose = sorted((a, b))
    assert _chosen_error(table, tight) <= _chosen_error(table, loose)


@pytest.mark.slow
@given(candidate_tables(), errors)
def test_the_choice_is_the_cheapest_meeting_the_budget_else_the_least_error(table, budget):
    i, k, met = _choose(table, None, budget)
    cost = (k, table[i]["grid"])
    meeting = [(e["terms"], c["grid"]) for c in table for e in c["errors"] if e["relative_rms"] <= budget]
    if meeting:
        assert met and cost == min(meeting)
    else:
        assert not met
        assert table[i]["errors"][k - 1]["relative_rms"] == min(e["relative_rms"] for c in table for e in c["errors"])


@pytest.fixture(scope="module")
def sharp():
    # A near-mirror lobe: the case where the sampling grid matters most.
    return approximate_brdf(analytic("ggx", alpha=0.05), terms=4, target="f_proxy", grids=(16, 32, 48))


@pytest.mark.slow
def test_every_grid_is_measured_on_the_stored_resolution(sharp):
    assert sharp.factors.resolution == 32 and sharp.terms == 4
    assert sorted(c["grid"] for c in sharp.candidates) == [16, 32, 48]
    assert all(len(c["relative_rms_by_terms"]) == 4 for c in sharp.candidates)


@pytest.mark.slow
def test_a_fixed_k_takes_the_grid_with_the_least_error(sharp):
    at_k = {c["grid"]: c["relative_rms_by_terms"][3] for c in sharp.candidates}
    assert sharp.grid == min(at_k, key=at_k.get)
    # The hemisphere error: least squares from a finer grid beats sampling at the stored
    # texels, which beats interpolating a coarser one (docs/separable.md says why the
    # finer grid is still not a default: it rings around the highlight in images).
    assert at_k[48] < at_k[32] < at_k[16]


@pytest.mark.slow
def test_the_search_stops_at_a_grid_that_meets_the_budget_with_one_term():
    broad = analytic("lambert", diffuse=(0.6, 0.5, 0.4))
    result = approximate_brdf(broad, max_error=0.05, grids=GRID_RESOLUTIONS)
    assert (result.terms, result.grid, result.max_error_met) == (1, GRID_RESOLUTIONS[0], True)
    assert {c["grid"] for c in result.candidates} == {GRID_RESOLUTIONS[0]}
    # A budget one term cannot meet on the coarse grid samples every grid.
    tight = approximate_brdf(analytic("ggx", alpha=0.2), max_error=0.02, grids=GRID_RESOLUTIONS)
    assert {c["grid"] for c in tight.candidates} == set(GRID_RESOLUTIONS)


@pytest.mark.slow
def test_one_grid_by_default_keeps_the_stored_resolution():
    result = approximate_brdf(analytic("beckmann", alpha=0.4), terms=2)
    assert result.grid == 32 and [c["grid"] for c in result.candidates] == [32, 32]
    assert np.isfinite(result.errors["relative_rms"])


@pytest.mark.slow
def test_the_term_search_weighs_both_factorizations_and_stops_at_the_first_k_that_meets():
    from atlasgen.separable.approximate import search_terms
    from atlasgen.separable.error import SELECTION_SEED, error_sample_for, upper_bound

    source = analytic("ggx", alpha=0.15, fresnel="schlick", f0=(0.9, 0.6, 0.3))
    selection = error_sample_for(source, SELECTION_SEED, count=20_000)
    reference = source.f_cos(*selection.pairs)
    found, _ = search_terms(source, "half_diff", 0.0, selection, reference, targets=("f_cos",), max_terms=3)
    # A budget of 0 is never met: every K up to the cap, each factorization once per K.
    assert [(c["terms"], c["factorization"]) for c in found] == [(k, m) for k in (1, 2, 3) for m in ("svd", "nmf")]
    svd = [c["relative_rms"] for c in found if c["factorization"] == "svd"]
    assert svd == sorted(svd, reverse=True)  # prefixes of one SVD: the error never grows with K
    # One term of either factorization is the same rank-1 fit up to 8 bits (NMF starts from |SVD|).
    first = [c["relative_log_rms"] for c in found if c["terms"] == 1]
    assert first[0] == pytest.approx(first[1], rel=0.05)
    budget = min(upper_bound(c, "relative_log_rms") for c in found if c["terms"] == 2)
    stopped, _ = search_terms(source, "half_diff", budget, selection, reference, targets=("f_cos",), max_terms=3)
    assert max(c["terms"] for c in stopped) == 2 and stopped == found[:4]


@pytest.mark.slow
def test_the_term_search_keeps_per_k_the_target_a_fixed_k_would_store():
    """Both targets are factored at each K; with ``target_measure`` only the one of less relative RMS
    stays a candidate, as a fixed K of that factorization chooses (``_choose``): the budget then picks K
    and the factorization, never a target that K would not be baked with."""
    from atlasgen.separable.approximate import search_terms
    from atlasgen.separable.error import SELECTION_SEED, error_sample_for

    source = analytic("ggx", alpha=0.15, fresnel="schlick", f0=(0.9, 0.6, 0.3))
    selection = error_sample_for(source, SELECTION_SEED, count=20_000)
    reference = source.f_cos(*selection.pairs)
    every, _ = search_terms(source, "half_diff", 0.0, selection, reference, max_terms=2, target_measure=None)
    kept, _ = search_terms(source, "half_diff", 0.0, selection, reference, max_terms=2)
    assert [(c["terms"], c["factorization"]) for c in every] == [(k, m) for k in (1, 2) for m in ("svd", "nmf") for _ in (0, 1)]
    expected = [min((c for c in every if (c["terms"], c["factorization"]) == (k, m)), key=lambda c: c["relative_rms"])
                for k in (1, 2) for m in ("svd", "nmf")]  # fmt: skip
    assert kept == expected
    assert {c["target"] for c in every} == {"f_cos", "f_proxy"}
