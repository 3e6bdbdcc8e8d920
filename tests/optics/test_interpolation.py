"""Linear filtering as a GPU sampler does it: exact on linear tables, texels at centres, clamp-to-edge."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import RegularGridInterpolator

from atlasgen.contract import texel_centres
from atlasgen.optics.interpolation import interpolate_1d, interpolate_2d, linear_stencil, sample_slice


@given(
    a=st.floats(-5, 5),
    b=st.floats(-5, 5),
    c=st.floats(-5, 5),
    x=st.lists(st.floats(-3, 40), min_size=1, max_size=20),
    y=st.lists(st.floats(-3, 40), min_size=1, max_size=20),
)
@settings(max_examples=100, deadline=None)
@pytest.mark.slow
def test_interpolation_is_exact_for_linear_tables_and_clamps(a, b, c, x, y):
    n = 32
    k = min(len(x), len(y))
    x = np.array(x[:k])
    y = np.array(y[:k])
    idx = np.arange(n)
    t1 = a + b * idx
    t2 = a + b * idx[None, :] + c * idx[:, None]  # rows y, columns x
    cx, cy = np.clip(x, 0, n - 1), np.clip(y, 0, n - 1)
    np.testing.assert_allclose(interpolate_1d(t1, x), a + b * cx, atol=1e-9)
    np.testing.assert_allclose(interpolate_2d(t2, x, y), a + b * cx + c * cy, atol=1e-9)


def test_interpolation_hits_texels_at_centres_for_every_channel():
    rng = np.random.default_rng(0)
    t = rng.random((32, 24, 2, 3))
    i = np.arange(24, dtype=float)
    j = np.arange(32, dtype=float)
    np.testing.assert_array_equal(interpolate_2d(t, i[None, :], j[:, None]), t)
    np.testing.assert_array_equal(interpolate_1d(t, j), t)


def test_bilinear_matches_an_independent_interpolator_inside_the_grid():
    rng = np.random.default_rng(1)
    t = rng.random((7, 11))
    x = rng.uniform(0, 10, 500)
    y = rng.uniform(0, 6, 500)
    reference = RegularGridInterpolator((np.arange(7.0), np.arange(11.0)), t)(np.stack([y, x], -1))
    np.testing.assert_allclose(interpolate_2d(t, x, y), reference, rtol=1e-12)


def test_stencil_of_a_single_texel_reads_it():
    i0, i1, f = linear_stencil(1, np.array([-1.0, 0.0, 0.7, 5.0]))
    assert i0.tolist() == i1.tolist() == [0, 0, 0, 0]
    assert interpolate_1d(np.array([3.5]), np.array([-1.0, 2.0])).tolist() == [3.5, 3.5]


def test_slice_lookup_hits_texel_centres_exactly_and_interpolates_linearly_between():
    rng = np.random.default_rng(4)
    table = rng.random((32, 64, 4))
    nl, nv = texel_centres()
    grid_l, grid_v = np.meshgrid(nl, nv)
    np.testing.assert_allclose(sample_slice(table, grid_l, grid_v), table, atol=1e-12)

    @settings(max_examples=50, deadline=None)
    @given(st.integers(0, 62), st.integers(0, 31), st.floats(0.0, 1.0))
    def halfway(i, j, t):
        # Along N.L between texel centres i and i+1 (fixed row j): linear in t.
        got = sample_slice(table, np.array([nl[i] + t * (nl[i + 1] - nl[i])]), np.array([nv[j]]))[0]
        np.testing.assert_allclose(got, (1 - t) * table[j, i] + t * table[j, i + 1], atol=1e-9)

    halfway()
    # Clamp to edge outside the domain, as the sampler's addressing mode does.
    np.testing.assert_allclose(sample_slice(table, np.array([-3.0, 3.0]), np.array([-1.0, 2.0])), table[[0, -1], [0, -1]])


@pytest.mark.parametrize(
    "nl, nv, texel", [(-1.0, 0.0, (0, 0)), (1.0, 1.0, (31, 63)), (-1.0 + 2 * 10.4 / 63, 20.6 / 31, (21, 10))]
)
def test_nearest_reads_the_texel_containing_the_point(nl, nv, texel):
    table = np.arange(32 * 64, dtype=float).reshape(32, 64, 1)
    assert sample_slice(table, np.array([nl]), np.array([nv]), nearest=True)[0, 0] == table[texel][0]
