"""The supersampled fit from physics (atlasgen/models/physical_fit.py): f cos averaged over each
texel's footprint, projected at the texel centre."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.contract import HEIGHT, WIDTH, texel_centres
from atlasgen.models.physical_fit import GRAZING_N_DOT_V, fit_slice, footprint_f_cos


def _diffuse(g):
    """f cos = g(N.L, N.V) (1, 1/2, 1/4) / pi: the renderer's diffuse term with RGB = g (1, 1/2, 1/4)."""

    def f_cos(l, v):
        x = g(l[:, 2], v[:, 2])
        return np.stack([x, 0.5 * x, 0.25 * x], axis=-1) / np.pi

    return f_cos


def _linear(nl, nv):
    return 0.3 + 0.2 * nl + 0.4 * nv


def test_footprint_mean_of_a_linear_function_is_its_value_at_the_centre():
    """Inside the slice the box is symmetric about the centre: the mean of a linear function is its
    centre value. At the edges the bake's clip makes it the mean over the clipped sub-positions."""
    boxed = footprint_f_cos(_diffuse(_linear), azimuths=8, factor=4)[..., 0] * np.pi
    nl, nv = texel_centres(WIDTH, HEIGHT)
    np.testing.assert_allclose(
        boxed[1:-1, 1:-1], _linear(nl[None, 1:-1, None], nv[1:-1, None, None]).repeat(8, -1), rtol=0, atol=1e-13
    )
    offsets = (np.arange(4) + 0.5) / 4 - 0.5
    edge_nl = np.clip(1.0 + offsets * 2.0 / (WIDTH - 1), -1.0, 1.0).mean()  # the last column: half its box is past N.L = 1
    edge_nv = np.maximum(np.clip(offsets / (HEIGHT - 1), 0.0, 1.0), GRAZING_N_DOT_V).mean()  # row 0, floored as the fit floors it
    np.testing.assert_allclose(boxed[0, -1], _linear(edge_nl, edge_nv), rtol=0, atol=1e-13)


@pytest.mark.slow
def test_supersampled_fit_of_a_function_linear_over_each_texel_is_the_point_fit(monkeypatch):
    from atlasgen.models import physical_fit

    # The slices' peaks differ at the clipped edge boxes, and so would their 8-bit scales (each
    # slice's peak): one common scale makes the inside round alike, which is what is compared.
    monkeypatch.setattr(physical_fit, "unorm_scale", lambda peak: 1.0)
    point, _ = fit_slice(_diffuse(_linear), 0.5)
    boxed, info = fit_slice(_diffuse(_linear), 0.5, supersampling=4)
    assert info["supersampling"] == 4
    np.testing.assert_array_equal(boxed[1:-1, 1:-1, :3], point[1:-1, 1:-1, :3])
    np.testing.assert_allclose(boxed[1:-1, 1:-1, 3], point[1:-1, 1:-1, 3], rtol=0, atol=1e-12)


@pytest.mark.slow
def test_supersampled_fit_of_a_sharp_feature_is_closer_to_the_texel_mean():
    """A ridge in N.L narrower than a texel (sigma = 0.004, texels 0.032 apart) between two texel
    centres: point sampling sees only its tails, the footprint its mean. Texel means by a dense
    midpoint rule over the same (clipped) box."""
    centre = -1.0 + 2.0 * 40.3 / (WIDTH - 1)

    def ridge(nl, nv):
        return 0.05 + 0.9 * np.exp(-0.5 * ((nl - centre) / 0.004) ** 2)

    point, _ = fit_slice(_diffuse(ridge), 0.5)
    boxed, _ = fit_slice(_diffuse(ridge), 0.5, supersampling=4)
    nl, _ = texel_centres(WIDTH, HEIGHT)
    dense = (np.arange(400) + 0.5) / 400 - 0.5
    mean = ridge(np.clip(nl[:, None] + dense * 2.0 / (WIDTH - 1), -1.0, 1.0), 0.5).mean(axis=1)  # (W,)
    row = HEIGHT // 2  # the ridge does not depend on N.V
    point_error = np.abs(point[row, :, 0] - mean)
    boxed_error = np.abs(boxed[row, :, 0] - mean)
    assert point_error.max() > 0.1  # the point fit misses the ridge's mass
    assert boxed_error.max() < 0.05 * point_error.max() + 2.0 / 255.0  # the footprint holds it, to about 8-bit rounding
    assert np.sum(boxed_error**2) < 0.1 * np.sum(point_error**2)


def test_footprint_pairs_deal_the_point_fits_azimuths_over_the_footprint():
    from atlasgen.models.physical_fit import AZIMUTHS, azimuth_pairs, footprint_pairs

    l, v, _, _ = footprint_pairs(AZIMUTHS, 4)
    nl, nv = texel_centres(WIDTH, HEIGHT)
    centre, _, _, _ = azimuth_pairs(nl, np.maximum(nv, GRAZING_N_DOT_V), AZIMUTHS)
    # Every texel sees the point fit's S azimuth strata once each (as a set), at 16 sub-positions
    # whose mean is the texel centre inside the slice.
    # (inside columns: at N.L = +-1 l has no azimuth)
    phi = np.sort(np.mod(np.arctan2(l[:, 1:-1, :, 1], l[:, 1:-1, :, 0]), 2 * np.pi), axis=-1)
    np.testing.assert_allclose(phi, np.mod(np.arctan2(centre[:, 1:-1, :, 1], centre[:, 1:-1, :, 0]), 2 * np.pi), atol=1e-12)
    np.testing.assert_allclose(l[1:-1, 1:-1, :, 2].mean(-1), nl[None, 1:-1].repeat(HEIGHT - 2, 0), atol=1e-13)
    assert np.unique(l[5, 5, :, 2]).size == 4 and np.unique(v[5, 5, :, 2]).size == 4


@pytest.mark.slow
def test_footprint_fit_of_the_renderers_own_equation_is_exact_to_8_bits():
    """f cos = c / pi + A0 D V max(N.L, 0) at the fit's gloss is the renderer's equation with one
    constant texel value: fitted over the footprint, the slice reproduces it (at the footprint's pairs
    and at the centres') as closely as the point fit does, to the 8-bit rounding of RGB and A."""
    from atlasgen.models.physical_fit import renderer_bases, slice_relative_rms
    from atlasgen.optics.specular import half_vector_cosine

    c, a0 = np.array([0.4, 0.2, 0.1]), 0.3

    def f_cos(l, v):
        nh, degenerate = half_vector_cosine(l, v)
        diffuse, lobe = renderer_bases(0.5, l, v, nh, degenerate)
        return diffuse * c + lobe * a0

    point, point_info = fit_slice(f_cos, 0.5)
    fitted, info = fit_slice(f_cos, 0.5, supersampling=4, footprint="fit")
    assert info["footprint"] == "fit" and info["supersampling"] == 4
    assert point_info["relative_rms"] < 0.005 and info["relative_rms"] < 0.005
    assert slice_relative_rms(fitted, f_cos, 0.5) < 0.005
    # (A itself is loosely tied where the lobe is faint: the projection's ridge decides it there.)
    np.testing.assert_allclose(np.median(fitted[2:-2, 2:-2, :3], axis=(0, 1)), c, rtol=0.01)


@pytest.mark.slow
def test_footprint_fit_of_a_sharp_feature_is_closer_to_the_texel_mean():
    centre = -1.0 + 2.0 * 40.3 / (WIDTH - 1)

    def ridge(nl, nv):
        return 0.05 + 0.9 * np.exp(-0.5 * ((nl - centre) / 0.004) ** 2)

    point, _ = fit_slice(_diffuse(ridge), 0.5)
    fitted, _ = fit_slice(_diffuse(ridge), 0.5, supersampling=4, footprint="fit")
    nl, _ = texel_centres(WIDTH, HEIGHT)
    dense = (np.arange(400) + 0.5) / 400 - 0.5
    mean = ridge(np.clip(nl[:, None] + dense * 2.0 / (WIDTH - 1), -1.0, 1.0), 0.5).mean(axis=1)
    row = HEIGHT // 2
    assert np.sum((fitted[row, :, 0] - mean) ** 2) < 0.1 * np.sum((point[row, :, 0] - mean) ** 2)


def test_psnr_against_is_the_closed_form_and_its_se_shrinks_with_the_sample():
    """A constant error e under a reference of peak P gives 10 log10(P^2 / e^2) with SE 0; a noisy error's SE
    is the delta method's, within 10% of the spread over independent samples."""
    from atlasgen.models.physical_fit import cosine_pairs, psnr_against

    reference = np.zeros((1000, 3))
    reference[0] = 2.0
    db, se = psnr_against(reference, reference + 0.01)
    assert db == pytest.approx(10.0 * np.log10(4.0 / 1e-4), rel=1e-12) and se == pytest.approx(0.0, abs=1e-9)
    rng = np.random.default_rng(3)
    runs = [psnr_against(reference, reference + 0.01 * rng.standard_normal((1000, 3))) for _ in range(100)]
    spread = np.std([r[0] for r in runs])
    assert np.mean([r[1] for r in runs]) == pytest.approx(spread, rel=0.25)
    l, v = cosine_pairs(20000, 1)
    for d in (l, v):  # cosine-weighted: E[cos] = 2/3, unit vectors on the upper hemisphere
        assert np.allclose(np.linalg.norm(d, axis=1), 1.0) and (d[:, 2] >= 0).all()
        assert d[:, 2].mean() == pytest.approx(2.0 / 3.0, abs=0.01)
    below, _ = cosine_pairs(20000, 1, sphere=True)
    assert 0.45 < (below[:, 2] < 0).mean() < 0.55
