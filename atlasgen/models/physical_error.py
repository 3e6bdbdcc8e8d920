"""Error against the physical reference of every representation a material could be baked as.

A material's *physical* reference is one BRDF f_p: a separable material's source (its
closed form or Mitsuba BSDF is the physical material the factors approximate), a LUT
model's own NumPy f cos (:meth:`~atlasgen.models.base.Model.physical_f_cos`: the thin
sheet, the spectral thin film, which its ``from = "physical"`` fit fits), or its plain
Mitsuba BSDF (:func:`atlasgen.models.physical_fit.plain_bsdf_reference`). A reference
that is no BRDF (skin's volume) has no candidates, and says why
(:attr:`~atlasgen.models.base.Model.no_physical_f_cos`).
Each candidate representation r is drawn by the renderer as some f_r cos(theta_l), and its
error is the same figure the separable model reports (:mod:`atlasgen.separable.error`):

    e_r^2 = int int |f_r cos - f_p cos|^2 dw_l dw_v / int int |f_p cos|^2 dw_l dw_v,

estimated on the importance-sampled pairs of :func:`atlasgen.separable.error.error_sample_for`
(seed :data:`~atlasgen.separable.error.ERROR_SEED`) with its delta-method standard error
(Owen 2013, sec. 9.2). For a reference that transmits (:attr:`PhysicalBrdf.transmits`) the
integrals run over l in the whole sphere (``sphere=True``): the renderer draws a slice's RGB
for N.L < 0 too, and light from behind is part of the material. Every parameter of a candidate (a LUT's renderer gloss, a
separable material's grid and target) is chosen on another sample (the fit's texel grid
with stratified azimuths, or the seed :data:`~atlasgen.separable.error.SELECTION_SEED`),
so the reported error is not biased down by the choice.

The LUT of the renderer's equation (docs/atlas-format.md) is

    f_r cos = A.rgb / pi + A.a * D(N.H) V(N.L, N.V) max(N.L, 0),   A = the slice at (N.L, N.V),

(albedo 1: the physical reference carries the colour), with A read bilinearly as the
atlas sampler reads it (:func:`atlasgen.optics.interpolation.sample_slice`).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass

import numpy as np

from atlasgen.io.fields import validate_params
from atlasgen.models.base import Model, PhysicalFCos
from atlasgen.models.physical_fit import FIT_GLOSS, FIT_SUPERSAMPLING, fit_slice, plain_bsdf_reference
from atlasgen.models.physical_lut import LUT_GLOSSES, fit_lut, lut_errors, pair_geometry, stored_slice
from atlasgen.models.separable import ANALYTIC_SHADER_SOURCES, MAX_AUTO_TERMS, Separable, stored_factors
from atlasgen.separable.approximate import reference_values
from atlasgen.separable.auto import cost_key, read_lighting_cost
from atlasgen.separable.error import ERROR_SEED, MET_SIGMAS, error_sample_for, measure_errors
from atlasgen.separable.rebuild import evaluate_factors
from atlasgen.separable.source import BrdfSource, make_source

__all__ = [
    "PhysicalBrdf",
    "physical_brdf",
    "analytic_twin",
    "physical_candidates",
    "candidates_key",
]

#: Version of the candidate list's content: part of the report cache's key.
CANDIDATES_VERSION = 8


@dataclass(frozen=True)
class PhysicalBrdf:
    """A material's physical reference: separable-model source parameters of it (``params``, or
    ``None`` where no separable source holds it), its description, and the model's NumPy f cos
    where the model supplies one (``numpy``, :meth:`~atlasgen.models.base.Model.physical_f_cos`)."""

    params: dict | None
    description: str
    numpy: PhysicalFCos | None = None

    def source(self) -> BrdfSource:
        """The reference as a :class:`~atlasgen.separable.source.BrdfSource`: the model's own f cos where it gives one."""
        if self.numpy is None:
            return make_source(self.params)
        return BrdfSource("physical", evaluate_f_cos=self.numpy.f_cos, alpha=self.numpy.alpha)

    @property
    def transmits(self) -> bool:
        """Whether f cos is non-zero for l below the surface (then the error covers the whole sphere of l)."""
        return self.numpy is not None and self.numpy.transmits

    @property
    def no_source(self) -> str:
        """Why there are no separable candidates ("" where there are)."""
        return "" if self.params is not None else (self.numpy.no_source or "no separable source holds this reference")


#: The supersampled fits from physics (:func:`~atlasgen.models.physical_fit.fit_slice`'s ``footprint``):
#: the centre fitted to f cos averaged over the texel's 4x4 footprint, and the texel fitted to f cos
#: at pairs spread over it; each label, float then 8-bit.
_SUPERSAMPLED_FITS = (
    ("mean", f"lut: fitted from physics, {FIT_SUPERSAMPLING}x{FIT_SUPERSAMPLING} supersampled", "lut-physical-supersampled"),
    ("fit", f"lut: fitted from physics over the {FIT_SUPERSAMPLING}x{FIT_SUPERSAMPLING} footprint", "lut-physical-footprint"),
)


def physical_brdf(model: Model, values: dict, gloss: float = FIT_GLOSS):
    """The physical reference of ``model`` with ``values`` as a :class:`PhysicalBrdf`, or why there is none (a string).

    A model that is its own physical material (:meth:`~atlasgen.models.base.Model.physical_brdf_source`)
    gives its source; one that gives its reference as NumPy f cos
    (:meth:`~atlasgen.models.base.Model.physical_f_cos`) that function, with the separable source of
    the same BRDF where there is one; any other needs a plain Mitsuba BSDF (:func:`plain_bsdf_reference`),
    all for an object of renderer gloss ``gloss`` (a table model's physical coat has the renderer's
    roughness). A model whose reference is no BRDF says why (``no_physical_f_cos``).
    """
    own = model.physical_brdf_source(values)
    if own is not None:
        params, description = own  # already the model's validated parameters
        return PhysicalBrdf(dict(params), description)
    numpy_ref = model.physical_f_cos(values, gloss)
    if numpy_ref is not None:
        params = None
        if numpy_ref.source is not None:
            params = validate_params(Separable.params, numpy_ref.source, "<physical>")
        return PhysicalBrdf(params, numpy_ref.description, numpy_ref)
    ref = plain_bsdf_reference(model, values, gloss)
    if isinstance(ref, str):
        return model.no_physical_f_cos or ref
    params = validate_params(Separable.params, {"source": "mitsuba", "bsdf": ref.bsdf}, "<physical>")
    return PhysicalBrdf(params, ref.description)


def analytic_twin(params: dict) -> dict | None:
    """Separable-source parameters of the lighting shader's closed form equal to a Mitsuba BSDF, where one
    is: ``diffuse`` with an RGB or uniform reflectance rho is Lambert's rho / pi; ``None`` otherwise."""
    if params.get("source") != "mitsuba":
        return None
    bsdf = params.get("bsdf") or {}
    reflectance = bsdf.get("reflectance", {"type": "uniform", "value": 0.5})
    if bsdf.get("type") != "diffuse" or not isinstance(reflectance, dict) or reflectance.get("type") not in ("rgb", "uniform"):
        return None
    rho = np.broadcast_to(np.asarray(reflectance.get("value"), dtype=np.float64), (3,))
    return validate_params(Separable.params, {"source": "lambert", "diffuse": [float(x) for x in rho]}, "<analytic twin>")


def _model_f_cos(model: Model, values: dict, gloss: float, l, v):
    nl, nv, nh, degenerate = pair_geometry(l, v)
    return model.renderer_f_cos(values, 1.0, gloss, nl, nv, nh, degenerate)


def _entry(label: str, key: str, errors: dict, table, kind: str, **more) -> dict:
    return {"representation": label, "cost_key": key, "cost": table.cost(key), "error": errors["relative_rms"],
            "error_se": errors.get("relative_rms_se", 0.0), "kind": kind, **more}  # fmt: skip


def _sphere_errors_by_terms(factors, reference: np.ndarray, sample) -> list[dict]:
    """8-bit errors of the first K terms (K = 1 .. all) with the transmission slice, at ``sample``'s
    pairs (l over the whole sphere): the whole f cos the include rebuilds, against ``reference``."""
    out = []
    for k in range(1, min(factors.terms, MAX_AUTO_TERMS) + 1):
        approx = evaluate_factors(factors.truncated(k), None, sample.l, sample.v, cosine=True)
        out.append({"terms": k, **measure_errors(reference, approx, sample.weight)})
    return out


def candidates_key(model: Model, values: dict, gloss: float | None = None) -> str:
    """A digest of what :func:`physical_candidates` depends on (for a report's cache)."""
    table = read_lighting_cost()
    text = json.dumps({"type": model.type_name, "values": values, "gloss": gloss, "version": CANDIDATES_VERSION,
                       "costs": table.costs, "device": table.device}, sort_keys=True, default=str)  # fmt: skip
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def physical_candidates(model: Model, values: dict, supersample=None, srgb: bool = True, gloss: float | None = None) -> dict:
    """Every representation ``values`` could be baked as, with its run-time cost and its error against
    the physical reference (relative RMS of f cos, standard error), or why there is no reference.

    Returns ``{"reference", "estimator", "pairs", "seed", "sphere", "cost_device", "cost_unit", "gloss",
    "candidates": [{"representation", "cost_key", "cost", "error", "error_se", "kind", ...}],
    "skipped": [{"representation", "reason"}]}`` or ``{"reference": None, "reason": ...}``.
    ``sphere``: the pairs' l covers the whole sphere (a reference that transmits). ``gloss`` is the
    renderer gloss the material is drawn with (a material fitted from physics: its ``fit.gloss``): the
    physical reference's and every LUT candidate's. Without it, a table model's is
    :data:`~atlasgen.models.physical_fit.FIT_GLOSS`, and a BRDF that is its own physical material
    (separable) lets the fitted slice choose among :data:`~atlasgen.models.physical_lut.LUT_GLOSSES`.
    Candidates:

    - for a table model (one (N.L, N.V) slice): its closed form drawn by the renderer at the fitted
      gloss with no texels (the limit of a finer table), its point-sampled slice after 8-bit storage,
      and with ``supersample(model, values, factor)`` given (:func:`atlasgen.bake.adaptive.bake_supersampled`)
      the 4x4-supersampled slice where it differs from the point-sampled one by more than 2 SE;
    - the slice fitted from physics, in float and after 8-bit storage: :func:`fit_lut` for a BRDF
      source, :func:`~atlasgen.models.physical_fit.fit_slice` of the model's own f cos (what its
      ``from = "physical"`` bake fits) otherwise;
    - the slice fitted from physics *supersampled*, at the same gloss, in float and 8-bit: each texel's
      centre fitted to f cos averaged over its 4x4 footprint (``fit_slice(..., supersampling=4)``), and
      each texel fitted to f cos at its pairs spread over that footprint (``footprint="fit"``);
    - K = 1 .. 8 separable terms of the physical BRDF (8-bit estimate, grid and target chosen on the
      selection sample: :meth:`atlasgen.models.separable.Separable.bake` with a budget no K meets),
      where a separable source holds the reference (else ``skipped`` says why). For a reference that
      transmits, the bake adds a transmission slice, and each K is measured here with it on the
      sphere's pairs (the first K of the terms chosen for K = 8, and the slice);
    - the analytic shader where the physical BRDF is a closed form it evaluates (exact: error 0), or a
      Mitsuba BSDF it has in closed form (:func:`analytic_twin`; its error measured like the others').
    """
    own = model.physical_brdf_source(values) is not None
    drawn = FIT_GLOSS if gloss is None else float(gloss)
    brdf = physical_brdf(model, values, drawn)
    if isinstance(brdf, str):
        return {"reference": None, "reason": brdf}
    table = read_lighting_cost()
    source = brdf.source()
    sample = error_sample_for(source, ERROR_SEED, sphere=brdf.transmits)
    reference, _ = reference_values(source, sample)
    if brdf.numpy is None:
        fitted, info = fit_lut(brdf.params, LUT_GLOSSES if gloss is None and own else (drawn,), srgb=srgb)
    else:  # what the model's fit_physical bakes: its own f cos at the drawn gloss
        fitted, info = fit_slice(brdf.numpy.f_cos, drawn, srgb=srgb)
    gloss = float(info["gloss"])
    lut = cost_key("lut")
    out, skipped = [], []
    if not model.custom_lighting:
        exact = measure_errors(reference, _model_f_cos(model, values, gloss, sample.l, sample.v), sample.weight)
        out.append(_entry("lut: model closed form (no texels)", lut, exact, table, "lut-model-exact", gloss=gloss))
        point = stored_slice(model.bake(values).values[0], srgb)
        point_errors = lut_errors(point, gloss, reference, sample)
        out.append(_entry("lut: model, point-sampled, 8-bit", lut, point_errors, table, "lut-model-point", gloss=gloss))
        if supersample is not None:
            sup = lut_errors(stored_slice(supersample(model, values, 4), srgb), gloss, reference, sample)
            se = np.hypot(sup["relative_rms_se"], point_errors["relative_rms_se"])
            if abs(sup["relative_rms"] - point_errors["relative_rms"]) > MET_SIGMAS * se:
                out.append(_entry("lut: model, 4x4 supersampled, 8-bit", lut, sup, table, "lut-model-supersampled", gloss=gloss))
    out.append(_entry("lut: fitted from physics", lut, lut_errors(fitted, gloss, reference, sample), table, "lut-physical-float",
                      gloss=gloss))  # fmt: skip
    out.append(_entry("lut: fitted from physics, 8-bit", lut, lut_errors(stored_slice(fitted, srgb), gloss, reference, sample),
                      table, "lut-physical", gloss=gloss))  # fmt: skip
    # The same fit at the same gloss (chosen on the selection sample) over each texel's footprint.
    for footprint, label, kind in _SUPERSAMPLED_FITS:
        boxed, _ = fit_slice(source.f_cos, gloss, srgb=srgb, supersampling=FIT_SUPERSAMPLING, footprint=footprint)
        more = {"gloss": gloss, "supersampling": FIT_SUPERSAMPLING, "footprint": footprint}
        out.append(_entry(label, lut, lut_errors(boxed, gloss, reference, sample), table, f"{kind}-float", **more))
        out.append(_entry(f"{label}, 8-bit", lut, lut_errors(stored_slice(boxed, srgb), gloss, reference, sample), table,
                          kind, **more))  # fmt: skip
    if brdf.params is None:
        skipped.append({"representation": "separable", "reason": brdf.no_source})
    else:
        baked = Separable().bake({**brdf.params, "terms": None, "max_error": 1e-9, "representation": "separable"})
        rep = baked.extra["representation"]
        by_terms = baked.extra["errors"]["estimated_8bit_srgb_by_terms"][rep["target"]]
        if brdf.transmits:  # the bake's figures cover the upper hemispheres: measure terms + transmission slice here
            by_terms = _sphere_errors_by_terms(stored_factors(baked, srgb), reference, sample)
        for e in by_terms:
            if e["terms"] <= MAX_AUTO_TERMS:
                key = cost_key("separable", e["terms"])
                out.append(_entry(key, key, e, table, "separable", grid=rep["sampling_grid"], target=rep["target"]))
    twin = None if brdf.params is None else analytic_twin(brdf.params)
    if brdf.params is not None and brdf.params["source"] in ANALYTIC_SHADER_SOURCES:
        key = cost_key("analytic", brdf.params["source"])
        out.append(_entry(key, key, {"relative_rms": 0.0, "relative_rms_se": 0.0}, table, "analytic"))
    elif twin is not None:  # a Mitsuba BSDF the shader has in closed form: measured, not assumed exact
        key = cost_key("analytic", twin["source"])
        measured = measure_errors(reference, make_source(twin).f_cos(sample.l, sample.v), sample.weight)
        out.append(_entry(key, key, measured, table, "analytic"))
    else:
        skipped.append({"representation": "analytic", "reason": "the lighting shader has no closed form of this reference"})
    return {"reference": brdf.description, "estimator": sample.estimator, "pairs": sample.count, "seed": sample.seed,
            "sphere": sample.sphere, "cost_device": table.device, "cost_unit": table.unit, "gloss": gloss,
            "candidates": out, "skipped": skipped}  # fmt: skip
