"""Error of a separable approximation over the (l, v) domain, estimated by importance sampling.

Every figure is a ratio of two integrals over pairs of directions on the upper hemisphere
(n = +z), for example the relative RMS

    e^2 = int int |f^ cos - f cos|^2 dw_l dw_v / int int |f cos|^2 dw_l dw_v.

A glossy lobe puts nearly all of the denominator in a sliver of that domain, where pairs
drawn uniformly rarely land (a Beckmann alpha 0.08 copper: 9 of 10^5 uniform pairs carry
half of it). So the pairs are drawn from a *defensive mixture* (Hesterberg 1995; Owen &
Zhou 2000): v uniform in solid angle, and l, with probability 1/2 uniform in solid angle,
else reflected about a half vector drawn from a GGX distribution of normals with one of
two roughnesses taken from the lobe (0.7 alpha, which matches the core of D^2, and
2 alpha, for the tails), the way a renderer samples a microfacet lobe (Walter et al.
2007, sec. 5.3). Each pair carries the weight w = p_uniform / p_mixture <= 2,
so sums of w g estimate the uniform-measure integrals without bias, and the variance is
never more than twice that of uniform sampling. The ratio's standard error is the delta
method's (Owen, "Monte Carlo theory, methods and examples", 2013, sec. 9.2), the same
formula as a self-normalised importance sampler's.

A reference that transmits (a thin sheet, a back-lit film: f cos > 0 for l below the
surface) is measured with l over the *whole sphere* (``sphere=True``): each pair of the
mixture above has its l mirrored through the tangent plane with probability 1/2, so uniform
l covers the lower hemisphere uniformly and a reflection lobe's mirror image lies around -v,
where a transmission lobe peaks. The weight is then p_uniform / p_sample with p_uniform
uniform over the sphere for l (see :func:`mixture_weights`); the integrals are over l in the
sphere, which for a reflection-only f are the hemisphere's.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from atlasgen.separable.parametrization import get_parametrization
from atlasgen.separable.rebuild import cached_on_pairs, sample_factors
from atlasgen.separable.source import lobe_alpha

__all__ = [
    "ERROR_PAIRS",
    "ERROR_SEED",
    "SELECTION_SEED",
    "ESTIMATOR",
    "SPHERE_SUFFIX",
    "MET_SIGMAS",
    "LOBE_SCALES",
    "ErrorSample",
    "sample_error_pairs",
    "error_sample_for",
    "sample_hemisphere_pairs",
    "relative_rms",
    "log_error",
    "relative_log_errors",
    "weighted_errors",
    "measure_errors",
    "errors_by_terms",
    "upper_bound",
    "mixture_weights",
]

#: Number of (l, v) pairs in each sample: the one that chooses and the one that reports.
ERROR_PAIRS = 100_000
#: The seed of the sample every reported figure is measured on.
ERROR_SEED = 20260101
#: The seed of the independent sample K, the grid and the target are chosen on.
SELECTION_SEED = 20260102
#: The estimator's name, as the manifest records it.
ESTIMATOR = "defensive-ggx-mixture"
#: A budget is met when the estimate plus this many standard errors is within it.
MET_SIGMAS = 2.0
#: The GGX sampling lobes' roughnesses, in units of the lobe's alpha.
LOBE_SCALES = (0.7, 2.0)
#: Share of pairs whose l is uniform (the defensive part of the mixture).
UNIFORM_SHARE = 0.5
#: Appended to the estimator's name when l covers the whole sphere.
SPHERE_SUFFIX = "-sphere"


@dataclass(frozen=True, eq=False)
class ErrorSample:
    """(l, v) pairs with their importance weights w = p_uniform(l, v) / p_sample(l, v).

    ``l`` and ``v`` are ``(N, 3)`` unit vectors (l may lie below the horizon, where every
    integrand is 0); the arrays are read-only, so per-pair quantities computed from them can
    be cached (:func:`atlasgen.separable.rebuild.cached_on_pairs`). ``lobe_alpha`` is the
    width the lobe components were drawn with (None: uniform pairs only).
    """

    l: np.ndarray
    v: np.ndarray
    weight: np.ndarray
    seed: int
    lobe_alpha: float | None
    estimator: str
    #: l drawn over the whole sphere (transmission counted), not the upper hemisphere.
    sphere: bool = False

    @property
    def count(self) -> int:
        return int(self.l.shape[0])

    @property
    def pairs(self):
        return self.l, self.v


def _uniform_hemisphere(rng, count):
    # z = xi_1, phi = 2 pi xi_2 (Archimedes' hat-box theorem; PBRT 3rd ed., sec. 13.6.1).
    z = rng.random(count)
    phi = 2.0 * np.pi * rng.random(count)
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def _ggx_pdf_h(cos_h, alpha):
    """GGX's D(h) cos(theta_h) (Walter et al. 2007, eq. 33): a density of h per steradian."""
    c2 = np.clip(cos_h, 0.0, 1.0) ** 2
    a2 = alpha * alpha
    denom = np.pi * (c2 * (a2 - 1.0) + 1.0) ** 2
    return np.where(cos_h > 0.0, a2 * np.sqrt(c2) / np.maximum(denom, 1e-300), 0.0)


def _sample_reflected(rng, v, alpha):
    """l = reflect(v, h) with h drawn from GGX's D(h) cos(theta_h): tan^2 theta_h = alpha^2 xi / (1 - xi),
    phi_h = 2 pi xi_2 (Walter et al. 2007, eqs. 35-36)."""
    xi = rng.random(v.shape[0])
    phi = 2.0 * np.pi * rng.random(v.shape[0])
    tan2 = alpha * alpha * xi / np.maximum(1.0 - xi, 1e-300)
    cos_h = 1.0 / np.sqrt(1.0 + tan2)
    sin_h = np.sqrt(np.maximum(1.0 - cos_h * cos_h, 0.0))
    h = np.stack([sin_h * np.cos(phi), sin_h * np.sin(phi), cos_h], axis=-1)
    return 2.0 * np.sum(v * h, axis=-1, keepdims=True) * h - v


def _reflected_pdf(l, v, alpha):
    """Density of l = reflect(v, h) per steradian: D(h) cos(theta_h) / (4 |v.h|), h = (l + v) / |l + v|
    (Walter et al. 2007, eq. 14)."""
    h = l + v
    length = np.linalg.norm(h, axis=-1)
    # Reflection about h and about -h give the same l, and h is drawn on the upper side:
    # l + v points down when v.h < 0 (l then lies below the surface), so the h that made l
    # is the upper one of +-(l + v) / |l + v|. Above the surface (l + v).z > 0: unchanged.
    h = h * np.where(h[:, 2] < 0.0, -1.0, 1.0)[:, None] / np.maximum(length, 1e-300)[:, None]
    vh = np.abs(np.sum(v * h, axis=-1))
    return np.where(length > 1e-12, _ggx_pdf_h(h[:, 2], alpha) / np.maximum(4.0 * vh, 1e-300), 0.0)


def _lobe_alphas(lobe_alpha: float) -> np.ndarray:
    return np.clip(np.asarray(LOBE_SCALES) * lobe_alpha, 1e-4, 4.0)


def mixture_weights(l, v, lobe_alpha: float | None, sphere: bool = False) -> np.ndarray:
    """w = p_uniform / p_mixture for pairs (l, v); 0 where l is below the horizon (``sphere=False``).

    p_mixture(l | v) = UNIFORM_SHARE / (2 pi) + sum_j s_j p_j(l | v), p_j the density of
    l reflected about a GGX normal of roughness LOBE_SCALES[j] * lobe_alpha, the lobe
    shares s_j splitting 1 - UNIFORM_SHARE equally; v is uniform in both parts.

    ``sphere=True``: l is that mixture's draw q mirrored through the surface with probability
    1/2, so p(l) = (q(l) + q(l'))/2, l' = (l_x, l_y, -l_z), against p_uniform = 1/(4 pi):

        w = 1 / (UNIFORM_SHARE + 2 pi sum_j s_j (p_j(l) + p_j(l'))),

    (q's uniform part is 1/(2 pi) on exactly one of l, l'); w = 1 without lobes.
    """
    if sphere:
        if lobe_alpha is None:
            return np.ones(l.shape[0])
        mirrored = l * np.array([1.0, 1.0, -1.0])
        alphas = _lobe_alphas(lobe_alpha)
        share = (1.0 - UNIFORM_SHARE) / len(alphas)
        lobe = sum(share * (_reflected_pdf(l, v, a) + _reflected_pdf(mirrored, v, a)) for a in alphas)
        return 1.0 / (UNIFORM_SHARE + 2.0 * np.pi * lobe)
    above = l[:, 2] > 0.0
    if lobe_alpha is None:
        return above.astype(np.float64)
    alphas = _lobe_alphas(lobe_alpha)
    share = (1.0 - UNIFORM_SHARE) / len(alphas)
    lobe = sum(share * _reflected_pdf(l, v, a) for a in alphas)
    return np.where(above, 1.0 / (UNIFORM_SHARE + 2.0 * np.pi * lobe), 0.0)


@lru_cache(maxsize=16)
def sample_error_pairs(
    count: int = ERROR_PAIRS, seed: int = ERROR_SEED, lobe_alpha: float | None = None, sphere: bool = False
) -> ErrorSample:
    """``count`` i.i.d. pairs from the defensive mixture (see the module docstring).

    v is uniform in solid angle on the upper hemisphere; l is uniform too with probability
    UNIFORM_SHARE, else drawn around the mirror direction of v from one of the GGX lobes.
    ``lobe_alpha = None`` draws uniform pairs only (w = 1). ``sphere=True`` then mirrors
    each l through the surface with probability 1/2 (the pairs' other draws are unchanged),
    for references that transmit. numpy's PCG64 with ``seed``: the same arguments give the
    same pairs.
    """
    rng = np.random.default_rng(seed)
    v = _uniform_hemisphere(rng, count)
    l = _uniform_hemisphere(rng, count)
    if lobe_alpha is not None:
        alphas = _lobe_alphas(lobe_alpha)
        # Component per pair: uniform below UNIFORM_SHARE, else lobe j of equal shares.
        u = rng.random(count)
        lobe = np.minimum(((u - UNIFORM_SHARE) / (1.0 - UNIFORM_SHARE) * len(alphas)).astype(int), len(alphas) - 1)
        for j, alpha in enumerate(alphas):
            pick = (u >= UNIFORM_SHARE) & (lobe == j)
            l[pick] = _sample_reflected(rng, v[pick], alpha)
        l /= np.linalg.norm(l, axis=-1, keepdims=True)
    if sphere:  # drawn after the hemisphere's pairs, which stay as they were
        l[rng.random(count) < 0.5, 2] *= -1.0
    weight = mixture_weights(l, v, lobe_alpha, sphere)
    for a in (l, v, weight):
        a.flags.writeable = False  # shared by every candidate's error measurement
    name = (ESTIMATOR if lobe_alpha is not None else "uniform") + (SPHERE_SUFFIX if sphere else "")
    return ErrorSample(l, v, weight, int(seed), None if lobe_alpha is None else float(lobe_alpha), name, bool(sphere))


def error_sample_for(source, seed: int = ERROR_SEED, count: int = ERROR_PAIRS, sphere: bool = False) -> ErrorSample:
    """The error sample for one BRDF source: lobes as wide as its :func:`lobe_alpha`; l over the
    whole sphere with ``sphere`` (a source that transmits)."""
    alpha = lobe_alpha(source)
    return sample_error_pairs(count, seed, None if alpha is None else float(f"{alpha:.6g}"), bool(sphere))


def sample_hemisphere_pairs(count: int = ERROR_PAIRS, seed: int = ERROR_SEED):
    """``count`` independent (l, v) pairs, each uniform in solid angle on the upper hemisphere.

    z = xi_1, phi = 2 pi xi_2 (Archimedes' hat-box theorem; PBRT 3rd ed., sec. 13.6.1),
    from numpy's PCG64 with a fixed seed. Returns read-only unit vectors ``(count, 3)``
    with n = +z. (Uniform pairs miss glossy lobes: the reported errors use
    :func:`sample_error_pairs`.)
    """
    rng = np.random.default_rng(seed)
    xi = rng.random((2, 2, count))
    out = []
    for k in range(2):
        z = xi[k, 0]
        phi = 2.0 * np.pi * xi[k, 1]
        r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
        d = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)
        d.flags.writeable = False
        out.append(d)
    return out[0], out[1]


def _round(x: float, digits: int = 6) -> float:
    return float(f"{x:.{digits}g}")


def _sqrt_with_se(ratio: np.ndarray, ratio_se: np.ndarray):
    """sqrt(R) and its delta-method SE, SE(R) / (2 sqrt(R)); 0 where R is 0."""
    root = np.sqrt(np.maximum(ratio, 0.0))
    return root, np.where(root > 0.0, ratio_se / np.maximum(2.0 * root, 1e-300), 0.0)


def _relative_rms_with_se(squared_error: np.ndarray, squared_reference: np.ndarray, channels: int):
    """Relative RMS and its standard error from per-pair weighted sums over channels.

    ``squared_error`` is ``(..., N)``: w_i sum_c (f^ - f)^2, ``squared_reference`` ``(N,)``:
    w_i sum_c f^2. R = sum a / sum b; its delta-method variance is sum (a - R b)^2 / (sum b)^2
    (Owen 2013, eq. 9.9). An all-zero reference gives the absolute RMS and the SE of its mean.
    """
    count = squared_error.shape[-1]
    norm = float(np.sum(squared_reference))
    if norm == 0.0:
        mean = np.mean(squared_error, axis=-1) / channels
        se = np.std(squared_error, axis=-1) / channels / np.sqrt(max(count, 1))
        return _sqrt_with_se(mean, se)
    ratio = np.sum(squared_error, axis=-1) / norm
    residual = squared_error - ratio[..., None] * squared_reference
    se = np.sqrt(np.sum(residual**2, axis=-1)) / norm
    return _sqrt_with_se(ratio, se)


def _mean_sqrt_with_se(values: np.ndarray):
    """sqrt(mean x) over the last axis and its SE (the mean's, through the delta method)."""
    count = values.shape[-1]
    mean = np.mean(values, axis=-1)
    return _sqrt_with_se(mean, np.std(values, axis=-1) / np.sqrt(max(count, 1)))


def _weights_or_ones(weight, count):
    return np.ones(count) if weight is None else np.asarray(weight, dtype=np.float64).reshape(count)


def relative_rms(reference: np.ndarray, approx: np.ndarray, weight=None) -> float:
    """sqrt(sum w (approx - ref)^2 / sum w ref^2) over all pairs and channels.

    The values are f cos(theta_l), ``(N, 3)``; ``weight`` (default 1) is each pair's
    importance weight (:class:`ErrorSample`). When the reference is zero everywhere the
    absolute RMS is returned (there is nothing to be relative to).
    """
    return weighted_errors(reference, approx, weight, log=False)["relative_rms"]


def log_error(reference: np.ndarray, approx: np.ndarray, weight=None) -> float:
    """Löw et al. 2012 log error: sqrt(mean w (ln(1 + f cos) - ln(1 + f^ cos))^2).

    Löw et al. (2012, eq. 11) weight by sin(theta_i) on a grid uniform in angle; that
    weight is the solid-angle Jacobian, which pairs drawn uniformly in solid angle
    already carry, and w carries for importance-sampled ones. Negative approximations
    are clamped at 0, as the shader does.
    """
    a = np.log1p(np.maximum(approx, 0.0))
    r = np.log1p(np.maximum(reference, 0.0))
    w = _weights_or_ones(weight, np.shape(reference)[0])
    return float(np.sqrt(np.mean(w[:, None] * (a - r) ** 2)))


def weighted_errors(reference: np.ndarray, approx: np.ndarray, weight=None, log: bool = True) -> dict:
    """Relative RMS and log error with their standard errors, unrounded.

    Keys: ``relative_rms``, ``relative_rms_se``, and with ``log`` ``log_error``, ``log_error_se``.
    """
    reference = np.asarray(reference, dtype=np.float64).reshape(-1, 3)
    approx = np.asarray(approx, dtype=np.float64).reshape(-1, 3)
    w = _weights_or_ones(weight, reference.shape[0])
    rel, rel_se = _relative_rms_with_se(w * np.sum((approx - reference) ** 2, axis=1), w * np.sum(reference**2, axis=1), 3)
    out = {"relative_rms": float(rel), "relative_rms_se": float(rel_se)}
    if log:
        diff = np.log1p(np.maximum(approx, 0.0)) - np.log1p(np.maximum(reference, 0.0))
        g, g_se = _mean_sqrt_with_se(w * np.mean(diff**2, axis=1))
        out.update(log_error=float(g), log_error_se=float(g_se))
    return out


def relative_log_errors(reference: np.ndarray, approx: np.ndarray, weight=None) -> dict:
    """The relative log RMS and its standard error, rounded (``relative_log_rms``, ``relative_log_rms_se``):

        e_log^2 = sum w |ln(1 + f^ cos) - ln(1 + f cos)|^2 / sum w |ln(1 + f cos)|^2,

    over pairs and channels, negative approximations clamped at 0 as the shader does. The
    logarithm (Löw et al. 2012, eq. 11) weighs a dim tail's relative error as a display
    does and a peak's as the clipping one; dividing by the reference's own log norm makes
    it unitless like :func:`relative_rms`, so one budget serves bright and dark materials.
    The SE is the ratio's delta-method one (:func:`_relative_rms_with_se`).
    """
    reference = np.asarray(reference, dtype=np.float64).reshape(-1, 3)
    approx = np.asarray(approx, dtype=np.float64).reshape(-1, 3)
    w = _weights_or_ones(weight, reference.shape[0])
    log_ref = np.log1p(np.maximum(reference, 0.0))
    diff = np.log1p(np.maximum(approx, 0.0)) - log_ref
    rel, se = _relative_rms_with_se(w * np.sum(diff**2, axis=1), w * np.sum(log_ref**2, axis=1), 3)
    return _rounded_errors({"relative_log_rms": float(rel), "relative_log_rms_se": float(se)})


def _rounded_errors(errors: dict) -> dict:
    """Estimates to 6 significant digits, standard errors (keys ending ``_se``) to 3."""
    return {k: _round(v, 3 if k.endswith("_se") else 6) for k, v in errors.items()}


def measure_errors(reference: np.ndarray, approx: np.ndarray, weight=None) -> dict:
    """Both error measures and their standard errors as a dict (``relative_rms``,
    ``relative_rms_se``, ``log_error``, ``log_error_se``), rounded (:func:`weighted_errors`)."""
    return _rounded_errors(weighted_errors(reference, approx, weight))


def upper_bound(error: dict, measure: str = "relative_rms") -> float:
    """The figure a budget is judged on: the estimate of ``measure`` plus MET_SIGMAS standard errors
    (``relative_rms + MET_SIGMAS * relative_rms_se`` by default)."""
    return error[measure] + MET_SIGMAS * error.get(f"{measure}_se", 0.0)


def errors_by_terms(
    factors,
    reference: np.ndarray,
    l: np.ndarray,
    v: np.ndarray,
    terms=None,
    log: bool = True,
    weight=None,
    relative_log: bool = False,
) -> list[dict]:
    """Errors and standard errors of the first K terms at the pairs (l, v), n = +z, for each K in ``terms``.

    ``terms`` defaults to 1 .. factors.terms. One interpolation pass serves every K
    (a running sum over terms). ``weight`` is each pair's importance weight (default 1).
    Each dict also holds its ``terms``; ``log=False`` leaves out ``log_error`` (the
    costlier measure, not needed to rank candidates); ``relative_log=True`` adds
    ``relative_log_rms`` and its SE (:func:`relative_log_errors`).
    """
    wanted = sorted(set(range(1, factors.terms + 1) if terms is None else terms))
    if not wanted:
        return []
    products, valid = sample_factors(factors, None, l, v)
    pair_weight = _pair_weights(factors.parametrization, factors.target, valid, l, v)
    w = _weights_or_ones(weight, l.shape[0])
    ref = np.ascontiguousarray(np.asarray(reference, dtype=np.float64).T)
    # All K at once, channel-major like ``products``: cumulative sums over terms, then
    # the shader's clamp and weight, in place (these arrays are K x 3 x 100 000).
    # A running sum, term by term: it adds in np.cumsum's order, several times faster on this layout.
    approx = np.array(products[: wanted[-1]], order="C")
    for k in range(1, approx.shape[0]):
        approx[k] += approx[k - 1]
    if len(wanted) < approx.shape[0]:
        approx = approx[np.asarray(wanted) - 1]
    np.maximum(approx, 0.0, out=approx)
    approx *= pair_weight
    logs = relative_logs = None
    if log or relative_log:
        log_ref = np.log1p(np.maximum(ref, 0.0))
        diff = np.log1p(approx)
        diff -= log_ref
        np.square(diff, out=diff)
        if log:
            logs = _mean_sqrt_with_se(w * np.mean(diff, axis=1))
        if relative_log:
            relative_logs = _relative_rms_with_se(w * np.sum(diff, axis=1), w * np.sum(log_ref**2, axis=0), 3)
    approx -= ref
    squared = w * np.sum(np.square(approx, out=approx), axis=1)
    rel, rel_se = _relative_rms_with_se(squared, w * np.sum(ref**2, axis=0), 3)
    out = [_rounded_errors({"relative_rms": r, "relative_rms_se": s}) for r, s in zip(rel, rel_se)]
    out = [{"terms": k, **e} for k, e in zip(wanted, out)]
    if logs is not None:
        for entry, g, s in zip(out, *logs):
            entry.update(_rounded_errors({"log_error": g, "log_error_se": s}))
    if relative_logs is not None:
        for entry, g, s in zip(out, *relative_logs):
            entry.update(_rounded_errors({"relative_log_rms": g, "relative_log_rms_se": s}))
    return out


def _pair_weights(parametrization: str, target: str, valid, l, v) -> np.ndarray:
    """What multiplies the clamped sum at each pair: 0 where invalid, n.l / proxy for f_proxy, else 1."""
    if target != "f_proxy":
        return valid.astype(np.float64)

    def make():
        proxy = get_parametrization(parametrization).proxy_at(np.array([0.0, 0.0, 1.0]), l, v)
        return np.maximum(l[:, 2], 0.0) / proxy

    cosine = cached_on_pairs(("proxy", parametrization), (l, v), make)
    return np.where(valid, cosine, 0.0)
