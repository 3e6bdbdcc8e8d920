"""The least-squares projection onto the renderer's equation (atlasgen.optics.projection):
closed-form round trips, an independent NNLS solver, and monotonicity in the weights."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import nnls

from atlasgen.contract import texel_centres
from atlasgen.models.physical_fit import azimuth_pairs, fit_slice, renderer_bases
from atlasgen.optics.projection import (
    collinear_texels,
    continue_collinear_texels,
    project_slice_texels,
    refine_specular_scale,
    solve_nonnegative_least_squares,
    weighted_residual,  # fmt: skip
)
from atlasgen.optics.srgb import encode_srgb

AZIMUTHS = 64


@pytest.fixture(scope="module")
def texels():
    """Every texel's azimuth samples and the renderer's bases there, at gloss 0.5."""
    nl, nv = texel_centres()
    l, v, nh, degenerate = azimuth_pairs(nl, nv, AZIMUTHS)
    diffuse, lobe = renderer_bases(0.5, l, v, nh, degenerate)
    weights = np.full(l.shape[:-1], 1.0 / AZIMUTHS)
    return nl, nv, l, v, diffuse, lobe, weights


def test_lambertian_projects_onto_itself(texels):
    nl, nv, l, v, diffuse, lobe, weights = texels
    colour = np.array([0.8, 0.4, 0.1])
    target = colour * np.maximum(l[..., 2:3], 0.0) / np.pi
    rgba = project_slice_texels(target, diffuse, lobe, weights)
    expected = np.maximum(nl, 0.0)[None, :, None] * colour
    np.testing.assert_allclose(rgba[..., :3], np.broadcast_to(expected, rgba[..., :3].shape), atol=1e-5)
    assert np.abs(rgba[..., 3]).max() < 1e-5


def test_diffuse_plus_renderer_lobe_with_constant_fresnel_projects_onto_itself(texels):
    """A BSDF the slice holds exactly: any RGB of (N.L, N.V) plus c(N.L, N.V) times the renderer's lobe."""
    nl, nv, l, v, diffuse, lobe, weights = texels
    lit = np.maximum(nl, 0.0)[None, :]
    rgb = np.stack(np.broadcast_arrays(0.6 * lit * (1.0 - 0.3 * nv[:, None]), 0.2 * lit, 0.05 * lit + 0.1 * nv[:, None]), -1)
    fresnel = 0.04 + 0.96 * (1.0 - nv[:, None]) ** 5 + 0.0 * nl[None, :]  # Schlick's F(N.V), constant over azimuth
    target = diffuse * rgb[..., None, :] + lobe * fresnel[..., None, None]
    rgba = project_slice_texels(target, diffuse, lobe, weights)
    # At N.L = 1 or N.V = 1 every azimuth gives the same pair: the lobe is a constant there,
    # which the diffuse term holds as well, and the ridge gives it to the diffuse term. At
    # N.V = 0 the GGX lobe barely varies with azimuth, so the split is as ill-conditioned.
    rgba, rgb, fresnel, target, diffuse, lobe, weights = (
        x[1:-1, :-1] for x in (rgba, rgb, fresnel, target, diffuse, lobe, weights)
    )
    np.testing.assert_allclose(rgba[..., :3], rgb, atol=1e-4)
    # The ridge (1e-6 of the diffuse Gram entry, 3/pi^2) leaves A exact to 1e-3 where the lobe carries more than 1e-3.
    has_lobe = (weights[..., None] * lobe**2).sum(axis=(-2, -1)) > 1e-3
    np.testing.assert_allclose(rgba[..., 3][has_lobe], fresnel[has_lobe], rtol=1e-3)
    assert weighted_residual(target, diffuse, lobe, weights, rgba).sum() < 1e-6 * (weights[..., None] * target**2).sum()


def _random_problem(rng, samples=24):
    diffuse = np.full((samples, 3), 1.0 / np.pi) * rng.uniform(0.5, 1.5, 3)
    lobe = np.repeat(rng.gamma(0.5, 2.0, (samples, 1)), 3, axis=1)
    target = rng.normal(0.1, 0.4, (samples, 3)) + lobe * rng.uniform(-1.0, 1.0)
    weights = rng.uniform(0.1, 1.0, samples)
    return target, diffuse, lobe, weights


@pytest.mark.parametrize("seed", range(40))
def test_projection_matches_an_independent_nnls_solver(seed):
    """scipy.optimize.nnls (Lawson-Hanson active set) on the same weighted problem."""
    target, diffuse, lobe, weights = _random_problem(np.random.default_rng(seed))
    design = np.zeros((len(target), 3, 4))
    for c in range(3):
        design[:, c, c] = diffuse[:, c]
    design[:, :, 3] = lobe
    root_w = np.sqrt(weights)[:, None, None]
    expected, _ = nnls((root_w * design).reshape(-1, 4), (root_w[..., 0] * target).reshape(-1))
    got = project_slice_texels(target, diffuse, lobe, weights, ridge=0.0)
    assert (got >= 0.0).all()
    np.testing.assert_allclose(got, expected, atol=1e-7)


@pytest.mark.parametrize("seed", range(40))
def test_more_weight_on_a_sample_never_increases_its_residual(seed):
    rng = np.random.default_rng(seed)
    target, diffuse, lobe, weights = _random_problem(rng)
    k = int(rng.integers(len(target)))

    def residual_at_k(w):
        rgba = project_slice_texels(target, diffuse, lobe, w)
        one = np.zeros_like(w)
        one[k] = 1.0
        return float(weighted_residual(target, diffuse, lobe, one, rgba))

    before = residual_at_k(weights)
    for factor in (1.5, 4.0, 50.0):
        heavier = weights.copy()
        heavier[k] *= factor
        after = residual_at_k(heavier)
        assert after <= before + 1e-10 * max(before, 1e-12)
        before = after


def test_nonnegative_even_when_the_target_pulls_negative():
    rng = np.random.default_rng(7)
    target, diffuse, lobe, weights = _random_problem(rng)
    target = target - 2.0 * lobe  # wants a negative A and negative colours
    rgba = project_slice_texels(target, diffuse, lobe, weights)
    assert (rgba >= 0.0).all() and rgba[3] == 0.0
    assert (refine_specular_scale(target, diffuse, lobe, weights, rgba[:3]) == 0.0).all()


def test_solver_takes_the_unconstrained_minimum_when_it_is_feasible():
    rng = np.random.default_rng(3)
    b = rng.uniform(0.0, 1.0, (10, 3))
    x = np.array([0.5, 1.0, 2.0])
    gram, rhs = b.T @ b, b.T @ (b @ x)
    np.testing.assert_allclose(solve_nonnegative_least_squares(gram, rhs), x, rtol=1e-8)


def test_fitted_lambertian_slice_holds_the_colour_to_one_srgb_step():
    """fit_slice rounds RGB as the atlas stores it (sRGB 8-bit, per-slice scale) and refits A."""
    colour = np.array([0.8, 0.4, 0.1])
    rgba, info = fit_slice(lambda l, v: colour * np.maximum(l[:, 2:3], 0.0) / np.pi, gloss=0.5, azimuths=16)
    nl, _ = texel_centres()
    expected = np.maximum(nl, 0.0)[None, :, None] * colour
    # The peak is below 1, so the slice's scale is 1: the stored code is encode_srgb(value).
    step = np.abs(encode_srgb(rgba[..., :3]) - encode_srgb(np.broadcast_to(expected, rgba[..., :3].shape)))
    assert step.max() <= 0.5 / 255 + 1e-9
    assert info["gloss"] == 0.5 and info["relative_rms"] < 0.01


@pytest.mark.slow
def test_a_fit_choosing_its_gloss_finds_the_lobe_width_between_grid_points():
    """A diffuse colour plus 0.3 times the renderer's own lobe at a gloss off the 1/32 grid:
    the slice holds it exactly at that gloss only, and the refined search lands on it."""
    truth = 0.6123
    assert min(abs(truth - k / 32) for k in range(33)) > 0.005

    def f_cos(l, v):
        h = l + v
        h2 = (h * h).sum(-1)
        nh = np.divide(h[:, 2], np.sqrt(h2), out=np.zeros_like(h2), where=h2 > 1e-12)
        diffuse, lobe = renderer_bases(truth, l[:, None], v[:, None], nh[:, None], (h2 <= 1e-12)[:, None])
        return (diffuse * np.array([0.5, 0.3, 0.2]) + 0.3 * lobe)[:, 0]

    _, info = fit_slice(f_cos, gloss=None, azimuths=32)
    assert abs(info["gloss"] - truth) < 1e-3, info
    assert info["relative_rms"] < 0.01, info


def test_collinear_texels_are_the_normal_column_and_row_where_the_lobe_is_lit(texels):
    """At N.L = 1 or N.V = 1 every azimuth gives the same (l, v): the lobe is a constant multiple
    of the diffuse term there, and nowhere else (the lobe is zero where N.L <= 0)."""
    nl, nv, l, v, diffuse, lobe, weights = texels
    expected = (nl[None, :] > 0.0) & ((nl[None, :] == 1.0) | (nv[:, None] == 1.0))
    np.testing.assert_array_equal(collinear_texels(diffuse, lobe, weights), expected)


def test_a_pure_lobe_stays_in_a_through_the_collinear_row_and_column(texels):
    """A conductor-like target, c(N.L, N.V) times the renderer's lobe with no diffuse part: the
    slice holds it with A.rgb = 0 at every separable texel, and at N.L = 1 and N.V = 1 A continues
    the smooth c, so A.rgb there holds only c's change over one texel (A.rgb = k (c - A), k = S / D)."""
    nl, nv, l, v, diffuse, lobe, weights = texels
    c = 0.9 + 0.05 * nl[None, :] - 0.04 * (1.0 - nv[:, None]) ** 2
    target = lobe * c[..., None, None]
    raw = project_slice_texels(target, diffuse, lobe, weights)
    rgba = continue_collinear_texels(raw, diffuse, lobe, weights)
    collinear = collinear_texels(diffuse, lobe, weights)
    # The N.V = 0 row is left out: there the lobe barely varies with azimuth, ill-conditioned but not collinear.
    inner = ~collinear & (nv[:, None] > 0.0)
    np.testing.assert_allclose(rgba[inner][:, :3], 0.0, atol=1e-3 * c.max())  # the ridge, where the lobe is faint
    step = 0.05 * 2.0 / 63 + 0.04 * 2.0 / 31  # c's largest change over one texel diagonal
    # Where the lobe is faint (N.L near 0) the ridge leaves the neighbour's split, and so A, to the diffuse term.
    has_lobe = (weights[..., None] * lobe**2).sum(axis=(-2, -1)) > 1e-3
    firm = collinear & has_lobe
    assert np.abs(rgba[..., 3] - c)[firm].max() <= step
    k = lobe[..., 0, 0] / diffuse[..., 0, 0]
    assert (rgba[firm][:, :3] <= (k * step)[firm][:, None]).all()
    assert (rgba[firm][:, :3] < 0.1 * raw[firm][:, :3]).all()  # the ridge's split gave it all to A.rgb
    # The split changed, the fit at each texel's own samples did not.
    np.testing.assert_allclose(weighted_residual(target, diffuse, lobe, weights, rgba),
                               weighted_residual(target, diffuse, lobe, weights, raw), atol=1e-12)  # fmt: skip


def test_continuing_the_split_keeps_each_collinear_texels_fit_and_colours_non_negative(texels):
    """A random split at every collinear texel: the continued slice gives the same radiance at
    each of the texel's samples (r_c + k A is kept), never a negative colour, and A no larger
    than the nearest separable texel's."""
    nl, nv, l, v, diffuse, lobe, weights = texels
    rng = np.random.default_rng(11)
    rgba = rng.uniform(0.0, 1.0, diffuse.shape[:2] + (4,))
    out = continue_collinear_texels(rgba, diffuse, lobe, weights)
    before = diffuse * rgba[..., None, :3] + lobe * rgba[..., None, 3:]
    after = diffuse * out[..., None, :3] + lobe * out[..., None, 3:]
    np.testing.assert_allclose(after, before, rtol=1e-12, atol=1e-12)
    assert (out >= 0.0).all()
    collinear = collinear_texels(diffuse, lobe, weights)
    np.testing.assert_array_equal(out[~collinear], rgba[~collinear])
    # Corner (N.L, N.V) = (1, 1): its nearest separable texel is the diagonal one.
    assert out[-1, -1, 3] <= rgba[-2, -2, 3] + 1e-15


def test_a_fitted_sharp_lobe_holds_between_the_last_texels_as_the_renderer_filters_it():
    """fit_slice of 0.9 times the renderer's own sharp lobe (gloss 0.7, alpha 0.09), read as the
    renderer reads it (bilinear A.rgb and A) at random pairs with N.L and N.V in the last texel
    cells, near the mirror direction: the slice is A = 0.9 there too, so the error is 8-bit only.
    Before the collinear texels were continued, the corner held the peak as a diffuse A.rgb of
    about 23 that the filter spread over the highlight."""
    from atlasgen.optics.interpolation import sample_slice
    from atlasgen.optics.specular import half_vector_cosine

    gloss = 0.7

    def f_cos(l, v):
        nh, degenerate = half_vector_cosine(l, v)
        _, lobe = renderer_bases(gloss, l[:, None], v[:, None], nh[:, None], degenerate[:, None])
        return 0.9 * lobe[:, 0]

    rgba, _ = fit_slice(f_cos, gloss=gloss, azimuths=32)
    rng = np.random.default_rng(5)
    n = 4000
    cos_l, cos_v = rng.uniform(1.0 - 1.0 / 31, 1.0, (2, n))
    phi = np.pi + rng.uniform(-0.5, 0.5, n)  # l about opposite v in azimuth: the mirror lobe
    sl, sv = np.sqrt(1.0 - cos_l**2), np.sqrt(1.0 - cos_v**2)
    l = np.stack([sl * np.cos(phi), sl * np.sin(phi), cos_l], -1)
    v = np.stack([sv, 0.0 * sv, cos_v], -1)
    nh, degenerate = half_vector_cosine(l, v)
    diffuse, lobe = renderer_bases(gloss, l, v, nh, degenerate)
    texel = sample_slice(rgba, cos_l, cos_v)
    shown = diffuse * texel[:, :3] + lobe * texel[:, 3:]
    target = f_cos(l, v)
    assert np.sqrt(((shown - target) ** 2).sum() / (target**2).sum()) < 0.01


def test_the_split_continues_from_a_texel_with_a_lobe_not_from_one_lit_from_below(texels):
    """Where the light is below the horizon (N.L <= 0) the lobe is 0 and so is A: a collinear
    texel must take its split from the nearest texel whose samples see a lobe, or it would hand
    its whole lobe to A.rgb. Here the texel below the first lit one of the N.V = 1 row is made
    lobe-less too, so both of that texel's nearest neighbours are, and the diagonal one must serve."""
    nl, nv, l, v, diffuse, lobe, weights = texels
    lobe = np.array(np.broadcast_to(lobe, diffuse.shape))
    first_lit = int(np.argmax((weights[-1][..., None] * lobe[-1] ** 2).sum(axis=(-2, -1)) > 0.0))
    lobe[-2, first_lit] = 0.0
    has_lobe = (weights[..., None] * lobe**2).sum(axis=(-2, -1)) > 0.0
    collinear = collinear_texels(diffuse, lobe, weights)
    assert collinear[-1, first_lit] and not has_lobe[-1, first_lit - 1] and not has_lobe[-2, first_lit]
    rgba = np.zeros(diffuse.shape[:2] + (4,))
    rgba[..., 3] = np.where(has_lobe, 0.5, 0.0)
    out = continue_collinear_texels(rgba, diffuse, lobe, weights)
    np.testing.assert_allclose(out[collinear][:, 3], 0.5, rtol=1e-12)
    np.testing.assert_allclose(out[collinear][:, :3], 0.0, atol=1e-12)
