"""Adaptive LUT supersampling: the cheapest pre-filter that meets an error budget."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.bake.adaptive import SUPERSAMPLING_FACTORS, bake_supersampled, bake_within_budget, reconstruction_error
from atlasgen.models.base import Model
from atlasgen.models.lambert import Lambert


class Bands(Model):
    """Two hard toon bands: a discontinuity at N.L = threshold, between texel centres."""

    type_name = "bands"

    def evaluate(self, values, n_dot_l, n_dot_v):
        nl = np.asarray(n_dot_l, dtype=np.float64)
        shape = np.broadcast(nl, np.asarray(n_dot_v)).shape
        out = np.zeros(shape + (4,))
        out[..., :3] = np.where(nl >= values["threshold"], 1.0, 0.2)[..., None]
        return out


def test_supersampling_one_is_point_sampling_at_texel_centres():
    from atlasgen.contract import texel_grid

    nl, nv = texel_grid()
    model = Lambert()
    values = {"colour": (0.5, 0.25, 1.0)}
    np.testing.assert_array_equal(bake_supersampled(model, values, 1), model.evaluate(values, nl, nv))


def test_a_smooth_model_needs_no_supersampling():
    chosen = bake_within_budget(Lambert(), {"colour": (1.0, 1.0, 1.0)}, budget=0.01)
    assert chosen.extra["representation"]["supersampling"] == 1
    assert chosen.extra["representation"]["meets_budget"]


def test_bands_need_prefiltering_and_it_helps():
    errors = [
        reconstruction_error(Bands(), {"threshold": 0.3}, bake_supersampled(Bands(), {"threshold": 0.3}, f))
        for f in SUPERSAMPLING_FACTORS
    ]
    assert errors[-1] < errors[0]


@pytest.mark.slow
@settings(max_examples=12, deadline=None)
@given(st.floats(-0.9, 0.9), st.floats(1e-4, 0.2), st.floats(0.05, 1.0))
def test_a_tighter_budget_never_yields_a_larger_error(threshold, tight, ratio):
    loose = tight / ratio
    values = {"threshold": threshold}
    e_tight = bake_within_budget(Bands(), values, tight).extra["representation"]["reconstruction_error"]
    e_loose = bake_within_budget(Bands(), values, loose).extra["representation"]["reconstruction_error"]
    assert e_tight <= e_loose + 1e-15


def test_budget_reaches_the_manifest(tmp_path, write_material):
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_materials

    write_material("a", 'type = "lambert"\nerror_budget = 0.02\n')
    entry = bake_atlas(read_materials([tmp_path / "materials"])).manifest.materials[0]
    assert entry.representation.supersampling == 1
    assert entry.representation.error_budget == 0.02


@pytest.mark.parametrize("bad", ["0", "-1", "nan", '"tight"'])
def test_bad_budget(write_material, bad):
    from atlasgen.errors import MaterialError
    from atlasgen.materials.material import read_material

    with pytest.raises(MaterialError, match="field 'error_budget': expected a finite number > 0"):
        read_material(write_material("a", f'type = "lambert"\nerror_budget = {bad}\n'))


def test_a_separable_budget_is_its_term_budget(write_material):
    from atlasgen.errors import MaterialError
    from atlasgen.materials.material import read_material

    m = read_material(write_material("s", 'type = "separable"\nsource = "ggx"\nerror_budget = 0.03\n'))
    assert m.params["max_error"] == 0.03
    with pytest.raises(MaterialError, match="field 'error_budget': expected either 'terms'"):
        read_material(write_material("t", 'type = "separable"\nterms = 2\nerror_budget = 0.03\n'))
