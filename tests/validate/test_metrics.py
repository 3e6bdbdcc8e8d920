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
