"""Error measures: the fixed hemisphere pairs, relative RMS and the Löw 2012 log error."""

import numpy as np
import pytest

from atlasgen.separable.error import ERROR_PAIRS, log_error, measure_errors, relative_rms, sample_hemisphere_pairs


def test_pairs_are_uniform_on_the_hemisphere_and_fixed():
    l, v = sample_hemisphere_pairs()
    assert l.shape == v.shape == (ERROR_PAIRS, 3) and ERROR_PAIRS >= 100_000
    for d in (l, v):
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
        assert d[:, 2].min() >= 0.0
        # Uniform in solid angle: z is uniform on [0, 1], so E[z] = 1/2, E[z^2] = 1/3;
        # the azimuth is uniform, so E[x] = E[y] = 0. Tolerances are ~5 standard errors.
        assert d[:, 2].mean() == pytest.approx(0.5, abs=5 * 0.29 / np.sqrt(ERROR_PAIRS))
        assert (d[:, 2] ** 2).mean() == pytest.approx(1 / 3, abs=5 * 0.3 / np.sqrt(ERROR_PAIRS))
        assert abs(d[:, 0].mean()) < 5 * 0.5 / np.sqrt(ERROR_PAIRS)
    # l and v are independent.
    assert abs(np.corrcoef(l[:, 2], v[:, 2])[0, 1]) < 0.02
    l2, v2 = sample_hemisphere_pairs()
    np.testing.assert_array_equal(l, l2)
    np.testing.assert_array_equal(v, v2)


def test_relative_rms_closed_forms():
    rng = np.random.default_rng(0)
    ref = rng.random((1000, 3))
    assert relative_rms(ref, ref) == 0.0
    assert relative_rms(ref, 1.03 * ref) == pytest.approx(0.03)
    assert relative_rms(ref, np.zeros_like(ref)) == pytest.approx(1.0)
    # All-zero reference: no division by zero.
    zero = np.zeros((10, 3))
    assert relative_rms(zero, zero) == 0.0
    assert relative_rms(zero, np.full((10, 3), 0.5)) == pytest.approx(0.5)


def test_log_error_closed_forms():
    ref = np.zeros((100, 3))
    assert log_error(ref, ref) == 0.0
    assert log_error(ref, np.full_like(ref, np.e - 1.0)) == pytest.approx(1.0)
    # Negative approximations are clamped to 0 first, as the shader clamps.
    assert log_error(ref, np.full_like(ref, -5.0)) == 0.0
    out = measure_errors(np.ones((4, 3)), np.full((4, 3), 1.5))
    # A constant error has no spread: both standard errors are 0.
    assert out == {
        "relative_rms": 0.5,
        "relative_rms_se": 0.0,
        "log_error": pytest.approx(np.log(2.5) - np.log(2.0), rel=1e-5),
        "log_error_se": 0.0,
    }


def test_relative_log_rms_closed_forms_and_its_by_terms_twin():
    from atlasgen.separable.error import errors_by_terms, relative_log_errors
    from atlasgen.separable.factorize import Factors
    from atlasgen.separable.rebuild import evaluate_factors

    rng = np.random.default_rng(3)
    ref = rng.random((2000, 3)) * 5.0
    assert relative_log_errors(ref, ref)["relative_log_rms"] == 0.0
    # ln(1 + a) = (1 + c) ln(1 + f) everywhere: the relative log RMS is |c| exactly, the SE 0.
    c = 0.07
    scaled = np.expm1((1.0 + c) * np.log1p(ref))
    e = relative_log_errors(ref, scaled)
    assert e["relative_log_rms"] == pytest.approx(c, rel=1e-5) and e["relative_log_rms_se"] == pytest.approx(0.0, abs=1e-6)
    # Negative approximations count as 0, as the shader clamps them: then every log is lost.
    assert relative_log_errors(ref, -ref)["relative_log_rms"] == pytest.approx(1.0)
    # errors_by_terms computes it from running sums over terms: the same figure as from the rebuilt values.
    l, v = sample_hemisphere_pairs(4000, seed=5)
    factors = Factors(rng.random((3, 3, 32)), rng.random((3, 3, 32, 32)), "half_diff", np.zeros((3, 3)))
    reference = 0.8 * evaluate_factors(factors, None, l, v, cosine=True)
    by_terms = errors_by_terms(factors, reference, l, v, log=False, relative_log=True)
    for entry in by_terms:
        k = entry["terms"]
        direct = relative_log_errors(reference, evaluate_factors(factors.truncated(k), None, l, v, cosine=True))
        assert entry["relative_log_rms"] == pytest.approx(direct["relative_log_rms"], rel=1e-5)
        assert entry["relative_log_rms_se"] == pytest.approx(direct["relative_log_rms_se"], rel=1e-2)
    # Without the flag the figures are those the manifests have always held.
    assert "relative_log_rms" not in errors_by_terms(factors, reference, l, v, log=False)[0]
