"""The GGX-prefiltered environment: its levels' roughness and size, constants, the closed form at
roughness 1, and the FFT-ordered sum against the plain brute-force sum over source texels."""

import doctest
from pathlib import Path

import numpy as np
import pytest

from atlasgen.optics.equirect import resample_equirect, sample_equirect, texel_directions, texel_solid_angles
from atlasgen.optics.microfacet import ggx_distribution
from atlasgen.optics.prefilter import filter_width, level_alpha, level_width, prefilter_ggx, sample_prefiltered
from atlasgen.optics.specular import specular_alpha

RNG = np.random.default_rng(3)
DOCS = Path(__file__).resolve().parents[2] / "docs" / "atlas-format.md"


def test_level_k_is_roughness_k_over_levels_minus_one_as_the_renderer_maps_gloss():
    for levels in (2, 4, 6):
        for k in range(levels):
            rough = k / (levels - 1)
            assert level_alpha(k, levels) == pytest.approx(float(specular_alpha(1.0 - rough)), rel=1e-15)
    assert level_alpha(0) == 0.002 and level_alpha(5) == 1.0


def test_levels_are_a_standard_mip_chain_of_the_source():
    # Level k is exactly (W >> k, H >> k), so the levels upload as one texture's mip chain.
    assert [level_width(256, k) for k in range(6)] == [256, 128, 64, 32, 16, 8]
    shapes = [lv.shape for lv in prefilter_ggx(np.ones((32, 64, 3)), 4)]
    assert shapes == [(32, 64, 3), (16, 32, 3), (8, 16, 3), (4, 8, 3)]
    assert [lv.shape[:2] for lv in prefilter_ggx(np.ones((128, 256, 3)), 6)] == [(128 >> k, 256 >> k) for k in range(6)]


def test_levels_are_filtered_no_finer_than_their_lobe_and_no_coarser_than_16_wide():
    widths = [filter_width(2048, k) for k in range(6)]
    assert widths == [2048, 256, 64, 32, 16, 16]
    assert all(b <= a for a, b in zip(widths, widths[1:]))


def test_an_image_that_makes_no_mip_chain_is_refused():
    for shape, levels in (((16, 32, 3), 6), ((30, 60, 3), 3), ((32, 48, 3), 2)):
        with pytest.raises(ValueError, match="mip chain"):
            prefilter_ggx(np.ones(shape), levels)


@pytest.mark.slow
def test_a_level_filtered_coarser_than_its_mip_is_the_filtered_one_resampled():
    # 1024 wide: level 1 (512 wide) is filtered at 256 wide from the source averaged to 512, then interpolated.
    big = resample_equirect(RNG.random((16, 32, 3)), 512, 1024)
    assert filter_width(1024, 1) == 256 == level_width(512, 1) == filter_width(512, 1)
    level = prefilter_ggx(big, 6)[1]
    assert level.shape == (256, 512, 3)
    small = prefilter_ggx(resample_equirect(big, 256, 512), 6)[1]
    np.testing.assert_allclose(level, resample_equirect(small, 256, 512), rtol=1e-5, atol=1e-6)


def test_a_constant_environment_stays_that_constant_at_every_level():
    for level in prefilter_ggx(np.full((64, 128, 3), [0.2, 1.5, 7.0]), 6):
        np.testing.assert_allclose(level, np.broadcast_to([0.2, 1.5, 7.0], level.shape), rtol=1e-6)
        assert level.dtype == np.float32


def test_level_zero_is_the_source_itself():
    img = RNG.random((16, 32, 3))
    np.testing.assert_array_equal(prefilter_ggx(img, 3)[0], img.astype(np.float32))


def test_the_fft_ordered_sum_is_the_brute_force_sum():
    img = RNG.random((32, 64, 3))
    levels = prefilter_ggx(img, 3)
    assert [filter_width(64, k, 3) for k in (1, 2)] == [level_width(64, k) for k in (1, 2)]  # not resampled
    src = texel_directions(32, 64).reshape(-1, 3)
    omega = texel_solid_angles(32, 64).ravel()
    for k in (1, 2):
        r = texel_directions(*levels[k].shape[:2]).reshape(-1, 3)
        h = r[:, None] + src[None]
        h /= np.linalg.norm(h, axis=-1, keepdims=True)
        kernel = ggx_distribution(np.sum(h * r[:, None], axis=-1), level_alpha(k, 3)) * np.maximum(r @ src.T, 0.0) * omega
        brute = kernel @ img.reshape(-1, 3) / kernel.sum(axis=1, keepdims=True)
        np.testing.assert_allclose(levels[k].reshape(-1, 3), brute, rtol=1e-6, atol=1e-7)


def test_roughness_one_spreads_a_bright_texel_into_the_normalised_lobe():
    # At alpha = 1, D = 1/pi everywhere, so int D max(r.l, 0) dl = 1 and a texel of power P Omega_0 at d0
    # gives Lpre(r) = P Omega_0 max(r.d0, 0) / pi.
    h, w = 64, 128
    img = np.zeros((h, w, 3))
    img[20, 37] = 500.0
    d0, omega = texel_directions(h, w)[20, 37], texel_solid_angles(h, w)[20, 37]
    rough = prefilter_ggx(img, 6)[5][..., 0]
    # Level 5 (4x2) is filtered at 16x8 and averaged down to its mip size.
    assert filter_width(w, 5) == 16 and rough.shape == (2, 4)
    at_filter = 500.0 * omega * np.maximum(texel_directions(8, 16) @ d0, 0.0) / np.pi
    expected = resample_equirect(at_filter[..., None], 2, 4)[..., 0]
    np.testing.assert_allclose(rough, expected, atol=2e-3 * expected.max())


def test_sampling_blends_the_two_nearest_levels():
    levels = [np.full((8, 16, 3), v, dtype=np.float32) for v in (1.0, 2.0, 4.0)]
    d = np.array([[0.0, 0.6, 0.8], [1.0, 0.0, 0.0]])
    np.testing.assert_allclose(sample_prefiltered(levels, d, [0.75, 1.5]), [[1.75] * 3, [3.0] * 3])
    np.testing.assert_allclose(sample_prefiltered(levels, d, 7.0), 4.0)
    np.testing.assert_allclose(sample_prefiltered(levels[:1] + levels[1:], d, 0.0), 1.0)
    img = RNG.random((8, 16, 3))
    np.testing.assert_allclose(sample_prefiltered([img, img], d, 0.3), sample_equirect(img, d))


def test_docs_give_the_levels_measured_roughness_and_sizes():
    text = " ".join(DOCS.read_text(encoding="utf-8").split())
    assert "(alpha " + ", ".join(f"{level_alpha(k):g}" for k in range(6)) + ")" in text
    sizes = ", ".join(f"{w}x{w // 2}" for w in (level_width(256, k) for k in range(6)))
    assert "filtered at " + ", ".join(str(filter_width(256, k)) for k in range(6)) + " wide" in text
    assert f"256x128 gives {sizes})" in text, sizes


def test_the_docstrings_examples_hold():
    from atlasgen.optics import prefilter

    assert doctest.testmod(prefilter).failed == 0
