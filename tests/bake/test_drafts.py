"""Draft bakes (``bake_atlas(drafts=True)``, what a watching preview draws first): the same texels and
include as a full bake, an entry without the figures still to measure, and a completion that gives the
full bake's manifest byte for byte and fills the cache as a full bake does."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.bake.cache import cache_path
from atlasgen.bake.pipeline import bake_atlas
from atlasgen.io.manifest import format_manifest
from atlasgen.materials.material import read_material

#: Separable materials with a draft: a fixed K with the target chosen, a budget choosing K and the grid,
#: a thin film whose back-light adds a transmission slice.
DRAFTED = {
    "fixed": 'type = "separable"\nsource = "ggx"\nalpha = 0.25\nterms = 3\n',
    "budget": 'type = "separable"\nsource = "beckmann"\nalpha = 0.3\nmax_error = 0.05\n',
    "backlit": 'type = "separable"\nsource = "thin_film"\nterms = 2\n'
    "film = { thickness = 420.0, film_ior = 1.45, base_ior = 1.8, backlight = 0.5 }\n",
}


def _same_atlas(a, b) -> None:
    assert len(a.levels) == len(b.levels)
    for la, lb in zip(a.levels, b.levels):
        np.testing.assert_array_equal(la, lb)
    assert a.include == b.include and a.includes == b.includes and a.separable_data == b.separable_data


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(DRAFTED))
def test_a_draft_is_the_full_bakes_atlas_and_its_completion_the_full_manifest(case, write_material):
    material = read_material(write_material(case, DRAFTED[case]))
    full = bake_atlas([material])
    draft = bake_atlas([material], drafts=True)
    assert sorted(draft.drafts) == [case] and full.drafts == {}
    _same_atlas(draft, full)
    drafted, whole = draft.manifest.entry_named(case), full.manifest.entry_named(case)
    # The figures measured on the report sample are what the draft leaves out ...
    assert drafted.factors.errors is None and drafted.factors.errors_8bit is None and drafted.representation is None
    assert whole.factors.errors is not None and whole.factors.errors_8bit is not None
    # ... not the choice: K (a budget's too), the grid and the target are the full bake's.
    assert (drafted.slice_count, drafted.factors.terms, drafted.factors.sampling_grid, drafted.factors.target) == (
        whole.slice_count, whole.factors.terms, whole.factors.sampling_grid, whole.factors.target)  # fmt: skip
    completed = bake_atlas([material], baked={case: draft.drafts[case]()})
    _same_atlas(completed, full)
    assert format_manifest(completed.manifest) == format_manifest(full.manifest)


@pytest.mark.slow
def test_only_the_completion_fills_the_cache(write_material, tmp_path):
    material = read_material(write_material("fixed", DRAFTED["fixed"]))
    cache = tmp_path / "cache"
    draft = bake_atlas([material], cache_dir=cache, drafts=True)
    assert not cache_path(cache, material).exists()  # a draft is never stored
    full = draft.drafts["fixed"]()
    assert cache_path(cache, material).is_file()
    assert full.timings["bake_s"] > 0
    again = bake_atlas([material], cache_dir=cache, drafts=True)
    assert again.drafts == {} and again.timings["cache"]["hits"] == ["fixed"]
    assert format_manifest(again.manifest) == format_manifest(bake_atlas([material]).manifest)


@pytest.mark.slow
@pytest.mark.parametrize(
    "body",
    [
        'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n',
        # "auto" chooses its representation by the report sample's figures: nothing to defer.
        'type = "separable"\nsource = "ggx"\nalpha = 0.3\nrepresentation = "auto"\nerror_budget = 0.05\n',
    ],
)
def test_a_material_without_a_draft_bakes_whole(write_material, body):
    material = read_material(write_material("m", body))
    draft = bake_atlas([material], drafts=True)
    assert draft.drafts == {}
    assert format_manifest(draft.manifest) == format_manifest(bake_atlas([material]).manifest)
