"""The importance-sampled error estimator: unbiased within its standard error on sharp lobes,
and every reported figure within 10% of a converged estimate."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.separable.approximate import approximate_brdf, reference_values
from atlasgen.separable.error import (
    ERROR_SEED,
    SELECTION_SEED,
    errors_by_terms,
    measure_errors,
    mixture_weights,
    sample_error_pairs,
)
from atlasgen.separable.storage import quantize_factors
from tests.separable.separable_helpers import analytic

COPPER_F0 = (0.955, 0.638, 0.538)


def _gauss(n, lo, hi):
    x, w = np.polynomial.legendre.leggauss(n)
    return lo + (hi - lo) * (x + 1) / 2, w * (hi - lo) / 2


def dense_ratio(f, g, alpha, n_view=48, n_theta=160, n_phi=256):
    """int int |g - f|^2 / int int |f|^2 over (l, v) on the upper hemisphere, by a deterministic
    quadrature: v by Gauss-Legendre in cos(theta_v) (phi_v integrates to 2 pi, both are isotropic),
    l as the reflection of v about h, with tan(theta_h) = alpha u / (1 - u), u Gauss-Legendre, and
    phi_h by the trapezoid rule: the nodes follow the lobe whatever v is. dw_l = 4 |v.h| dw_h."""
    mu, w_mu = _gauss(n_view, 0.0, 1.0)
    u, w_u = _gauss(n_theta, 0.0, 1.0)
    tan = alpha * u / (1.0 - u)
    theta = np.arctan(tan)
    dtheta = (alpha / (1.0 - u) ** 2) / (1.0 + tan**2)
    phi = (np.arange(n_phi) + 0.5) * 2.0 * np.pi / n_phi
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    wh = (w_u * dtheta * np.sin(theta))[:, None] * np.full(n_phi, 2.0 * np.pi / n_phi)[None, :]
    h = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1).reshape(-1, 3)
    wh = wh.reshape(-1)
    num = den = 0.0
    for m, wm in zip(mu, w_mu):
        v = np.array([np.sqrt(1.0 - m * m), 0.0, m])
        vh = h @ v
        l = 2.0 * vh[:, None] * h - v
        keep = (vh > 0.0) & (l[:, 2] > 0.0)
        lk, vk = l[keep], np.broadcast_to(v, (int(keep.sum()), 3))
        jac = wh[keep] * 4.0 * vh[keep]
        fv, gv = f(lk, vk), g(lk, vk)
        num += 2.0 * np.pi * wm * np.sum(jac * np.sum((gv - fv) ** 2, axis=1))
        den += 2.0 * np.pi * wm * np.sum(jac * np.sum(fv**2, axis=1))
    return num / den


def test_mixture_weights_are_bounded_and_average_to_one_over_the_uniform_measure():
    s = sample_error_pairs(200_000, 11, 0.05)
    assert s.weight.max() <= 2.0 + 1e-12 and s.weight.min() >= 0.0
    # E[w] = int p_uniform over the upper hemisphere = 1 (l below the horizon has w = 0).
    assert np.mean(s.weight) == pytest.approx(1.0, abs=5 * np.std(s.weight) / np.sqrt(s.count))
    # Uniform pairs only: w = 1, the old estimator.
    assert np.all(sample_error_pairs(1000, 3, None).weight == 1.0)
    assert np.array_equal(mixture_weights(s.l, s.v, 0.05), s.weight)


@pytest.fixture(scope="module")
def sharp_copper():
    """GGX alpha 0.05 copper, its approximation a GGX alpha 0.06 (isotropic, so the quadrature
    can use it), and the quadrature's relative RMS, converged to 0.1% (checked against a finer one)."""
    f_src = analytic("ggx", alpha=0.05, f0=COPPER_F0)
    g_src = analytic("ggx", alpha=0.06, f0=COPPER_F0)
    exact = np.sqrt(dense_ratio(f_src.f_cos, g_src.f_cos, 0.05))
    return f_src, g_src, exact


@pytest.mark.slow
def test_the_quadrature_is_converged(sharp_copper):
    f_src, g_src, exact = sharp_copper
    finer = np.sqrt(dense_ratio(f_src.f_cos, g_src.f_cos, 0.05, n_view=96, n_theta=240, n_phi=384))
    assert finer == pytest.approx(exact, rel=1e-3)


@pytest.mark.slow
def test_the_estimator_is_unbiased_within_its_standard_error_across_seeds(sharp_copper):
    f_src, g_src, exact = sharp_copper
    z = []
    for seed in range(20):
        s = sample_error_pairs(20_000, 1000 + seed, 0.05)
        got = measure_errors(f_src.f_cos(s.l, s.v), g_src.f_cos(s.l, s.v), s.weight)
        z.append((got["relative_rms"] - exact) / got["relative_rms_se"])
    z = np.asarray(z)
    # 20 z-scores: mean ~ N(0, 1/20), std ~ 1; loose bounds (about 3 sigma).
    assert abs(z.mean()) < 0.7, z
    assert 0.6 < z.std(ddof=1) < 1.5, z


@pytest.mark.slow
def test_uniform_pairs_miss_the_lobe_the_estimator_sees(sharp_copper):
    """The old estimator (10^5 uniform pairs) on an alpha 0.02 lobe is off by far more than the
    new one's reported uncertainty."""
    f_src = analytic("ggx", alpha=0.02, f0=COPPER_F0)
    g_src = analytic("ggx", alpha=0.024, f0=COPPER_F0)
    exact = np.sqrt(dense_ratio(f_src.f_cos, g_src.f_cos, 0.02))
    s = sample_error_pairs(100_000, ERROR_SEED, 0.02)
    got = measure_errors(f_src.f_cos(s.l, s.v), g_src.f_cos(s.l, s.v), s.weight)
    assert abs(got["relative_rms"] - exact) < 3 * got["relative_rms_se"] and got["relative_rms_se"] < 0.03 * exact
    u = sample_error_pairs(100_000, ERROR_SEED, None)
    uniform = measure_errors(f_src.f_cos(u.l, u.v), g_src.f_cos(u.l, u.v), u.weight)
    assert uniform["relative_rms_se"] > 5 * got["relative_rms_se"]


#: Glossy conductors (alpha 0.02 - 0.1) and rough plastics.
CONVERGED_CASES = {
    "ggx-0.02-copper": dict(source="ggx", alpha=0.02, f0=COPPER_F0),
    "ggx-0.05-copper": dict(source="ggx", alpha=0.05, f0=COPPER_F0),
    "beckmann-0.08-copper": dict(source="beckmann", alpha=0.08, f0=COPPER_F0),
    "ggx-0.1-silver": dict(source="ggx", alpha=0.1, f0=(0.972, 0.960, 0.915)),
    "plastic-ggx-0.1": dict(source="ggx", alpha=0.1, fresnel="exact", ior=1.5, diffuse=(0.5, 0.04, 0.03)),
    "plastic-ggx-0.3": dict(source="ggx", alpha=0.3, fresnel="exact", ior=1.5, diffuse=(0.2, 0.3, 0.6)),
}


def _converged_sample(src, lobe_alpha):
    """400 000 pairs independent of both bake samples, and the source's f cos at them: one for every
    target and storage of a case (they depend on neither)."""
    s = sample_error_pairs(400_000, 99, lobe_alpha)
    ref, _ = reference_values(src, s)
    return s, ref


def _converged(factors, sample, quantized):
    s, ref = sample
    judged = quantize_factors(factors) if quantized else factors
    return errors_by_terms(judged, ref, s.l, s.v, log=not quantized, weight=s.weight)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(CONVERGED_CASES))
def test_every_reported_figure_agrees_with_a_converged_estimate(name):
    params = dict(CONVERGED_CASES[name])
    src = analytic(params.pop("source"), **params)
    result = approximate_brdf(src, max_error=0.02, grids=(16, 32))
    assert (result.selection.seed, result.report.seed) == (SELECTION_SEED, ERROR_SEED)
    chosen = {c["target"]: c for c in result.candidates if c["grid"] == result.grid}
    sample = _converged_sample(src, result.report.lobe_alpha)
    for target, reported in result.errors_by_terms.items():
        factors = _full_factors(src, result, target)
        for quantized, figures in ((False, reported), (True, result.errors_8bit_by_terms[target])):
            converged = _converged(factors, sample, quantized)
            for mine, truth in zip(figures, converged):
                for key in ("relative_rms", "log_error"):
                    if key in mine:
                        print(name, target, "8bit" if quantized else "float", mine["terms"], key, mine[key], truth[key])
                        assert abs(mine[key] - truth[key]) <= 0.1 * mine[key], (name, target, quantized, mine, truth)
    assert chosen


def _full_factors(src, result, target):
    """The chosen grid's factors for ``target`` with every K (the result keeps only the chosen K)."""
    again = approximate_brdf(src, terms=max(e["terms"] for e in result.errors_by_terms[target]), target=target,
                             grids=(result.grid,), measure_8bit=False)  # fmt: skip
    return again.factors


@pytest.mark.parametrize("alpha", [None, 0.05, 0.3])
@pytest.mark.slow
def test_sphere_pairs_integrate_closed_forms_without_bias(alpha):
    """With l over the whole sphere, mean(w g) = (1/(4 pi)) (1/(2 pi)) int_sphere int_hemisphere g:
    1 for g = 1, 1/4 for g = |cos theta_l| below the surface, 1/(2(n+1)) for the cosine lobes
    max(l.r, 0)^n about the mirror direction r and max(-l.v, 0)^n about -v (a transmission lobe),
    each within 4 SE. The lobe density of an l drawn below the surface (v.h < 0) must be counted."""
    s = sample_error_pairs(400_000, 5, alpha, sphere=True)
    l, v, w = s.l, s.v, s.weight
    assert s.sphere and s.estimator.endswith("-sphere") and abs((l[:, 2] < 0).mean() - 0.5) < 0.005
    r = v * np.array([-1.0, -1.0, 1.0])
    n = 200
    cases = [
        (np.ones(len(w)), 1.0),
        (np.where(l[:, 2] < 0, -l[:, 2], 0.0), 0.25),
        (np.maximum((l * r).sum(1), 0.0) ** n, 0.5 / (n + 1)),
        (np.maximum(-(l * v).sum(1), 0.0) ** n, 0.5 / (n + 1)),
    ]
    for g, exact in cases:
        x = w * g
        se = x.std() / np.sqrt(len(x))
        assert abs(x.mean() - exact) <= 4.0 * se + 1e-12, (alpha, exact, x.mean(), se)


def test_sphere_pairs_leave_the_hemisphere_sample_unchanged():
    """The mirror draws come after the hemisphere's: the reported figures of reflecting materials do not move."""
    a, b = sample_error_pairs(1000, 3, 0.1), sample_error_pairs(1000, 3, 0.1, sphere=True)
    np.testing.assert_array_equal(np.abs(a.l), np.abs(b.l))
    np.testing.assert_array_equal(a.v, b.v)
    assert not a.sphere and a.estimator == "defensive-ggx-mixture"
