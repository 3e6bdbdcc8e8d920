"""The whole approximation of one BRDF: sample, factor, measure, and pick K and the target."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from .error import errors_by_terms, sample_hemisphere_pairs
from .factorize import Factors, factorize, matrix_errors
from .parametrization import get_parametrization
from .source import BrdfSource, sample_matrices
from .storage import quantize_factors

__all__ = ["Approximation", "approximate_brdf", "reference_values", "TARGETS", "MAX_AUTO_TERMS"]

#: ``max_error`` mode tries K = 1 .. MAX_AUTO_TERMS.
MAX_AUTO_TERMS = 8
#: What the factors approximate: f cos(theta_l), or f times a separable cosine proxy.
TARGETS = ("f_cos", "f_proxy")


@dataclass
class Approximation:
    """The chosen factors and the evidence for them.

    ``errors_by_terms[target]`` lists, for K = 1 .. the largest K tried, the float
    errors at the fixed (l, v) pairs, ``errors_8bit_by_terms`` the same after 8-bit
    quantization, ``matrix_errors_by_terms`` the weighted residual on the sampled grid
    (:func:`matrix_errors`); ``factors`` is truncated to the chosen ``terms``.
    """

    factors: Factors
    terms: int
    target: str
    errors_by_terms: dict
    errors_8bit_by_terms: dict
    matrix_errors_by_terms: dict
    nonfinite_samples: int
    nonfinite_reference: int
    timings: dict = field(default_factory=dict)
    max_error_met: bool | None = None

    @property
    def errors(self) -> dict:
        """Float errors of the chosen target at the chosen K."""
        return {k: v for k, v in _at(self.errors_by_terms[self.target], self.terms).items() if k != "terms"}


@lru_cache(maxsize=None)
def _weights(name: str, resolution: int):
    return get_parametrization(name).quadrature_weights(resolution)


def reference_values(source: BrdfSource, pairs=None):
    """f cos at the error pairs, non-finite values set to 0; returns (values, count of non-finite)."""
    l, v = pairs if pairs is not None else sample_hemisphere_pairs()
    ref = source.f_cos(l, v)
    finite = np.isfinite(ref)
    return np.where(finite, ref, 0.0), int(np.count_nonzero(~finite))


def _at(errors: list[dict], terms: int) -> dict:
    return next(e for e in errors if e["terms"] == terms)


def _choose(errors: list[dict], terms, max_error):
    if terms is not None:
        return terms, None
    meeting = [e["terms"] for e in errors if e["relative_rms"] <= max_error]
    return (meeting[0], True) if meeting else (errors[-1]["terms"], False)


def approximate_brdf(
    source: BrdfSource,
    parametrization: str = "half_diff",
    terms: int | None = None,
    max_error: float | None = None,
    method: str = "svd",
    target: str = "auto",
    resolution: int = 32,
    reference=None,
    pairs=None,
    srgb: bool = True,
    measure_8bit: bool = True,
) -> Approximation:
    """Factor one BRDF (Kautz & McCool 1999) and measure every candidate.

    Parameters
    ----------
    terms, max_error
        A fixed K, or the error budget (relative RMS of f cos after 8-bit quantization,
        :func:`quantize_factors`) for which the smallest K <= 8 is chosen. With
        neither, ``max_error = 0.02``.
    target
        ``"f_cos"``, ``"f_proxy"``, or ``"auto"``: both are factored (from one sampling pass)
        and the one meeting the budget with fewer terms, then the one with the lower
        8-bit error, wins.
    srgb
        Whether the atlas stores RGB sRGB-encoded (the default), for the 8-bit estimate.
    measure_8bit
        False skips the 8-bit estimate (then candidates are judged on float errors and
        ``errors_8bit_by_terms`` is empty); for studies that only compare float errors.
    reference, pairs
        f cos at the error pairs and the pairs themselves, if already computed.
    """
    if terms is None and max_error is None:
        max_error = 0.02
    timings = {}
    p = get_parametrization(parametrization)
    t0 = time.perf_counter()
    targets = TARGETS if target == "auto" else (target,)
    matrices, nonfinite = sample_matrices(source, p, resolution, targets)
    t1 = time.perf_counter()
    timings["sample_s"] = t1 - t0
    most = 1 if method == "nd" else (terms or MAX_AUTO_TERMS)
    candidates = {}
    w1, w2 = _weights(p.name, resolution)
    for name in targets:
        factors = factorize(matrices[name], w1, w2, most, p.name, method)
        factors.target = name
        candidates[name] = factors
    t2 = time.perf_counter()
    timings["svd_s"] = t2 - t1
    grid_errors = {
        name: [float(f"{e:.6g}") for e in matrix_errors(matrices[name], w1, w2, f.truncated(min(most, MAX_AUTO_TERMS)))]
        for name, f in candidates.items()
    }

    if pairs is None:
        pairs = sample_hemisphere_pairs()
    if reference is None:
        reference, ref_nonfinite = reference_values(source, pairs)
    else:
        ref_nonfinite = 0
    l, v = pairs
    # K = 1 .. 8 for the curves, and the fixed K itself when it is larger.
    wanted = sorted(set(range(1, min(most, MAX_AUTO_TERMS) + 1)) | {most})
    errors = {name: errors_by_terms(f, reference, l, v, wanted) for name, f in candidates.items()}
    # Each term has its own scale and bias, so quantizing all K terms once gives the
    # 8-bit error of every prefix K in one more pass.
    errors_8bit = {
        name: errors_by_terms(quantize_factors(f, srgb=srgb), reference, l, v, wanted) for name, f in candidates.items()
    } if measure_8bit else {}
    judged = errors_8bit if measure_8bit else errors
    best = None
    for name in targets:
        k, met = _choose(judged[name], most if terms else None, max_error)
        key = (0 if met in (None, True) else 1, k if met else 0, _at(judged[name], k)["relative_rms"])
        if best is None or key < best[0]:
            best = (key, name, k, met)
    _, chosen, k, met = best
    timings["error_s"] = time.perf_counter() - t2
    return Approximation(
        factors=candidates[chosen].truncated(k),
        terms=k,
        target=chosen,
        errors_by_terms=errors,
        errors_8bit_by_terms=errors_8bit,
        matrix_errors_by_terms=grid_errors,
        nonfinite_samples=nonfinite,
        nonfinite_reference=ref_nonfinite,
        timings=timings,
        max_error_met=met,
    )
