"""Metrics: closed forms for RMSE and PSNR, FLIP's basics, on the display image (tests/optics/test_display.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.optics.display import display_clip
from atlasgen.validate.metrics import compare_images, flip, psnr, relative_rms, rmse


@given(st.floats(1e-4, 0.5), st.integers(1, 8), st.integers(1, 8))
def test_psnr_of_a_constant_offset_is_minus_20_log10_of_it(d, h, w):
    a = np.full((h, w, 3), 0.25)
    assert rmse(a, a + d) == pytest.approx(d, rel=1e-12)
    assert psnr(a, a + d) == pytest.approx(-20.0 * math.log10(d), rel=1e-9)


def test_psnr_of_identical_images_is_infinite_and_shapes_must_match():
    a = np.random.default_rng(1).random((4, 5, 3))
    assert psnr(a, a) == math.inf
    with pytest.raises(ValueError, match="shapes differ"):
        rmse(a, a[:, :4])


def test_flip_is_zero_for_identical_images_and_grows_with_the_error():
    rng = np.random.default_rng(7)
    ref = rng.uniform(0.2, 0.8, (32, 32, 3))
    same_map, same = flip(ref, ref)
    assert same_map.shape == (32, 32)
    assert same == pytest.approx(0.0, abs=1e-7)
    small = flip(ref, np.clip(ref + 0.01, 0, 1))[1]
    large = flip(ref, np.clip(ref + 0.1, 0, 1))[1]
    assert 0.0 < small < large <= 1.0


@pytest.mark.slow
@settings(max_examples=10, deadline=None)
@given(st.floats(0.001, 0.2))
def test_compare_images_measures_the_tone_mapped_pair(offset):
    rng = np.random.default_rng(3)
    ref = rng.uniform(0.0, 0.8, (16, 16, 3))
    test = ref + offset
    m = compare_images(ref, test, exposure=1.0)
    assert m.rmse == pytest.approx(rmse(display_clip(ref), display_clip(test)))
    assert m.linear_rmse == pytest.approx(offset, abs=1e-12)
    assert m.flip_map.shape == (16, 16)
    assert 0.0 < m.flip < 1.0


@given(st.floats(0.0, 2.0))
def test_relative_rms_of_a_scaled_image_is_the_scale_error(k):
    ref = np.random.default_rng(2).uniform(0.0, 1.0, (6, 7, 3))
    assert relative_rms(ref, ref * k) == pytest.approx(abs(1.0 - k), abs=1e-12)
    assert relative_rms(np.zeros((2, 2, 3)), np.zeros((2, 2, 3))) == 0.0


def test_masked_pixels_are_left_out_of_every_figure():
    from atlasgen.validate.metrics import compare_images, noise_floor

    rng = np.random.default_rng(2)
    a = rng.uniform(0.1, 0.6, size=(24, 32, 3)).astype(np.float32)
    b = a.copy()
    mask = np.zeros((24, 32), dtype=bool)
    mask[4:9, 10:20] = True
    b[mask] += 0.3  # differs only where masked
    whole, masked = compare_images(a, b), compare_images(a, b, mask=mask)
    assert np.isfinite(whole.psnr) and whole.flip > 0
    assert masked.psnr == np.inf and masked.rmse == 0.0 and masked.linear_relative_rms == 0.0
    assert masked.flip == pytest.approx(float(whole.flip_map[~mask].mean()))
    assert noise_floor(a, b, mask=mask) == np.inf and noise_floor(a, b) == pytest.approx(whole.psnr)


def _srgb(x):
    """The sRGB transfer function, written out again (IEC 61966-2-1), for closed forms."""
    x = np.asarray(x, dtype=np.float64)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.maximum(x, 0.0), 1.0 / 2.4) - 0.055)


@settings(max_examples=20, deadline=None)
@given(st.integers(1, 9), st.integers(1, 11), st.floats(0.01, 0.3))
def test_the_background_does_not_dilute_the_error_and_coverage_says_how_much_was_compared(rows, cols, d):
    """Black background in both images is exact: over the whole 12x12 frame the same error reads
    10 log10(1 / coverage) dB better than over the material's pixels."""
    ref = np.zeros((12, 12, 3))
    ref[:rows, :cols] = 0.2
    test = ref.copy()
    test[:rows, :cols] += d
    outside = np.ones((12, 12), dtype=bool)
    outside[:rows, :cols] = False
    masked, whole = compare_images(ref, test, mask=outside, with_flip=False), compare_images(ref, test, with_flip=False)
    coverage = rows * cols / 144
    assert masked.coverage == pytest.approx(coverage) and whole.coverage == 1.0
    assert masked.psnr == pytest.approx(-20.0 * math.log10(float(_srgb(0.2 + d) - _srgb(0.2))), rel=1e-9)
    assert whole.psnr == pytest.approx(masked.psnr + 10.0 * math.log10(1.0 / coverage), rel=1e-9)


def test_clipped_pixels_are_counted_and_measured_at_an_exposure_that_clips_nothing():
    """A reference of 2 and a test of 1.5 both clip at exposure 1 and look exact; at exposure 0.5
    (the reference's peak at 1) they differ by srgb(1) - srgb(0.75)."""
    from atlasgen.validate.metrics import unclipped_exposure

    ref = np.full((4, 5, 3), 2.0)
    ref[0, 0] = 0.5  # one pixel below clipping
    test = np.where(ref > 1.0, 1.5, ref)
    m = compare_images(ref, test, exposure=1.0, with_flip=False)
    assert m.psnr == math.inf and m.clipped_pixels == 19
    assert m.unclipped_exposure == pytest.approx(0.5) == unclipped_exposure(ref, 1.0)
    rms = math.sqrt(19 / 20) * float(_srgb(1.0) - _srgb(0.75))
    assert m.unclipped_psnr == pytest.approx(-20.0 * math.log10(rms), rel=1e-9)
    # Masked out, the clipped pixels neither count nor set the exposure.
    keep_one = np.ones((4, 5), dtype=bool)
    keep_one[0, 0] = False
    m = compare_images(ref, test, exposure=1.0, with_flip=False, mask=keep_one)
    assert m.clipped_pixels == 0 and m.unclipped_exposure == 1.0 and m.unclipped_psnr == math.inf
    as_json = compare_images(ref, test, with_flip=False).as_dict()
    assert as_json["clipped_pixels"] == 19 and as_json["unclipped_psnr_db"] == pytest.approx(-20.0 * math.log10(rms))


def test_regions_split_the_compared_pixels_with_their_own_figures():
    ref = np.full((6, 8, 3), 0.3)
    test = ref.copy()
    test[:2] += 0.1  # the error sits in the first two rows only
    outside = np.zeros((6, 8), dtype=bool)
    outside[5] = True
    grazing = np.zeros((6, 8), dtype=bool)
    grazing[:2] = True
    m = compare_images(ref, test, mask=outside, regions={"grazing": grazing, "rest": ~grazing})
    g, r = m.regions["grazing"], m.regions["rest"]
    assert g["pixels"] == 16 and r["pixels"] == 24  # the masked row is in neither
    assert g["coverage"] + r["coverage"] == pytest.approx(m.coverage)
    assert g["psnr_db"] == pytest.approx(-20.0 * math.log10(float(_srgb(0.4) - _srgb(0.3))), rel=1e-9)
    assert r["psnr_db"] is None and r["flip"] == pytest.approx(float(m.flip_map[2:5].mean()))
    assert g["flip"] == pytest.approx(float(m.flip_map[:2].mean()))
