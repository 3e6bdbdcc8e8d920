"""The whole approximation of one BRDF: sample, factor, measure, and pick K, the grid and the target."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import cache

import numpy as np

from atlasgen.separable.error import (
    ERROR_SEED,
    SELECTION_SEED,
    ErrorSample,
    error_sample_for,
    errors_by_terms,
    sample_hemisphere_pairs,
    upper_bound,
)
from atlasgen.separable.factorize import Factors, factorize, matrix_errors
from atlasgen.separable.parametrization import get_parametrization
from atlasgen.separable.resample import resample_factors
from atlasgen.separable.source import BrdfSource, sample_matrices
from atlasgen.separable.storage import quantize_factors

__all__ = [
    "Approximation",
    "Choice",
    "approximate_brdf",
    "choose_approximation",
    "report_approximation",
    "reference_values",
    "TARGETS",
    "MAX_AUTO_TERMS",
    "GRID_RESOLUTIONS",
    "search_terms",
    "DISPLAY_FACTORIZATIONS",
]

#: ``max_error`` mode tries K = 1 .. MAX_AUTO_TERMS.
MAX_AUTO_TERMS = 8
#: What the factors approximate: f cos(theta_l), or f times a separable cosine proxy.
TARGETS = ("f_cos", "f_proxy")
#: Sampling grids (texels per factor axis) a bake with an error budget chooses from, cheapest
#: first. The atlas always stores 32; 16 is interpolated up to it. Finer grids (fitted down by
#: least squares) lower the measured error of sharp lobes but ring around the highlight in
#: images, so they are only used when a material asks for one (docs/separable.md).
GRID_RESOLUTIONS = (16, 32)
#: Factorizations :func:`search_terms` weighs. The SVD minimises the L2 error, but its terms after
#: the first are signed: each is stored with a bias of its whole span, and the 8-bit step of that
#: span lands in every dim tail, which a display shows. NMF's terms are non-negative, stored
#: without a bias, where sRGB's 8-bit codes are finest, so a sharp lobe's tails keep their shape.
DISPLAY_FACTORIZATIONS = ("svd", "nmf")


@dataclass
class Approximation:
    """The chosen factors and the evidence for them.

    ``errors_by_terms[target]`` lists, for K = 1 .. the largest K tried, the float
    errors and their standard errors on the ``report`` sample, ``errors_8bit_by_terms``
    the same after 8-bit quantization (relative RMS only), ``matrix_errors_by_terms`` the
    weighted residual on the sampled grid (:func:`matrix_errors`), all on the chosen
    sampling ``grid``; ``candidates`` holds the 8-bit relative RMS by K of every (grid,
    target) tried, on the ``selection`` sample that chose among them.
    ``factors`` is truncated to the chosen ``terms`` and stored on ``resolution`` texels.
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
    grid: int = 32
    candidates: list = field(default_factory=list)
    selection: ErrorSample | None = None
    report: ErrorSample | None = None

    @property
    def errors(self) -> dict:
        """Float errors of the chosen target at the chosen K."""
        return {k: v for k, v in _at(self.errors_by_terms[self.target], self.terms).items() if k != "terms"}


@cache
def _weights(name: str, resolution: int):
    return get_parametrization(name).quadrature_weights(resolution)


def _as_sample(pairs, seed: int = ERROR_SEED) -> ErrorSample:
    """An :class:`ErrorSample`; a bare (l, v) tuple is taken as uniform pairs (weight 1)."""
    if isinstance(pairs, ErrorSample):
        return pairs
    l, v = pairs
    return ErrorSample(l, v, np.ones(l.shape[0]), seed, None, "uniform")


def reference_values(source: BrdfSource, pairs=None):
    """f cos at the error pairs (an :class:`ErrorSample` or an (l, v) tuple), non-finite
    values set to 0; returns (values, count of non-finite)."""
    if pairs is None:
        pairs = sample_hemisphere_pairs()
    l, v = pairs.pairs if isinstance(pairs, ErrorSample) else pairs
    ref = source.f_cos(l, v)
    finite = np.isfinite(ref)
    return np.where(finite, ref, 0.0), int(np.count_nonzero(~finite))


def _at(errors: list[dict], terms: int) -> dict:
    return next(e for e in errors if e["terms"] == terms)


def _choose(candidates: list[dict], terms, max_error):
    """Index of the chosen candidate, its K, and whether it meets ``max_error`` (None: K fixed).

    Fixed K: the least error at K. A budget: candidates in a fixed order of cost, fewer
    terms (atlas slices and texture reads per pixel) before a coarser sampling grid
    (BRDF evaluations at bake time), then lower error; the first that meets the
    budget within its uncertainty (:func:`~atlasgen.separable.error.upper_bound`,
    estimate + 2 SE) wins. If none does, the least error of all is kept. Because the
    order does not depend on the budget, a tighter budget never yields a larger error.
    """
    if terms is not None:
        best = min(range(len(candidates)), key=lambda i: (_at(candidates[i]["errors"], terms)["relative_rms"], i))
        return best, terms, None
    ranked = sorted((e["terms"], c["grid"], e["relative_rms"], i, upper_bound(e))
                    for i, c in enumerate(candidates) for e in c["errors"])  # fmt: skip
    for k, _, _, i, bound in ranked:
        if bound <= max_error:
            return i, k, True
    k, _, _, i, _ = min(ranked, key=lambda r: (r[2], r[0], r[1], r[3]))
    return i, k, False


@dataclass
class Choice:
    """The first half of :func:`approximate_brdf`: every candidate factored and judged on the
    ``selection`` sample, and the one chosen (``index``, its ``terms``). Everything the atlas
    stores is decided here (:attr:`factors`); :func:`report_approximation` measures the figures
    that only describe it, on the independent report sample."""

    candidates: list
    index: int
    terms: int
    #: Whether the chosen candidate met ``max_error`` on the selection sample (None: K fixed).
    met: bool | None
    #: The largest K factored, and the K every reported curve lists.
    most: int
    wanted: list
    max_error: float | None
    measure_8bit: bool
    selection: ErrorSample
    timings: dict

    @property
    def chosen(self) -> dict:
        return self.candidates[self.index]

    @property
    def factors(self) -> Factors:
        """The chosen factors truncated to the chosen K, on the stored resolution: what the atlas holds."""
        return self.chosen["factors"].truncated(self.terms)


def choose_approximation(
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
    grids=None,
) -> Choice:
    """Factor and judge every candidate on the selection sample, and choose (:func:`approximate_brdf`'s
    parameters of the same names; ``pairs`` defaults to the lobe-sampled pairs with
    :data:`~atlasgen.separable.error.SELECTION_SEED`). Nothing here reads the report sample, so
    the choice, and the factors, are a full :func:`approximate_brdf`'s."""
    if terms is None and max_error is None:
        max_error = 0.02
    grids = (resolution,) if grids is None else tuple(sorted(set(int(g) for g in grids)))
    p = get_parametrization(parametrization)
    targets = TARGETS if target == "auto" else (target,)
    most = 1 if method == "nd" else (terms or MAX_AUTO_TERMS)
    # K = 1 .. 8 for the curves, and the fixed K itself when it is larger.
    wanted = sorted(set(range(1, min(most, MAX_AUTO_TERMS) + 1)) | {most})
    selection = _as_sample(error_sample_for(source, SELECTION_SEED) if pairs is None else pairs)
    if reference is None:
        reference, _ = reference_values(source, selection)
    l, v = selection.pairs

    timings = {"sample_s": 0.0, "svd_s": 0.0, "error_s": 0.0}
    candidates = []
    for grid in grids:
        t0 = time.perf_counter()
        matrices, nonfinite = sample_matrices(source, p, grid, targets)
        t1 = time.perf_counter()
        w1, w2 = _weights(p.name, grid)
        sampled = {}
        for name in targets:
            sampled[name] = factorize(matrices[name], w1, w2, most, p.name, method)
            sampled[name].target = name
        t2 = time.perf_counter()
        for name in targets:
            stored = resample_factors(sampled[name], resolution)
            # Each term has its own scale and bias, so quantizing all K terms once gives
            # the 8-bit error of every prefix K in one more pass.
            judged_factors = quantize_factors(stored, srgb=srgb) if measure_8bit else stored
            judged = errors_by_terms(judged_factors, reference, l, v, wanted, log=not measure_8bit, weight=selection.weight)
            candidates.append({"grid": grid, "target": name, "factors": stored, "sampled": sampled[name],
                               "judged": judged_factors, "matrix": matrices[name], "weights": (w1, w2),
                               "nonfinite": nonfinite, "errors": judged})  # fmt: skip
        timings["sample_s"] += t1 - t0
        timings["svd_s"] += t2 - t1
        timings["error_s"] += time.perf_counter() - t2
        if terms is None and any(upper_bound(c["errors"][0]) <= max_error for c in candidates):
            break  # one term on the coarsest grid so far: no later grid can be cheaper

    index, k, met = _choose(candidates, most if terms else None, max_error)
    return Choice(candidates, index, k, met, most, wanted, max_error, measure_8bit, selection, timings)


def report_approximation(choice: Choice, report: ErrorSample, report_reference) -> Approximation:
    """The second half of :func:`approximate_brdf`: the reported figures of ``choice``, measured on the
    independent ``report`` sample (f cos there: ``report_reference``), and whether the budget is met there."""
    t3 = time.perf_counter()
    timings = dict(choice.timings)
    candidates, chosen, k, met, most, wanted = (
        choice.candidates,
        choice.chosen,
        choice.terms,
        choice.met,
        choice.most,
        choice.wanted,
    )
    on_grid = [c for c in candidates if c["grid"] == chosen["grid"]]
    # Every reported figure is measured again, on the independent report sample.
    report = _as_sample(report)
    rl, rv, rw = report.l, report.v, report.weight
    errors = {c["target"]: errors_by_terms(c["factors"], report_reference, rl, rv, wanted, weight=rw) for c in on_grid}
    errors_8bit = ({c["target"]: errors_by_terms(c["judged"], report_reference, rl, rv, wanted, log=False, weight=rw)
                    for c in on_grid} if choice.measure_8bit else {})  # fmt: skip
    if met is not None:
        reported = (errors_8bit or errors)[chosen["target"]]
        met = bool(upper_bound(_at(reported, k)) <= choice.max_error)
    grid_errors = {
        c["target"]: [
            float(f"{e:.6g}")
            for e in matrix_errors(c["matrix"], *c["weights"], c["sampled"].truncated(min(most, MAX_AUTO_TERMS)))
        ]
        for c in on_grid
    }
    timings["error_s"] += time.perf_counter() - t3
    return Approximation(
        factors=choice.factors,
        terms=k,
        target=chosen["target"],
        errors_by_terms=errors,
        errors_8bit_by_terms=errors_8bit,
        matrix_errors_by_terms=grid_errors,
        nonfinite_samples=chosen["nonfinite"],
        nonfinite_reference=0,
        timings=timings,
        max_error_met=met,
        grid=chosen["grid"],
        candidates=[
            {
                "grid": c["grid"],
                "target": c["target"],
                "relative_rms_by_terms": [e["relative_rms"] for e in c["errors"]],
                "relative_rms_se_by_terms": [e["relative_rms_se"] for e in c["errors"]],
            }
            for c in candidates
        ],  # fmt: skip
        selection=choice.selection,
        report=report,
    )


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
    grids=None,
    report=None,
    report_reference=None,
) -> Approximation:
    """Factor one BRDF (Kautz & McCool 1999) and measure every candidate.

    A candidate is a (sampling grid, target) pair with its K = 1 .. 8 prefixes. The
    BRDF is sampled on each grid, factored there, and carried to the stored
    ``resolution`` (:func:`~atlasgen.separable.resample.resample_factors`), so every
    candidate is judged on what the atlas would hold. It is :func:`choose_approximation`
    (on the selection sample) followed by :func:`report_approximation` (on the report sample).

    Parameters
    ----------
    terms, max_error
        A fixed K, or the error budget (relative RMS of f cos after 8-bit quantization,
        :func:`quantize_factors`) for which the cheapest candidate meeting it is chosen
        (see :func:`_choose`). With neither, ``max_error = 0.02``.
    target
        ``"f_cos"``, ``"f_proxy"``, or ``"auto"``: both are factored (from one sampling
        pass per grid) and compete as candidates.
    resolution
        Texels per factor axis of the result (the atlas stores 32).
    grids
        Sampling grids to try, e.g. :data:`GRID_RESOLUTIONS`; default ``(resolution,)``.
        With a budget they are tried coarsest first, and a grid meeting it with one term
        ends the search (nothing after it can be cheaper).
    srgb
        Whether the atlas stores RGB sRGB-encoded (the default), for the 8-bit estimate.
    measure_8bit
        False skips the 8-bit estimate (then candidates are judged on float errors and
        ``errors_8bit_by_terms`` is empty); for studies that only compare float errors.
    pairs, reference
        The sample the candidates are judged and chosen on (an
        :class:`~atlasgen.separable.error.ErrorSample`, or an (l, v) tuple of uniform pairs)
        and f cos there, if already computed. Default: the source's lobe-sampled pairs with
        :data:`~atlasgen.separable.error.SELECTION_SEED`.
    report, report_reference
        The independent sample every reported figure (``errors_by_terms``,
        ``errors_8bit_by_terms``, ``max_error_met``) is measured on, and f cos there.
        Default: the source's lobe-sampled pairs with :data:`~atlasgen.separable.error.ERROR_SEED`
        when ``pairs`` is defaulted too; otherwise ``pairs`` itself (a study that passes one
        sample chooses and reports on it).
    """
    if report is None:
        report = error_sample_for(source, ERROR_SEED) if pairs is None else pairs
        report_reference = report_reference if report_reference is not None else (reference if pairs is not None else None)
    report = _as_sample(report)
    ref_nonfinite = 0
    if report_reference is None:
        report_reference, ref_nonfinite = reference_values(source, report)
    choice = choose_approximation(source, parametrization, terms, max_error, method, target, resolution, reference, pairs,
                                  srgb, measure_8bit, grids)  # fmt: skip
    result = report_approximation(choice, report, report_reference)
    result.nonfinite_reference = ref_nonfinite
    return result


def search_terms(
    source: BrdfSource,
    parametrization: str,
    budget: float,
    selection: ErrorSample,
    reference,
    grid: int = 32,
    resolution: int = 32,
    methods=DISPLAY_FACTORIZATIONS,
    targets=TARGETS,
    measure: str = "relative_log_rms",
    max_terms: int = MAX_AUTO_TERMS,
    srgb: bool = True,
    target_measure: str | None = "relative_rms",
):
    """Separable candidates K = 1, 2, ... of each factorization and target, judged on ``selection``.

    Each candidate is the 8-bit factors (:func:`quantize_factors`) of one factorization
    (``methods``) of one target's matrix sampled once on ``grid``, with its ``measure``
    (:func:`~atlasgen.separable.error.errors_by_terms`: ``relative_rms`` and
    ``relative_log_rms`` with their SEs) against ``reference`` (f cos at the selection pairs).
    SVD candidates are the prefixes of one factorization, which are the best rank-K ones
    (Eckart & Young 1936); NMF is factored anew for each K, since its terms have no order.
    The search stops after the first K at which a candidate meets ``budget`` within its
    uncertainty (:func:`~atlasgen.separable.error.upper_bound`): every larger K costs more.
    With ``target_measure``, each factorization keeps at each K only the target of the least
    ``target_measure`` (the estimate): the target a fixed K of that factorization is baked with
    (:func:`_choose`), so the budget chooses K and the factorization, never a target the same K
    would not store.

    Returns ``(candidates, nonfinite)``: dicts ``{"factorization", "target", "terms", "grid",
    "relative_rms", "relative_rms_se", "relative_log_rms", "relative_log_rms_se"}`` in
    order of K, and the count of non-finite samples.
    """
    p = get_parametrization(parametrization)
    matrices, nonfinite = sample_matrices(source, p, grid, targets)
    w1, w2 = _weights(p.name, grid)
    l, v = selection.pairs

    def judged(factors, wanted):
        stored = quantize_factors(resample_factors(factors, resolution), srgb=srgb)
        return errors_by_terms(stored, reference, l, v, wanted, log=False, weight=selection.weight, relative_log=True)

    prefixes = {}
    out = []
    for k in range(1, max_terms + 1):
        for method in methods:
            tried = []
            for target in targets:
                if method == "svd":
                    if target not in prefixes:
                        factors = factorize(matrices[target], w1, w2, max_terms, p.name, "svd")
                        factors.target = target
                        prefixes[target] = judged(factors, range(1, max_terms + 1))
                    error = prefixes[target][k - 1]
                else:
                    factors = factorize(matrices[target], w1, w2, k, p.name, method)
                    factors.target = target
                    error = judged(factors, [k])[0]
                tried.append({"factorization": method, "target": target, "grid": int(grid), **error})
            if target_measure is not None:
                tried = [min(tried, key=lambda c: c[target_measure])]
            out += tried
        if any(upper_bound(c, measure) <= budget for c in out if c["terms"] == k):
            break
    return out, nonfinite
