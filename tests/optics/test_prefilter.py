"""The GGX-prefiltered environment: its levels' roughness and size, constants, the closed form at
roughness 1, and the FFT-ordered sum against the plain brute-force sum over source texels."""

import doctest
from pathlib import Path

import numpy as np
import pytest

from atlasgen.optics.equirect import sample_equirect, texel_directions, texel_solid_angles
from atlasgen.optics.microfacet import ggx_distribution
from atlasgen.optics.prefilter import MIN_LEVEL_WIDTH, level_alpha, level_width, prefilter_ggx, sample_prefiltered
from atlasgen.optics.specular import specular_alpha

RNG = np.random.default_rng(3)
DOCS = Path(__file__).resolve().parents[2] / "docs" / "atlas-format.md"


def test_level_k_is_roughness_k_over_levels_minus_one_as_the_renderer_maps_gloss():
    for levels in (2, 4, 6):
        for k in range(levels):
            rough = k / (levels - 1)
            assert level_alpha(k, levels) == pytest.approx(float(specular_alpha(1.0 - rough)), rel=1e-15)
    assert level_alpha(0) == 0.002 and level_alpha(5) == 1.0


def test_levels_halve_as_they_roughen_and_stop_at_16x8():
    widths = [level_width(256, k) for k in range(6)]
    assert widths[0] == 256 and all(b <= a for a, b in zip(widths, widths[1:])) and min(widths) == MIN_LEVEL_WIDTH
    shapes = [lv.shape for lv in prefilter_ggx(np.ones((32, 64, 3)), 4)]
    assert shapes == [(32, 64, 3), (16, 32, 3), (8, 16, 3), (8, 16, 3)]


def test_a_constant_environment_stays_that_constant_at_every_level():
    for level in prefilter_ggx(np.full((32, 64, 3), [0.2, 1.5, 7.0]), 6):
        np.testing.assert_allclose(level, np.broadcast_to([0.2, 1.5, 7.0], level.shape), rtol=1e-6)
        assert level.dtype == np.float32


def test_level_zero_is_the_source_itself():
    img = RNG.random((16, 32, 3))
    np.testing.assert_array_equal(prefilter_ggx(img, 3)[0], img.astype(np.float32))


def test_the_fft_ordered_sum_is_the_brute_force_sum():
    img = RNG.random((16, 32, 3))
    levels = prefilter_ggx(img, 3)
    src = texel_directions(16, 32).reshape(-1, 3)
    omega = texel_solid_angles(16, 32).ravel()
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
    expected = 500.0 * omega * np.maximum(texel_directions(*rough.shape) @ d0, 0.0) / np.pi
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
    assert f"256x128 gives {sizes})" in text, sizes


def test_the_docstrings_examples_hold():
    from atlasgen.optics import prefilter

    assert doctest.testmod(prefilter).failed == 0
