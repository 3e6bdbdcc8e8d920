"""Slices fitted to a physical BSDF: sample it per texel over the azimuth, project it onto the renderer's equation.

For each texel centre (N.L, N.V) of the slice, l and v are placed at the texel's polar
angles with S stratified azimuths phi_s = 2 pi (s + 1/2) / S between them, the BSDF's
f cos(theta_l) is evaluated there, and :func:`atlasgen.optics.projection.project_slice_texels`
finds the non-negative (A.rgb, A.a) whose renderer radiance is closest in the uniform
azimuth measure. Uniform texels times uniform azimuths sample (l, v) pairs uniformly over
the hemisphere pair (N.L and N.V are uniform in cos theta), so the summed residual is the
squared error of f cos over uniform (l, v) pairs, the measure the separable model reports.
At N.L = 1 and N.V = 1 every azimuth is the same pair, so the samples cannot split the
texel between A.rgb and A: :func:`atlasgen.optics.projection.continue_collinear_texels`
holds A at its nearest separable texel's, which the bilinear filter needs for a sharp lobe.

The renderer's bases come from :meth:`atlasgen.models.base.Model.renderer_f_cos` (the
renderer's equation as :mod:`atlasgen.optics.specular` states it), so the fit follows any
change of the lobe. Then the RGB is rounded as the atlas stores it (per-slice scale,
sRGB 8-bit) and A re-fitted against the rounded RGB, then capped at the quantile of
:data:`A_CAP_QUANTILES` whose 8-bit A (one linear scale per slice) errs least.
"""

from __future__ import annotations

import json
from functools import lru_cache
from typing import ClassVar

import numpy as np

from atlasgen.contract import HEIGHT, WIDTH, texel_centres
from atlasgen.errors import MaterialError
from atlasgen.io.referenced_files import files_state
from atlasgen.models.base import Model, SliceSet
from atlasgen.optics.interpolation import sample_slice
from atlasgen.optics.projection import (
    continue_collinear_texels,
    pair_directions,
    project_slice_texels,
    refine_specular_scale,  # fmt: skip
    weighted_residual,
)
from atlasgen.optics.quantize import dequantize_rgba, quantize_rgba, unorm_scale
from atlasgen.optics.specular import half_vector_cosine, renderer_f_cos
from atlasgen.separable.mitsuba_source import evaluate_mitsuba_f_cos, load_mitsuba_bsdf

__all__ = ["AZIMUTHS", "FIT_GLOSS", "GRAZING_N_DOT_V", "GLOSS_CANDIDATES", "azimuth_pairs", "renderer_bases", "fit_slice",
           "plain_bsdf_reference", "check_physical_fit", "bake_from_physics", "mitsuba_f_cos", "FittedSlice",
           "slice_relative_rms", "fit_to_reference", "cosine_pairs", "psnr_against", "DEVIATION_PAIRS", "DEVIATION_SEED",
           "FIT_SUPERSAMPLING", "FOOTPRINTS", "footprint_f_cos", "footprint_pairs"]  # fmt: skip

#: Azimuth samples per texel.
AZIMUTHS = 128
#: The g-buffer gloss a ``from = "physical"`` slice is fitted for: a scene object's default.
FIT_GLOSS = 0.5
#: Glosses tried when a fit chooses its own (``type = "bsdf"`` without ``gloss``).
GLOSS_CANDIDATES = tuple(np.linspace(0.0, 1.0, 33).tolist())
#: Width in gloss at which a chosen gloss stops being refined (:func:`fit_slice`).
GLOSS_TOLERANCE = 2e-4
#: N.V at which the N.V = 0 texel row is sampled (see :func:`fit_slice`).
GRAZING_N_DOT_V = 1e-3
#: Quantiles of the fitted A tried as its cap (1 = no cap): see :func:`fit_slice`.
A_CAP_QUANTILES = (1.0, 0.999, 0.995, 0.99, 0.98, 0.95)
#: Sub-positions per texel axis of a supersampled fit (:func:`footprint_pairs`): the 4 x 4 of the
#: model's supersampled candidate (:func:`atlasgen.bake.adaptive.bake_supersampled`).
FIT_SUPERSAMPLING = 4
#: How a supersampled :func:`fit_slice` uses the footprint: ``"mean"`` fits the centre to f cos averaged
#: over it (:func:`footprint_f_cos`), ``"fit"`` fits the texel to f cos at pairs spread over it (:func:`footprint_pairs`).
FOOTPRINTS = ("mean", "fit")


def azimuth_pairs(n_dot_l, n_dot_v, azimuths: int = AZIMUTHS):
    """Unit l, v ``(H, W, S, 3)`` and n.h ``(H, W, S)`` for the texel grid ``n_dot_l`` (W,) x ``n_dot_v`` (H,).

    v lies in the xz plane; l at azimuth phi_s = 2 pi (s + 1/2) / S from it (n = +z).
    Returns ``l, v, n_dot_h, degenerate`` (l + v = 0).
    """
    nl = np.asarray(n_dot_l, dtype=np.float64)[None, :, None]
    nv = np.asarray(n_dot_v, dtype=np.float64)[:, None, None]
    phi = 2.0 * np.pi * (np.arange(azimuths) + 0.5) / azimuths
    shape = (len(np.atleast_1d(n_dot_v)), len(np.atleast_1d(n_dot_l)), azimuths)
    l, v = pair_directions(nl, nv, phi, shape)
    return (l, v, *half_vector_cosine(l, v))


def footprint_pairs(azimuths: int = AZIMUTHS, factor: int = FIT_SUPERSAMPLING):
    """Unit l, v ``(H, W, S, 3)``, n.h and l + v = 0 (as :func:`azimuth_pairs`), the S = ``azimuths``
    pairs of each texel dealt out over its footprint: the pairs of a footprint-fitted :func:`fit_slice`.

    The footprint's f x f sub-positions are :func:`footprint_f_cos`' (the bake's box, clipped, N.V
    at least :data:`GRAZING_N_DOT_V`); sub-position k = a f + b holds the azimuth strata
    s = k + f^2 m, phi_s = 2 pi (s + 1/2) / S, so each sees S / f^2 azimuths around the whole
    circle and the texel the point-sampled fit's S azimuths: stratified in (N.L, N.V, phi) at the
    same cost (``azimuths`` a multiple of f^2).
    """
    f = int(factor)
    per = int(azimuths) // (f * f)
    if f < 1 or per * f * f != int(azimuths):
        raise ValueError(f"azimuths ({azimuths}) must be a positive multiple of factor^2 ({f}^2)")
    nl_c, nv_c = texel_centres(WIDTH, HEIGHT)
    offsets = (np.arange(f) + 0.5) / f - 0.5
    nl = np.clip(nl_c[:, None] + offsets * 2.0 / (WIDTH - 1), -1.0, 1.0)[None, :, :, None, None]  # (1, W, f, 1, 1)
    nv = np.maximum(np.clip(nv_c[:, None] + offsets / (HEIGHT - 1), 0.0, 1.0), GRAZING_N_DOT_V)[:, None, None, :, None]
    k = np.arange(f)[:, None] * f + np.arange(f)[None, :]
    phi = (2.0 * np.pi * (k[..., None] + f * f * np.arange(per) + 0.5) / azimuths)[None, None]  # (1, 1, f, f, per)
    l, v = pair_directions(nl, nv, phi, (HEIGHT, WIDTH, f, f, per))
    l, v = l.reshape(HEIGHT, WIDTH, f * f * per, 3), v.reshape(HEIGHT, WIDTH, f * f * per, 3)
    return (l, v, *half_vector_cosine(l, v))


def footprint_f_cos(f_cos, azimuths: int = AZIMUTHS, factor: int = FIT_SUPERSAMPLING) -> np.ndarray:
    """``f_cos(l, v) -> (N, 3)`` averaged over each texel's footprint, ``(H, W, S, 3)``: the
    box-filtered target of a supersampled :func:`fit_slice`, at :func:`azimuth_pairs`' strata.

    The footprint is :func:`atlasgen.bake.adaptive.bake_supersampled`'s box, f = ``factor``
    sub-positions per axis: sub-position (a, b) of the texel centred at (N.L_i, N.V_j) lies at
    N.L_i + o_a 2 / (W - 1), N.V_j + o_b / (H - 1), o_k = (k + 1/2) / f - 1/2, clipped to
    [-1, 1] and [0, 1] as the bake clips (then N.V to at least :data:`GRAZING_N_DOT_V`, as
    :func:`fit_slice`). Its azimuth is jittered within the texel's azimuth stratum s,
    phi = 2 pi (s + (a f + b + 1/2) / f^2) / S, so the mean over the f^2 sub-positions is a
    stratified estimate of f cos's mean over the box in (N.L, N.V) times the stratum in phi:
    for f cos linear over the box it is f cos at the centre (texels inside the slice).
    Evaluates f^2 x the point-sampled fit's pairs, one sub-position at a time.
    """
    f = int(factor)
    nl_c, nv_c = texel_centres(WIDTH, HEIGHT)
    offsets = (np.arange(f) + 0.5) / f - 0.5
    total = None
    for a in range(f):
        nl = np.clip(nl_c + offsets[a] * 2.0 / (WIDTH - 1), -1.0, 1.0)[None, :, None]
        for b in range(f):
            nv = np.maximum(np.clip(nv_c + offsets[b] / (HEIGHT - 1), 0.0, 1.0), GRAZING_N_DOT_V)[:, None, None]
            phi = 2.0 * np.pi * (np.arange(azimuths) + (a * f + b + 0.5) / (f * f)) / azimuths
            l, v = pair_directions(nl, nv, phi, (HEIGHT, WIDTH, azimuths))
            value = np.asarray(f_cos(l.reshape(-1, 3), v.reshape(-1, 3)), dtype=np.float64).reshape(l.shape)
            value = np.where(np.isfinite(value), value, 0.0)
            total = value if total is None else total + value
    return total / (f * f)


class _Constant(Model):
    """A slice equal to one RGBA everywhere: the renderer's equation for it is one basis function."""

    def __init__(self, rgba):
        self.rgba = np.asarray(rgba, dtype=np.float64)

    def evaluate(self, values, n_dot_l, n_dot_v):
        shape = np.broadcast_shapes(np.shape(n_dot_l), np.shape(n_dot_v))
        return np.broadcast_to(self.rgba, shape + (4,))


def renderer_bases(gloss: float, l, v, n_dot_h, degenerate):
    """The renderer's f cos at (l, v) per unit A.rgb (``(..., 3)``) and per unit A (``(..., 3)``), albedo 1."""
    nl, nv = l[..., 2], v[..., 2]
    ones = np.ones(nl.shape + (3,))
    diffuse = _Constant((1.0, 1.0, 1.0, 0.0)).renderer_f_cos({}, ones, gloss, nl, nv, n_dot_h, degenerate)
    lobe = _Constant((0.0, 0.0, 0.0, 1.0)).renderer_f_cos({}, ones, gloss, nl, nv, n_dot_h, degenerate)
    return np.asarray(diffuse, dtype=np.float64), np.asarray(lobe, dtype=np.float64)


def fit_slice(
    f_cos, gloss=FIT_GLOSS, azimuths: int = AZIMUTHS, srgb: bool = True, supersampling: int = 1, footprint: str = "mean"
):
    """The slice (``(H, W, 4)``) fitted to ``f_cos(l, v) -> (N, 3)``, and a dict describing the fit.

    ``gloss`` is the renderer gloss the slice is made for, or ``None`` to choose the one of
    least residual: the best of :data:`GLOSS_CANDIDATES`, refined by golden-section search
    within one grid step to :data:`GLOSS_TOLERANCE`. The dict holds ``gloss``,
    ``azimuths``, ``alpha_cap`` and ``relative_rms``: sqrt(residual / sum w t^2) over
    every texel with the RGB and A rounded to 8 bits as stored.

    ``supersampling`` f > 1 uses each texel's footprint in (N.L, N.V) (f x f sub-positions, the
    box of the model's supersampled bake) rather than its centre. ``footprint = "mean"`` fits the
    texel, at its centre, to f cos averaged over the footprint (:func:`footprint_f_cos`, f^2 x the
    evaluations), as the bake box-filters a closed form; ``"fit"`` fits it, through the renderer's
    equation at each pair, to f cos at the texel's S pairs spread over the footprint
    (:func:`footprint_pairs`, the same evaluations): the texel value that best reproduces f cos
    over the texel rather than at its centre. The dict then also holds ``supersampling`` and
    ``footprint`` (``relative_rms`` is against that target).
    """
    nl, nv = texel_centres(WIDTH, HEIGHT)
    # The N.V = 0 row is the limit of grazing views: BSDFs return 0 for a view in the
    # tangent plane itself, which the bilinear filter would spread over the first texel.
    l, v, nh, degenerate = azimuth_pairs(nl, np.maximum(nv, GRAZING_N_DOT_V), azimuths)
    if footprint not in FOOTPRINTS:
        raise ValueError(f"footprint must be one of {FOOTPRINTS}, got {footprint!r}")
    if supersampling > 1 and footprint == "fit":
        l, v, nh, degenerate = footprint_pairs(azimuths, supersampling)
    if supersampling > 1 and footprint == "mean":  # the box-filtered target, projected at the centres
        target = footprint_f_cos(f_cos, azimuths, supersampling)
    else:
        target = np.asarray(f_cos(l.reshape(-1, 3), v.reshape(-1, 3)), dtype=np.float64).reshape(l.shape)
    nonfinite = int((~np.isfinite(target)).sum())
    target = np.where(np.isfinite(target), target, 0.0)
    weights = np.full(l.shape[:-1], 1.0 / azimuths)
    energy = float((weights[..., None] * target * target).sum())
    fits = {}

    def fit_at(g):
        if g not in fits:
            diffuse, lobe = renderer_bases(g, l, v, nh, degenerate)
            # Continue A into N.L = 1 and N.V = 1, where the samples leave the split free.
            rgba = continue_collinear_texels(project_slice_texels(target, diffuse, lobe, weights), diffuse, lobe, weights)
            fits[g] = (float(weighted_residual(target, diffuse, lobe, weights, rgba).sum()), g, rgba, diffuse, lobe)
        return fits[g]

    if gloss is None:
        coarse = min((fit_at(g) for g in GLOSS_CANDIDATES), key=lambda fit: fit[0])[1]
        step = GLOSS_CANDIDATES[1] - GLOSS_CANDIDATES[0]
        _refine_gloss(lambda g: fit_at(g)[0], max(0.0, coarse - step), min(1.0, coarse + step))
    else:
        fit_at(float(gloss))
    _, g, rgba, diffuse, lobe = min(fits.values(), key=lambda fit: (fit[0], fit[1]))
    # Round the RGB as the atlas will store it (encode_scaled's per-slice scale, then 8 bits),
    # and give A the best value against what is stored.
    scale = unorm_scale(rgba[..., :3].max())
    codes = quantize_rgba(np.concatenate([rgba[..., :3] / scale, np.zeros(rgba.shape[:-1] + (1,))], -1), srgb)
    rgba[..., :3] = dequantize_rgba(codes, srgb)[..., :3] * scale
    a = refine_specular_scale(target, diffuse, lobe, weights, rgba[..., :3])
    # A shares one 8-bit scale per slice: a few texels with a huge A (where the lobe is
    # nearly zero) would coarsen every other texel's step. Cap A where that errs least.
    best = None
    positive = a[a > 0.0] if (a > 0.0).any() else np.zeros(1)
    for cap in sorted({float(np.quantile(positive, q)) for q in A_CAP_QUANTILES}, reverse=True):
        scale_a = unorm_scale(cap)
        stored = np.rint(np.clip(np.minimum(a, cap) / scale_a, 0.0, 1.0) * 255.0) / 255.0 * scale_a
        rgba[..., 3] = stored
        residual = float(weighted_residual(target, diffuse, lobe, weights, rgba).sum())
        if best is None or residual < best[0]:
            best = (residual, cap)
    residual, cap = best
    rgba[..., 3] = np.minimum(a, cap)
    info = {"gloss": float(g), "azimuths": int(azimuths), "alpha_cap": cap,
            "relative_rms": float(np.sqrt(residual / energy)) if energy > 0 else 0.0}  # fmt: skip
    if supersampling > 1:
        info.update(supersampling=int(supersampling), footprint=footprint)
    if nonfinite:  # replaced by 0 above; the bake refuses them unless tolerated (atlasgen.bake.quality)
        info["nonfinite_samples"] = nonfinite
    return rgba, info


def _refine_gloss(residual, lo: float, hi: float, tolerance: float = GLOSS_TOLERANCE) -> None:
    """Golden-section search for the gloss of least ``residual`` in [lo, hi] (Kiefer 1953).

    The coarse grid's step (1/32 in gloss) is about 6% in alpha near gloss 0.7, enough to
    cost a sharp lobe several dB where its peak is bright: the residual is smooth and
    unimodal around the grid's best, so a bracketing search recovers the BSDF's own width.
    """
    ratio = (np.sqrt(5.0) - 1.0) / 2.0
    a, b = lo, hi
    c, d = b - ratio * (b - a), a + ratio * (b - a)
    fc, fd = residual(c), residual(d)
    while b - a > tolerance:
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - ratio * (b - a)
            fc = residual(c)
        else:
            a, c, fc = c, d, fd
            d = a + ratio * (b - a)
            fd = residual(d)


def slice_relative_rms(rgba, f_cos, gloss=FIT_GLOSS, azimuths: int = AZIMUTHS) -> float:
    """Relative RMS of the renderer's f cos with slice ``rgba`` (``(H, W, 4)``, at the texel
    centres) against ``f_cos(l, v) -> (N, 3)``: sqrt(sum w (t - fit)^2 / sum w t^2) over the
    same (l, v) pairs and weights as :func:`fit_slice`, at renderer gloss ``gloss``."""
    nl, nv = texel_centres(WIDTH, HEIGHT)
    l, v, nh, degenerate = azimuth_pairs(nl, np.maximum(nv, GRAZING_N_DOT_V), azimuths)
    target = np.asarray(f_cos(l.reshape(-1, 3), v.reshape(-1, 3)), dtype=np.float64).reshape(l.shape)
    target = np.where(np.isfinite(target), target, 0.0)
    weights = np.full(l.shape[:-1], 1.0 / azimuths)
    diffuse, lobe = renderer_bases(float(gloss), l, v, nh, degenerate)
    residual = float(weighted_residual(target, diffuse, lobe, weights, np.asarray(rgba, dtype=np.float64)).sum())
    energy = float((weights[..., None] * target * target).sum())
    return float(np.sqrt(residual / energy)) if energy > 0 else 0.0


#: Pairs and seed of the cosine-weighted sample a deviation in dB is measured on (:func:`psnr_against`).
DEVIATION_PAIRS = 16384
DEVIATION_SEED = 20260


def cosine_pairs(count: int = DEVIATION_PAIRS, seed: int = DEVIATION_SEED, sphere: bool = False):
    """``count`` i.i.d. (l, v) pairs, each cosine-weighted on the upper hemisphere (pdf cos / pi; Malley's
    method: a uniform disc point lifted to the hemisphere, PBRT 3rd ed. sec. 13.6.3), n = +z. With
    ``sphere``, l is mirrored below the surface with probability 1/2 (a reference that transmits)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(2):
        u, phi = rng.random(count), 2.0 * np.pi * rng.random(count)
        r = np.sqrt(u)
        out.append(np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1.0 - u)], axis=-1))
    l, v = out
    if sphere:
        l[rng.random(count) < 0.5, 2] *= -1.0
    return l, v


def psnr_against(reference: np.ndarray, approx: np.ndarray) -> tuple[float, float]:
    """PSNR in dB of ``approx`` against ``reference`` (``(N, 3)`` f cos at the same i.i.d. pairs), and its SE.

        PSNR = 10 log10(P^2 / MSE),  MSE = mean over pairs and channels of (approx - reference)^2,

    P the reference's peak over the sample, held fixed. The SE is the delta method's
    (10 / ln 10) SE(MSE) / MSE, SE(MSE) the pairs' standard error of the mean (Owen 2013, sec. 9.2).
    """
    ref, app = np.asarray(reference, dtype=np.float64), np.asarray(approx, dtype=np.float64)
    per_pair = ((app - ref) ** 2).mean(axis=1)
    mse = float(per_pair.mean())
    peak = float(ref.max())
    if mse <= 0.0 or peak <= 0.0:
        return float("inf"), 0.0
    se = float(per_pair.std(ddof=1) / np.sqrt(len(per_pair)))
    return 10.0 * float(np.log10(peak * peak / mse)), 10.0 / float(np.log(10.0)) * se / mse


def _deviations(model: Model, values: dict, f_cos, rgba, gloss: float, transmits: bool) -> dict:
    """The model's own f cos (its closed form, no texels) and the fitted slice's (float), each in the
    renderer's equation at ``gloss``, against ``f_cos`` in dB on one cosine-weighted sample (:func:`psnr_against`)."""
    l, v = cosine_pairs(sphere=transmits)
    nl, nv, nh, degenerate = l[:, 2], v[:, 2], *half_vector_cosine(l, v)
    reference = np.asarray(f_cos(l, v), dtype=np.float64)
    own = renderer_f_cos(model.evaluate(values, np.clip(nl, -1.0, 1.0), nv), 1.0, gloss, nl, nv, nh, degenerate)
    fitted = renderer_f_cos(sample_slice(rgba, nl, nv), 1.0, gloss, nl, nv, nh, degenerate)
    out = {}
    for name, approx in (("model", own), ("fit", fitted)):
        db, se = psnr_against(reference, approx)
        out[f"{name}_psnr_db"], out[f"{name}_psnr_se_db"] = round(db, 2), round(se, 3)
    out.update(
        psnr_pairs=len(l), psnr_seed=DEVIATION_SEED, psnr_sample="cosine-weighted" + (", l over the sphere" if transmits else "")
    )
    return out


def _remember_last(f_cos):
    """``f_cos`` that returns its last result again for the same (l, v): a spectral reference
    costs seconds per slice of pairs."""
    last = {}

    def remembered(l, v):
        if "t" not in last or not (np.array_equal(last["l"], l) and np.array_equal(last["v"], v)):
            last.update(l=np.array(l), v=np.array(v), t=np.asarray(f_cos(l, v), dtype=np.float64))
        return last["t"]

    return remembered


def fit_to_reference(
    model: Model,
    values: dict,
    f_cos,
    reference: str,
    gloss: float = FIT_GLOSS,
    deviation: bool = False,
    transmits: bool = False,
    **extra,
) -> SliceSet:
    """One slice fitted by :func:`fit_slice` to a model's physical reference given as NumPy
    ``f_cos(l, v) -> (N, 3)``, for the renderer gloss ``gloss`` (a model's
    :meth:`~atlasgen.models.base.Model.fit_physical`).

    ``extra["fit"]`` holds ``from`` ("physical"), ``reference``, the fit's own description
    (``gloss``, ``azimuths``, ``alpha_cap``, ``relative_rms``: 8-bit RGB and A), ``extra`` and
    ``model_relative_rms``: the model's own float slice (``from = "model"``, at the texel
    centres, not rounded) against the same reference in the same measure, so the manifest
    says what fitting to physics gained. With ``deviation``, also ``model_psnr_db`` and
    ``fit_psnr_db`` with their SEs: the model's closed form and the fitted float slice, each in
    the renderer's equation, against the reference in dB on a cosine-weighted sample (l over the
    sphere where the reference ``transmits``): what the model's look costs in truth, beside what
    the table can reach (:func:`psnr_against`).
    """
    f_cos = _remember_last(f_cos)  # the fit and the model's measure sample the same pairs
    rgba, info = fit_slice(f_cos, float(gloss))
    nl, nv = texel_centres(WIDTH, HEIGHT)
    own = np.broadcast_to(np.asarray(model.evaluate(values, nl[None, :], nv[:, None]), dtype=np.float64), rgba.shape)
    fit = {"from": "physical", "reference": reference, **info, **extra,
           "model_relative_rms": slice_relative_rms(own, f_cos, float(gloss), info["azimuths"])}  # fmt: skip
    if deviation:
        fit.update(_deviations(model, values, f_cos, rgba, float(gloss), transmits))
    return SliceSet(rgba.reshape(1, HEIGHT, WIDTH, 4), extra={"fit": fit})


def plain_bsdf_reference(model: Model, values: dict, gloss: float = FIT_GLOSS):
    """The model's physical reference for an object of albedo 1 and renderer gloss ``gloss``
    if it is one BSDF evaluated in ``llvm_ad_rgb`` with the default integrator (what a
    projection can sample), else a reason why not (a string)."""
    ref = model.physical_reference(values, (1.0, 1.0, 1.0), gloss)
    if ref is None:
        return f"model '{model.type_name}' has no physical reference"
    if ref.integrator is not None or ref.interior is not None:
        return f"model '{model.type_name}''s physical reference is a volume render ({ref.description}), not a BSDF to project"
    if ref.stochastic:
        return f"model '{model.type_name}''s physical reference is a stochastic render ({ref.description}), not an RGB BSDF to project"
    if ref.variant != "llvm_ad_rgb":
        return f"model '{model.type_name}''s physical reference needs {ref.variant} ({ref.description}), not an RGB BSDF"
    if ref.bsdf.get("type", "").startswith("atlasgen_"):
        return f"model '{model.type_name}''s physical reference is atlasgen's own plugin ({ref.description})"
    return ref


def check_physical_fit(model: Model, values: dict, path) -> None:
    """Raise :class:`MaterialError` naming ``from`` unless ``from = "physical"`` can bake the material:
    the model fits its physical reference itself (:meth:`~atlasgen.models.base.Model.fit_physical`)
    and sees no problem, or that reference is one plain BSDF to project."""
    if _fits_itself(model):
        problem = model.physical_fit_problem(values)
    else:
        ref = plain_bsdf_reference(model, values)
        problem = ref if isinstance(ref, str) else None
    if problem is not None:
        raise MaterialError(path, "from", f'expected "model" for this material: {problem}')


def _fits_itself(model: Model) -> bool:
    return type(model).fit_physical is not Model.fit_physical


def mitsuba_f_cos(bsdf_dict: dict, path="<bsdf>", field: str = "bsdf"):
    """f cos(theta_l) of a Mitsuba BSDF dict as a NumPy function of unit (l, v) ``(N, 3)``."""
    bsdf = load_mitsuba_bsdf(bsdf_dict, path, field)
    return lambda l, v: evaluate_mitsuba_f_cos(bsdf, l, v)


@lru_cache(maxsize=32)
def _fitted(bsdf_json: str, gloss_json: str, files: tuple):
    rgba, info = fit_slice(mitsuba_f_cos(json.loads(bsdf_json)), json.loads(gloss_json))
    rgba.setflags(write=False)
    return rgba, info


def fitted_bsdf_slice(bsdf_dict: dict, gloss=None):
    """The (cached) slice fitted to a Mitsuba BSDF dict and its fit description (:func:`fit_slice`); the files the
    dict names are part of the key (:func:`~atlasgen.io.referenced_files.files_state`)."""
    return _fitted(json.dumps(bsdf_dict, sort_keys=True), json.dumps(gloss), files_state(bsdf_dict))


def bake_from_physics(model: Model, values: dict, path="<material>", gloss: float = FIT_GLOSS) -> SliceSet:
    """One slice fitted to ``model``'s physical reference for the renderer gloss ``gloss`` (``from = "physical"``).

    A model that fits its reference itself (:meth:`~atlasgen.models.base.Model.fit_physical`)
    does; any other's reference is one plain BSDF, projected by :func:`fit_slice`.
    """
    check_physical_fit(model, values, path)
    if _fits_itself(model):
        return model.fit_physical(values, float(gloss))
    # The reference at the fit's gloss: a model whose roughness is the g-buffer's (fresnel)
    # describes a different BSDF at each gloss.
    ref = plain_bsdf_reference(model, values, float(gloss))
    rgba, info = fitted_bsdf_slice(ref.bsdf, float(gloss))
    fit = {"from": "physical", "reference": ref.description, **info}
    return SliceSet(np.array(rgba).reshape(1, HEIGHT, WIDTH, 4), extra={"fit": fit})


class FittedSlice(Model):
    """A ``from = "physical"`` material as validation sees it: its slice is the fit, not the closed form.

    :meth:`evaluate` samples the float slice fitted for renderer gloss ``gloss`` as the
    renderer does, so the model reference (the renderer's equation with the exact slice)
    and the float rebuild measure what the atlas costs against the fit; the physical
    reference is the wrapped model's, the material the fit reproduces.
    """

    def __init__(self, model: Model, gloss: float):
        self.model, self.gloss = model, float(gloss)
        self.type_name, self.params, self.reference = model.type_name, model.params, model.reference
        self.physical_omissions, self.validation_goals = model.physical_omissions, model.validation_goals

    def bake(self, values: dict) -> SliceSet:
        return bake_from_physics(self.model, values, gloss=self.gloss)

    #: Fitted slices by (type, values, gloss), shared by every instance: validation makes one
    #: per Mitsuba plugin instance, and a fit can take seconds (a spectral or volume reference).
    _tables: ClassVar[dict] = {}

    def _key(self, values: dict) -> tuple:
        return (self.type_name, json.dumps(values, sort_keys=True, default=str), self.gloss)

    def use_table(self, values: dict, table) -> None:
        """Take ``table`` ``(H, W, 4)`` as the fit of ``values`` (the bake cache's float slice of the very
        material, found by its content hash and the bake code), so that no instance fits it again."""
        FittedSlice._tables[self._key(values)] = np.asarray(table, dtype=np.float64)

    def _table(self, values: dict) -> np.ndarray:
        key = self._key(values)
        if key not in FittedSlice._tables:
            FittedSlice._tables[key] = np.asarray(self.bake(values).values[0], dtype=np.float64)
        return FittedSlice._tables[key]

    def evaluate(self, values, n_dot_l, n_dot_v):
        nl, nv = np.broadcast_arrays(np.asarray(n_dot_l, dtype=np.float64), np.asarray(n_dot_v, dtype=np.float64))
        return sample_slice(self._table(values), nl, nv)

    def radiance_rebuilds(self, entry, atlas, float_slices=None):
        # The float rebuild samples the fit itself (computed once per process), not a second fit.
        table = self._table(entry.params) if float_slices is None else float_slices[0]
        return Model.radiance_rebuilds(self, entry, atlas, np.asarray(table)[None])

    def model_reference(self, values: dict, albedo=(1.0, 1.0, 1.0), gloss: float = 0.5):
        # Fit now, before any Mitsuba scene holds the reference's plugin: a fit that renders
        # (sss) cannot run inside the render that evaluates it, nor beside live Python plugins.
        self._table(values)
        ref = Model.model_reference(self, values, albedo, gloss)
        material = {**json.loads(ref.bsdf["material"]), "fit_gloss": self.gloss}
        return type(ref)(
            {**ref.bsdf, "material": json.dumps(material, sort_keys=True)},
            f"{self.type_name} slice fitted from physics (gloss {self.gloss:g}), exact, in the renderer's equation",
        )

    def physical_reference(self, values: dict, albedo=(1.0, 1.0, 1.0), gloss: float = 0.5):
        return self.model.physical_reference(values, albedo, gloss)
