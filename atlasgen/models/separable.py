"""Kautz-McCool separable BRDFs: any BRDF factored by SVD into K atlas slices.

f(l, v) cos(theta_l) ~ sum_k g_k(pi1) h_k(pi2) (Kautz & McCool 1999), one slice per
term. The math lives in :mod:`atlasgen.separable`; this module is the TOML schema
and the bake/encode/finalize hooks. Mitsuba is imported only for ``source = "mitsuba"``.
"""

from __future__ import annotations

import json
import time
from dataclasses import replace

import numpy as np

from atlasgen.errors import ManifestError, MaterialError, shorten
from atlasgen.io.atlas import as_atlas
from atlasgen.io.fields import Param
from atlasgen.io.manifest import AnalyticRepresentation, LutRepresentation
from atlasgen.models.base import (
    BRDF_REFERENCE,
    THIN_FILM_REFERENCE,
    DraftSlices,
    EncodedSlices,
    Model,
    RadianceRebuild,
    Reference,
    SliceSet,
    encode_scaled,
)
from atlasgen.models.iridescent import Iridescent
from atlasgen.models.materialx import check_materialx_spec, describe_materialx, materialx_mitsuba_bsdf
from atlasgen.models.physical_lut import fit_lut, lut_errors, stored_slice
from atlasgen.optics.interpolation import sample_slice
from atlasgen.optics.quantize import dequantize_rgba, quantize_rgba
from atlasgen.optics.specular import half_vector_cosine, renderer_f_cos
from atlasgen.optics.thin_film import ENERGY_MODES, FILM_DEFAULTS
from atlasgen.separable.analytic import analytic_f_cos_world
from atlasgen.separable.approximate import (
    GRID_RESOLUTIONS,
    choose_approximation,
    reference_values,
    report_approximation,
    search_terms,
)
from atlasgen.separable.auto import choose_representation, cost_key, read_lighting_cost
from atlasgen.separable.error import (
    ERROR_SEED,
    MET_SIGMAS,
    SELECTION_SEED,
    error_sample_for,
    measure_errors,
    relative_log_errors,
    upper_bound,
)
from atlasgen.separable.mitsuba_source import load_mitsuba_bsdf, transmitted_fractions
from atlasgen.separable.parametrization import PARAMETRIZATIONS
from atlasgen.separable.rebuild import evaluate_factors, factors_from_slices, read_separable_factors
from atlasgen.separable.source import film_transmits, make_source
from atlasgen.separable.storage import CHANNEL_LAYOUT, FACTOR_RESOLUTION, encode_factor_slices, factors_to_slices
from atlasgen.separable.transmission import encode_transmission_slice, transmission_slice
from atlasgen.shaders.lang import Function, Let, Return, float_literal
from atlasgen.shaders.separable import TARGETS, separable_declarations, separable_table_bytes
from atlasgen.shaders.separable_analytic import DISTRIBUTION_CODES, FRESNEL_CODES, analytic_call, analytic_declarations

__all__ = ["Separable", "MAX_AUTO_TERMS", "ANALYTIC_SHADER_SOURCES", "LUT_F_COS", "analytic_params", "fit_gloss", "FILM_KEYS",
           "representation_radiance",
           "check_film", "stored_factors"]  # fmt: skip

MAX_AUTO_TERMS = 8  # max_error mode tries K = 1 .. 8 (atlasgen.separable.approximate)
#: ``representation = "auto"`` without an ``error_budget``: the separable default budget.
DEFAULT_BUDGET = 0.02
#: Largest fixed ``terms``: the rank of a 32 x 1024 factor matrix.
MAX_TERMS = 32

SOURCES = ("ggx", "beckmann", "blinn_phong", "ward", "lambert", "mitsuba", "thin_film", "materialx")
#: Sources the lighting shader can evaluate in closed form (``representation = "analytic"``).
ANALYTIC_SHADER_SOURCES = ("ggx", "beckmann", "lambert")
REPRESENTATIONS = ("separable", "analytic", "auto", "lut")
#: The fields each source reads (:func:`atlasgen.separable.source.make_source`); a file giving one its
#: source does not read is refused (:meth:`Separable.unused_fields`).
SOURCE_FIELDS = {
    "ggx": {"alpha", "fresnel", "f0", "ior", "specular", "diffuse"},
    "beckmann": {"alpha", "fresnel", "f0", "ior", "specular", "diffuse"},
    "blinn_phong": {"exponent", "specular", "diffuse"},
    "ward": {"alpha", "specular", "diffuse"},
    "lambert": {"diffuse"},
    "mitsuba": {"bsdf"},
    "thin_film": {"film", "alpha", "diffuse"},
    "materialx": {"materialx"},
}


#: Keys of a ``source = "thin_film"`` material's ``film`` table (the iridescent model's parameters
#: of the same names and ranges); the first three are required.
FILM_KEYS = ("thickness", "film_ior", "base_ior", "base_k", "film_strength", "film_split", "energy",
             "backlight", "backlight_colour", "backlight_distortion", "backlight_power")  # fmt: skip


def check_film(film, path) -> dict:
    """A ``film`` table checked against the iridescent model's parameters of the same names:
    the stack (``thickness``, ``film_ior``, ``base_ior`` required, ``base_k``) and how the
    film's reflection splits (``film_strength``, ``film_split``, ``energy``) and the light it
    transmits from behind (``backlight``, ``backlight_colour``, ``backlight_distortion``,
    ``backlight_power``: a transmission slice after the terms); returns it with the defaults
    filled in."""
    if not isinstance(film, dict):
        raise MaterialError(
            path, "film", f"expected a table such as {{thickness = 420.0, film_ior = 1.45, base_ior = 1.8}}, got {film!r}"
        )
    params = {p.name: p for p in Iridescent.params if p.name in FILM_KEYS}
    # A film table may also be the iridescent model's physical film, whose base is coupled to the lobe's albedo.
    params["energy"] = replace(params["energy"], choices=ENERGY_MODES)
    for key in film:
        if key not in params:
            raise MaterialError(path, f"film.{key}", f"unknown; expected one of {', '.join(FILM_KEYS)}")
    for key in FILM_KEYS[:3]:
        if key not in film:
            raise MaterialError(path, f"film.{key}", "missing; the film stack needs thickness, film_ior and base_ior")
    out = {key: params[key].coerce(film[key], path, name=f"film.{key}") if key in film else params[key].default
           for key in FILM_KEYS}  # fmt: skip
    Iridescent().check(out, path)  # the base must reflect
    return out


def _parametrization_names():
    return tuple(PARAMETRIZATIONS)


def _shown_value(value) -> str:
    """A flattened input's value as the document writes one: ``0.5`` or ``0.8, 0.2, 0.1``.

    >>> _shown_value([0.8, 0.2, 0.1]), _shown_value(1.0), _shown_value(True)
    ('0.8, 0.2, 0.1', '1', 'true')
    """
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list | tuple):
        return ", ".join(_shown_value(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def _transmits(values: dict) -> bool:
    """Whether the material's source sends light through from behind (a thin film's back-light):
    its slices are then K terms and one transmission slice."""
    return values["source"] == "thin_film" and film_transmits(values["film"])


def _error_samples(source):
    """The selection sample and the independent report sample for one source (atlasgen.separable.error)."""
    return error_sample_for(source, SELECTION_SEED), error_sample_for(source, ERROR_SEED)


def _reference(source, sample):
    """f cos at a sample's pairs, with non-finite values masked (and counted)."""
    return reference_values(source, sample)


class Separable(Model):
    """A BRDF approximated by K separable terms, f cos(theta_l) ~ sum_k g_k(pi1) h_k(pi2).

    Reference: J. Kautz and M. D. McCool, "Interactive Rendering with Arbitrary BRDFs
    using Separable Approximations", EGWR 1999. The factors, layout, parametrization and
    error measures are described in docs/separable.md.
    """

    type_name = "separable"
    reference = "Kautz & McCool 1999; f cos ~ sum_k g_k(pi1) h_k(pi2), truncated SVD"
    # The slices hold factors, not an (N.L, N.V) table: the lighting pass rebuilds f cos with
    # the include's code, and the bake's error claims take the place of the LUT goals.
    custom_lighting = True
    validation_goals = False
    model_reference_is_physical = True
    params = (
        Param("source", "ggx", "choice", choices=SOURCES, doc="the BRDF to factor"),
        # Below 1e-6 the lobe's peak overflows the float32 evaluation (alpha^4 underflows near 1e-10),
        # so the source yields NaN and inf, and the refusal named the wrong field; down to it, a lobe
        # sharper than the sampling resolves bakes with its error warned about.
        Param("alpha", 0.2, "float", lo=1e-6, hi=4.0, doc="roughness (GGX, Beckmann, Ward), at least 1e-6"),
        Param("fresnel", "schlick", "choice", choices=("schlick", "exact", "none"), doc="microfacet Fresnel"),
        Param("f0", (0.04, 0.04, 0.04), "colour", doc="Schlick's normal-incidence reflectance"),
        Param("ior", 1.5, "float", lo=1.0, hi=10.0, lo_open=True, doc="dielectric index for exact Fresnel"),
        Param("specular", (1.0, 1.0, 1.0), "colour", doc="specular lobe colour"),
        Param("diffuse", (0.0, 0.0, 0.0), "colour", doc="Lambertian colour added (the whole BRDF for 'lambert')"),
        Param("exponent", 100.0, "float", lo=0.0, hi=1e6, lo_open=True, doc="Blinn-Phong exponent"),
        Param("bsdf", None, "table", doc="a Mitsuba 3 BSDF dict (source = 'mitsuba')"),
        Param("film", None, "table", doc="the film stack and split, as the iridescent model names them (source = 'thin_film')"),
        Param(
            "materialx",
            None,
            "table",
            doc="a MaterialX surface shader (source = 'materialx', written by the .mtlx reader): document, material, "
            "category, oracle_inputs",
        ),
        Param("terms", None, "int", lo=1, hi=MAX_TERMS, doc="fixed number of terms K (one slice each)"),
        Param(
            "max_error",
            None,
            "float",
            lo=0.0,
            hi=10.0,
            lo_open=True,
            doc="relative RMS budget: the cheapest K <= 8 and grid meeting it",
        ),
        Param(
            "grid",
            None,
            "int",
            lo=4,
            hi=128,
            doc="fixed sampling grid, texels per factor axis (default: 32, or 16 or 32 chosen by the budget)",
        ),
        Param("parametrization", "half_diff", "choice", choices=_parametrization_names(), doc="pi1 / pi2 split"),
        Param("factorization", "svd", "choice", choices=("svd", "nmf", "nd"), doc="SVD, NMF, or Kautz-McCool ND (1 term)"),
        Param(
            "target",
            "auto",
            "choice",
            choices=("auto", "f_cos", "f_proxy"),
            doc="factor f cos, f times a cosine proxy, or whichever errs less in 8 bits",
        ),
        Param(
            "reflection_only",
            False,
            "bool",
            doc="bake only the reflection of a transmissive Mitsuba BSDF (the dropped fraction is recorded)",
        ),
        Param(
            "representation",
            "separable",
            "choice",
            choices=REPRESENTATIONS,
            doc="K separable terms; 'analytic': the closed form evaluated in the lighting shader (ggx, beckmann, lambert); "
            "'auto': the cheapest in run-time cost meeting error_budget; 'lut': one slice fitted to the source",
        ),
    )

    # -- validation ---------------------------------------------------------------------------
    def check(self, values: dict, path) -> None:
        if values["terms"] is not None and values["max_error"] is not None:
            raise MaterialError(path, "max_error", "give either 'terms' or 'max_error', not both")
        if values["factorization"] == "nd" and (values["terms"] or 1) != 1:
            raise MaterialError(path, "terms", f"expected 1 with factorization = 'nd' (one term), got {values['terms']}")
        if values["source"] == "mitsuba":
            if values["bsdf"] is None:
                raise MaterialError(
                    path,
                    "bsdf",
                    "missing; expected a Mitsuba BSDF table, e.g. {type = \"roughconductor\"}, with source = 'mitsuba'",
                )

            load_mitsuba_bsdf(values["bsdf"], path, reflection_only=values["reflection_only"],
                              anisotropic='or use type = "bsdf" with accept_anisotropy = true (a separable material has no such consent)',
                              rough_only='or use type = "bsdf" with rough_only = true (a separable material has no such consent)')  # fmt: skip
        elif values["bsdf"] is not None:
            raise MaterialError(path, "bsdf", f"only used with source = 'mitsuba', but source is {values['source']!r}")
        if values["source"] == "thin_film":
            if values["film"] is None:
                raise MaterialError(path, "film", "missing; expected a table such as {thickness = 420.0, film_ior = 1.45, "
                                                  "base_ior = 1.8} with source = 'thin_film'")  # fmt: skip
            values["film"] = check_film(values["film"], path)  # the defaults filled in, as every user of it reads them
        elif values["film"] is not None:
            raise MaterialError(path, "film", f"only used with source = 'thin_film', but source is {values['source']!r}")
        if values["source"] == "materialx":
            if values["materialx"] is None:
                raise MaterialError(
                    path, "materialx", "missing; expected the table the .mtlx reader writes, with source = 'materialx'"
                )
            values["materialx"] = check_materialx_spec(values["materialx"], path)
        elif values["materialx"] is not None:
            raise MaterialError(path, "materialx", f"only used with source = 'materialx', but source is {values['source']!r}")
        if values["representation"] == "lut" and _transmits(values):
            raise MaterialError(path, "representation", "'lut' holds reflection only, but film.backlight > 0 transmits light")
        if values["representation"] == "lut" and values["terms"] is not None:
            raise MaterialError(path, "representation", "'lut' is one slice; expected no 'terms'")
        if values["reflection_only"] and values["source"] != "mitsuba":
            raise MaterialError(path, "reflection_only", f"only used with source = 'mitsuba' (a transmissive BSDF), "
                                                         f"but source is {values['source']!r}")  # fmt: skip
        if values["representation"] == "analytic" and values["source"] not in ANALYTIC_SHADER_SOURCES:
            raise MaterialError(
                path,
                "representation",
                f"'analytic' needs a source the shader evaluates "
                f"({', '.join(ANALYTIC_SHADER_SOURCES)}), got source = {values['source']!r}",
            )
        if values["representation"] == "auto" and _transmits(values):
            raise MaterialError(
                path,
                "representation",
                "'auto' weighs reflection only, but film.backlight > 0 "
                "transmits light from behind; give terms or max_error (K terms and a transmission slice)",
            )
        if values["representation"] == "auto" and values["terms"] is not None:
            raise MaterialError(path, "representation", "'auto' chooses the representation and K; expected no 'terms'")

    # -- LUT-style evaluation (previews) ---------------------------------------------------------
    def apply_budget(self, values: dict, budget: float, path) -> dict:
        """``error_budget`` is this model's ``max_error``: the fewest terms whose relative RMS meets it."""
        if values["terms"] is not None:
            raise MaterialError(path, "error_budget", "expected either 'terms' or an error budget, not both")
        if values["max_error"] is not None and values["max_error"] != budget:
            raise MaterialError(path, "error_budget", "expected either 'max_error' or 'error_budget', not both")
        return {**values, "max_error": budget}

    def evaluate(self, values, n_dot_l, n_dot_v):
        """RGB = the exact f cos(theta_l) with l and v coplanar on opposite sides of n; A = 0.

        A separable material has no single (N.L, N.V) table; this in-plane cut is what a
        preview can show. The atlas slices themselves hold the factors (see :meth:`bake`).
        """
        nl = np.asarray(n_dot_l, dtype=np.float64)
        nv = np.asarray(n_dot_v, dtype=np.float64)
        nl, nv = np.broadcast_arrays(nl, nv)
        sl = np.sqrt(np.maximum(1.0 - nl * nl, 0.0))
        sv = np.sqrt(np.maximum(1.0 - nv * nv, 0.0))
        l = np.stack([-sl, np.zeros_like(nl), np.maximum(nl, 0.0)], axis=-1)
        v = np.stack([sv, np.zeros_like(nv), nv], axis=-1)
        l = l / np.maximum(np.linalg.norm(l, axis=-1), 1e-300)[..., None]
        rgb = make_source(values).f_cos(l, v)
        rgb = np.where((nl > 0.0)[..., None] & np.isfinite(rgb), rgb, 0.0)
        out = np.zeros(nl.shape + (4,))
        out[..., :3] = rgb
        return out

    def unused_fields(self, values: dict) -> dict[str, str]:
        """The source's fields another source reads (:data:`SOURCE_FIELDS`), and the Fresnel choice's:
        ``f0`` is read with ``fresnel = "schlick"`` only, ``ior`` with ``"exact"`` only."""
        source = values["source"]
        out = {}
        for key in sorted(set().union(*SOURCE_FIELDS.values()) - SOURCE_FIELDS[source]):
            readers = [s for s, keys in SOURCE_FIELDS.items() if key in keys]
            out[key] = f"with source = {' or '.join(repr(s) for s in readers)}, but source is {source!r}"
        if "fresnel" in SOURCE_FIELDS[source]:
            for key, fresnel in (("f0", "schlick"), ("ior", "exact")):
                if values["fresnel"] != fresnel:
                    out[key] = f"with fresnel = {fresnel!r}, but fresnel is {values['fresnel']!r}"
        return out

    def fit_limits(self, values: dict) -> list[str]:
        """A MaterialX source's lobes sharper than the renderer's sharpest (``materialx.sharp_lobes``)."""
        spec = values.get("materialx") or {}
        return list(spec.get("sharp_lobes") or [])

    def unheld_inputs(self, values: dict) -> list[str]:
        """A MaterialX source's ``materialx.not_in_table`` but its sharp lobes: those are baked, as well as a slice
        holds them, and the error warning names them (:meth:`fit_limits`)."""
        spec = values.get("materialx") or {}
        sharp = set(spec.get("sharp_lobes") or [])
        return [clause for clause in spec.get("not_in_table") or [] if clause not in sharp]

    def flattened_inputs(self, values: dict) -> list[str]:
        """A MaterialX source's ``materialx.flattened``: each input as ``"input (driven by node 'x') as 0.5"``; the
        bake's warning and the library report's MaterialX table show them."""
        spec = values.get("materialx") or {}
        return [f"{key} (driven by {record['driven_by']}) as {_shown_value(record['value'])}"
                for key, record in (spec.get("flattened") or {}).items()]  # fmt: skip

    def nonfinite_fault(self, values: dict) -> tuple[str, str] | None:
        """A MaterialX source: the material's input of the largest magnitude at or above 1e6, where one is (a
        ``specular_IOR`` of 3e38 overflows the oracle's float32 GLSL), else the material; a document has no
        ``nonfinite_tolerance`` to offer."""
        spec = values.get("materialx")
        if not spec:
            return None
        size = {key: float(np.max(np.abs(value))) for key, value in (spec.get("inputs") or {}).items()
                if isinstance(value, int | float | tuple | list) and not isinstance(value, bool) and np.size(value)}  # fmt: skip
        key = max((k for k, v in size.items() if v >= 1e6), key=lambda k: size[k], default=None)
        expected = "expected inputs MaterialX's shader (float32 GLSL) turns into finite values"
        if key is not None:
            return f"{spec['material']}.{key}", f"{expected}; got {key} = {size[key]:g}, far out of range"
        # An index of refraction near 0 (the nodedefs allow 0) divides by zero in the shader's Fresnel.
        ior = min((k for k, v in size.items() if "ior" in k.lower() and v < 1e-3), key=lambda k: size[k], default=None)
        if ior is not None:
            return f"{spec['material']}.{ior}", f"{expected}; got {ior} = {size[ior]:g}, an index of refraction near 0"
        return spec["material"], expected

    def slice_count(self, values: dict) -> int:
        """K when fixed (and one transmission slice for a back-light); with ``max_error`` only
        the bake knows (len of its slices)."""
        if values["representation"] == "lut":
            return 1
        terms = values["terms"] if values["terms"] is not None else MAX_AUTO_TERMS
        return terms + _transmits(values)

    def fewest_slices(self, values: dict) -> int:
        """K (and the transmission slice) when fixed; else one: ``auto`` may choose a LUT slice or a closed
        form, and a budget may be met by one term."""
        if values["representation"] == "separable" and values["terms"] is not None:
            return values["terms"] + _transmits(values)
        return 1 + (values["representation"] == "separable" and _transmits(values))

    # -- bake -------------------------------------------------------------------------------------
    def bake(self, values: dict) -> SliceSet:
        """K factor slices (``representation = "separable"``), one preview slice for the closed form
        (``"analytic"``), or whichever of them is cheapest within the budget (``"auto"``)."""
        if values["representation"] == "analytic":
            return self._bake_analytic(values)
        if values["representation"] == "auto":
            return self._bake_auto(values)
        if values["representation"] == "lut":
            return self._bake_lut_only(values)
        return self._bake_separable(values)

    def _bake_lut_only(self, values: dict) -> SliceSet:
        """``representation = "lut"``: one slice fitted to the source (:func:`atlasgen.models.physical_lut.fit_lut`),
        its error the relative RMS of f cos against the source on the report sample, 8-bit, with its SE."""
        budget = values["max_error"] if values["max_error"] is not None else DEFAULT_BUDGET
        source = make_source(values)
        sample = _error_samples(source)[1]
        reference, _ = _reference(source, sample)
        lut, fit = fit_lut(values)
        error = lut_errors(stored_slice(lut), fit["gloss"], reference, sample)
        key = cost_key("lut")
        chosen = {"representation": key, "error": error["relative_rms"], "error_se": error["relative_rms_se"],
                  "gloss": fit["gloss"], "meets_budget": bool(error["relative_rms"] <= budget),
                  "error_kind": "relative RMS of f cos, one 8-bit slice fitted from physics"}  # fmt: skip
        auto = {"error_budget": budget, "estimator": sample.estimator, "pairs": sample.count, "seed": sample.seed,
                "chosen": key, "candidates": [chosen]}  # fmt: skip
        return self._bake_lut(values, lut, fit, chosen, auto)

    def _bake_analytic(self, values: dict, auto: dict | None = None) -> SliceSet:
        """The in-plane cut of f cos as the one slice (previews only: the shader reads no texel of it)
        and the BRDF's parameters, the table the lighting shader evaluates."""
        out = Model.bake(self, values)
        rep = {"kind": "analytic", "distribution": values["source"], "alpha": _f32(values["alpha"]),
               "fresnel": values["fresnel"], "f0": _rounded(values["f0"]), "ior": _f32(values["ior"]),
               "specular": _rounded(values["specular"]), "diffuse": _rounded(values["diffuse"])}  # fmt: skip
        if auto is not None:
            rep["auto"] = auto
        out.extra = {"representation": rep}
        return out

    def _bake_auto(self, values: dict) -> SliceSet:
        """The cheapest candidate in run-time cost (:func:`atlasgen.separable.auto.read_lighting_cost`)
        whose error meets the budget: one LUT slice fitted from physics
        (:func:`atlasgen.models.physical_lut.fit_lut`), the closed form (exact: it is the source
        itself) where the shader has it, or K = 1..8 separable terms. Every error is the relative
        RMS of f cos against the source (the physical material) on the report sample of
        :mod:`atlasgen.separable.error`, 8-bit, with its standard error."""
        budget = values["max_error"] if values["max_error"] is not None else DEFAULT_BUDGET
        if error_measure(values) == "relative_log_rms":
            return self._bake_auto_display(values, budget)
        table = read_lighting_cost()
        separable = self._bake_separable({**values, "max_error": budget})
        rep = separable.extra["representation"]
        by_terms = {e["terms"]: e for e in separable.extra["errors"]["estimated_8bit_srgb_by_terms"][rep["target"]]}
        cached = separable._separable
        lut, fit = fit_lut(values)
        lut_error = lut_errors(stored_slice(lut), fit["gloss"], cached["reference"], cached["sample"])
        lut_key = cost_key("lut")
        candidates = [{"representation": lut_key, "cost": table.cost(lut_key), "error": lut_error["relative_rms"],
                       "error_se": lut_error["relative_rms_se"], "gloss": fit["gloss"],
                       "error_kind": "relative RMS of f cos, one 8-bit slice fitted from physics"}]  # fmt: skip
        if values["source"] in ANALYTIC_SHADER_SOURCES:
            key = cost_key("analytic", values["source"])
            candidates.append({"representation": key, "cost": table.cost(key), "error": 0.0, "error_se": 0.0,
                               "error_kind": "exact: the source's own closed form"})  # fmt: skip
        for k in sorted(by_terms):
            key = cost_key("separable", k)
            candidates.append({"representation": key, "cost": table.cost(key), "error": by_terms[k]["relative_rms"],
                               "error_se": by_terms[k]["relative_rms_se"],
                               "error_kind": "estimated relative RMS of f cos, 8-bit"})  # fmt: skip
        best, annotated = choose_representation(candidates, budget)
        sample = cached["sample"]
        auto = {"error_budget": budget, "cost_device": table.device, "cost_unit": table.unit,
                "estimator": sample.estimator, "pairs": sample.count, "seed": sample.seed,
                "chosen": annotated[best]["representation"], "candidates": annotated}  # fmt: skip
        chosen = annotated[best]["representation"]
        if chosen == lut_key:
            return self._bake_lut(values, lut, fit, annotated[best], auto)
        if chosen.startswith("analytic"):
            return self._bake_analytic(values, auto)
        terms = int(chosen.split(":")[1])
        if terms != rep["terms"]:
            separable = self._bake_separable({**values, "terms": terms, "max_error": None, "grid": rep["sampling_grid"]})
        separable.extra["representation"].update(error_budget=budget, meets_budget=annotated[best]["meets_budget"], auto=auto)
        return separable

    def _bake_auto_display(self, values: dict, budget: float) -> SliceSet:
        """``auto`` judged on the relative log RMS of f cos (:func:`~atlasgen.separable.error.relative_log_errors`),
        the measure a MaterialX document's budget is in (:func:`error_measure`): what the validation
        scenes' sRGB display shows, where the relative RMS is ruled by grazing peaks that the display
        clips. Candidates: one LUT slice (its gloss judged on the same measure) and K separable terms
        of each factorization of :data:`~atlasgen.separable.approximate.DISPLAY_FACTORIZATIONS` and each
        target, K = 1, 2, ... until one meets the budget (:func:`~atlasgen.separable.approximate.search_terms`).
        The choice is made on the selection sample; the chosen representation is then measured on
        the independent report sample, the figures the manifest holds."""
        table = read_lighting_cost()
        measure = "relative_log_rms"
        source = make_source(values)
        selection, report = _error_samples(source)
        selection_reference, _ = _reference(source, selection)
        lut, fit = fit_lut(values, measure=measure)
        lut_key = cost_key("lut")
        lut_selection = lut_errors(stored_slice(lut), fit["gloss"], selection_reference, selection)
        candidates = [{"representation": lut_key, "cost": table.cost(lut_key), "error": lut_selection[measure],
                       "error_se": lut_selection[f"{measure}_se"], "upper_bound": upper_bound(lut_selection, measure),
                       "gloss": fit["gloss"], "error_kind": "relative log RMS of f cos, one 8-bit slice fitted from physics"}]  # fmt: skip
        grid = values["grid"] if values["grid"] is not None else FACTOR_RESOLUTION
        targets = ("f_cos", "f_proxy") if values["target"] == "auto" else (values["target"],)
        terms, _ = search_terms(source, values["parametrization"], budget, selection, selection_reference, grid=grid,
                                resolution=FACTOR_RESOLUTION, targets=targets, measure=measure)  # fmt: skip
        for c in terms:
            key = cost_key("separable", c["terms"])
            candidates.append({"representation": key, "cost": table.cost(key), "error": c[measure], "error_se": c[f"{measure}_se"],
                               "upper_bound": upper_bound(c, measure), "factorization": c["factorization"],
                               "target": c["target"], "grid": c["grid"],
                               "error_kind": f"estimated relative log RMS of f cos, 8-bit, {c['factorization'].upper()}"})  # fmt: skip
        # Judged within the estimate's uncertainty, as a budget of separable terms is.
        best, annotated = choose_representation([{**c, "error": c["upper_bound"]} for c in candidates], budget)
        annotated = [{**c, "error": candidates[i]["error"]} for i, c in enumerate(annotated)]
        chosen = annotated[best]
        auto = {"error_budget": budget, "error_measure": measure, "cost_device": table.device, "cost_unit": table.unit,
                "estimator": selection.estimator, "pairs": selection.count, "seed": selection.seed,
                "report_seed": report.seed, "chosen": chosen["representation"], "candidates": annotated}  # fmt: skip
        if chosen["representation"] == lut_key:
            reported = lut_errors(stored_slice(lut), fit["gloss"], _reference(source, report)[0], report)
            # The slice's reconstruction_error stays its relative RMS, as every LUT's; the budget's figure is auto.reported.
            chosen = {**chosen, "error": reported["relative_rms"], "error_se": reported["relative_rms_se"],
                      "meets_budget": bool(upper_bound(reported, measure) <= budget)}  # fmt: skip
            auto["reported"] = {"error": reported[measure], "error_se": reported[f"{measure}_se"], "seed": report.seed}
            return self._bake_lut(values, lut, fit, chosen, auto)
        k = int(chosen["representation"].split(":")[1])
        separable = self._bake_separable({**values, "terms": k, "max_error": None, "grid": chosen["grid"],
                                          "factorization": chosen["factorization"], "target": chosen["target"]})  # fmt: skip
        cached = separable._separable
        approx = evaluate_factors(quantized_factors(cached), None, report.l, report.v, cosine=True)
        reported = relative_log_errors(cached["reference"], approx, report.weight)
        meets = bool(upper_bound(reported, measure) <= budget)
        auto["reported"] = {"error": reported[measure], "error_se": reported[f"{measure}_se"], "seed": report.seed}
        separable.extra["representation"].update(error_budget=budget, meets_budget=meets, auto=auto)
        return separable

    def _bake_lut(self, values: dict, rgba, fit: dict, chosen: dict, auto: dict) -> SliceSet:
        """One slice fitted from physics, drawn by the renderer's equation at the fitted gloss
        (:meth:`lighting_wgsl`); ``fit`` goes to the manifest as ``bake_from_physics`` writes it."""
        reference = _source_description(values)
        rep = {"kind": "lut", "supersampling": 1, "error_budget": auto["error_budget"],
               "reconstruction_error": chosen["error"], "meets_budget": chosen["meets_budget"],
               "candidates": auto["candidates"], "auto": auto}  # fmt: skip
        # "auto": the slice is fitted to this material's own source BRDF, which stays its model
        # reference (validation wraps only "physical" fits of a closed form).
        fit_info = {"from": "auto", "reference": reference, **{k: v for k, v in fit.items()}}
        return SliceSet(np.array(rgba).reshape(1, *np.shape(rgba)), extra={"representation": rep, "fit": fit_info})

    def bake_draft(self, values: dict) -> DraftSlices | None:
        """K factor slices before their error figures (``representation = "separable"`` only): the
        SVD, the choice of K, grid and target on the selection sample, and the 8-bit factors, all as
        the full bake makes them; the report sample's figures wait for ``complete()``. A draft's
        manifest fields lack ``errors``, ``representation``, ``max_error_met`` and ``errors_8bit``.
        ``"auto"`` chooses its representation by the report figures, so it has no draft."""
        if values["representation"] != "separable":
            return None
        return self._draft_separable(values)

    def _bake_separable(self, values: dict) -> SliceSet:
        return self._draft_separable(values).complete()

    def _draft_separable(self, values: dict) -> DraftSlices:
        source = make_source(values)
        method = values["factorization"]
        selection = error_sample_for(source, SELECTION_SEED)
        choice = choose_approximation(
            source,
            values["parametrization"],
            terms=1 if method == "nd" else values["terms"],
            max_error=values["max_error"],
            method=method,
            target=values["target"],
            resolution=FACTOR_RESOLUTION,
            grids=self.sampling_grids(values),
            reference=_reference(source, selection)[0],
            pairs=selection,
        )
        factors = choice.factors
        t0 = time.perf_counter()
        slices = factors_to_slices(factors)
        stored, scale, bias, clamped = encode_factor_slices(slices)
        quantize_s = time.perf_counter() - t0
        extra = {
            "brdf_source": values["source"],
            "parametrization": factors.parametrization,
            "factorization": method,
            "target": choice.chosen["target"],
            "terms": int(choice.terms),
            "sampling_grid": int(choice.chosen["grid"]),
            "factor_resolution": FACTOR_RESOLUTION,
            "channel_layout": CHANNEL_LAYOUT,
            "factor_scale": _rounded(scale),
            "factor_bias": _rounded(bias),
            "nonfinite_samples": choice.chosen["nonfinite"],
        }
        timings = {**choice.timings, "quantize_s": quantize_s}
        if source.transmits:
            t0 = time.perf_counter()
            slices = np.concatenate([slices, transmission_slice(source.f_cos)[None]])
            extra["transmission"] = {"slice": int(choice.terms)}
            timings["transmission_s"] = time.perf_counter() - t0
        draft = SliceSet(slices, extra, timings)
        hand_over = {"stored": stored, "scale": scale, "bias": bias, "clamped": clamped,
                     "parametrization": factors.parametrization, "target": choice.chosen["target"]}  # fmt: skip
        # Private hand-over to encode()/finalize(): exact arrays, never written to the manifest.
        draft._separable = {**hand_over, "draft": True}

        def complete() -> SliceSet:
            report = error_sample_for(source, ERROR_SEED)
            reference, ref_nonfinite = _reference(source, report)
            result = report_approximation(choice, report, reference)
            full = {
                **{k: v for k, v in extra.items() if k not in ("nonfinite_samples", "transmission")},
                "nonfinite_samples": result.nonfinite_samples,
                "nonfinite_reference": ref_nonfinite,
                "errors": {
                    "estimator": report.estimator,
                    "pairs": report.count,
                    "seed": report.seed,
                    "selection_pairs": selection.count,
                    "selection_seed": selection.seed,
                    **({} if report.lobe_alpha is None else {"lobe_alpha": report.lobe_alpha}),
                    "met_sigmas": MET_SIGMAS,
                    "float": result.errors,
                    "float_by_terms": result.errors_by_terms,
                    "estimated_8bit_srgb_by_terms": result.errors_8bit_by_terms,
                    "grid_by_terms": result.matrix_errors_by_terms,
                },
            }
            if values.get("reflection_only"):
                full["transmitted_fraction"] = transmitted_fractions(values["bsdf"])
            if result.max_error_met is not None:
                full["max_error"] = values["max_error"] if values["max_error"] is not None else 0.02
                full["max_error_met"] = result.max_error_met
            chosen_8bit = next(e for e in result.errors_8bit_by_terms[result.target] if e["terms"] == result.terms)
            full["representation"] = {
                "kind": "separable",
                "terms": int(result.terms),
                "sampling_grid": int(result.grid),
                "target": result.target,
                "error_budget": full.get("max_error"),
                "estimated_error_8bit": chosen_8bit["relative_rms"],
                "estimated_error_8bit_se": chosen_8bit["relative_rms_se"],
                "meets_budget": result.max_error_met,
                "candidates": result.candidates,
            }
            if "transmission" in extra:
                full["transmission"] = extra["transmission"]
            out = SliceSet(slices, full, {**result.timings, **{k: v for k, v in timings.items() if k not in result.timings}})
            # The values the terms were chosen with: what a study of the stored terms must run again (stored_terms).
            out._separable = {**hand_over, "reference": reference, "sample": report, "values": values}
            return out

        return DraftSlices(draft, complete)

    def stored_terms(self, values: dict) -> tuple[str, dict | None]:
        """What the bake stores (``"separable"``, ``"lut"`` or ``"analytic"``) and, for terms, the values they were
        chosen with (None for the others). ``"auto"`` runs the bake and returns the values its terms came from:
        a MaterialX budget's fixed K, grid, factorization and target (it reads neither ``factorization`` nor the
        measure the values' ``max_error`` is in, :meth:`_bake_auto_display`); a TOML budget's own search, whose
        K-term NMF is the prefix of an 8-term one, not a K-term NMF factored anew."""
        if values["representation"] != "auto":
            kind = values["representation"]
            return kind, values if kind == "separable" else None
        baked = self.bake(values)
        kind = _kind(baked)
        return kind, baked._separable["values"] if kind == "separable" else None

    @staticmethod
    def sampling_grids(values: dict) -> tuple:
        """The sampling grids the bake tries: ``grid`` if given; with a budget the
        candidates of :data:`~atlasgen.separable.approximate.GRID_RESOLUTIONS`; else
        the stored resolution."""
        if values["grid"] is not None:
            return (values["grid"],)
        return GRID_RESOLUTIONS if values["terms"] is None else (FACTOR_RESOLUTION,)

    def encode(self, values: dict, slices: SliceSet, rgb_scale="auto", alpha_scale="auto") -> EncodedSlices:
        """Per-term, per-factor, per-channel scale and bias (docs/separable.md, "Storage").

        ``rgb_scale`` and ``alpha_scale`` do not apply: every factor gets the scale and
        bias that fit it exactly. The generic (K, 2) ``scale``/``bias`` are 1 and 0; the
        real ones are ``factor_scale``/``factor_bias`` in the manifest entry.
        """
        if _kind(slices) in ("analytic", "lut"):
            return encode_scaled(slices.values, rgb_scale, alpha_scale)
        k = _term_slices(slices)
        terms = slices.values[:k]
        cached = getattr(slices, "_separable", None)
        if cached is None or cached["stored"].shape != terms.shape:
            stored, scale, bias, clamped = encode_factor_slices(terms)
        else:
            stored, scale, bias, clamped = cached["stored"], cached["scale"], cached["bias"], cached["clamped"]
        extra = {"factor_scale": _rounded(scale), "factor_bias": _rounded(bias)}
        slice_scale, slice_bias = np.ones((k, 2)), np.zeros((k, 2))
        if k < slices.values.shape[0]:  # the transmission slice: a table slice with its own RGB scale
            back, rgb_scale = encode_transmission_slice(slices.values[k])
            stored = np.concatenate([stored, back[None]])
            slice_scale = np.vstack([slice_scale, [[rgb_scale, 1.0]]])
            slice_bias = np.vstack([slice_bias, [[0.0, 0.0]]])
        return EncodedSlices(stored, slice_scale, slice_bias, clamped, extra=extra)

    def finalize(self, values: dict, slices: SliceSet, encoded: EncodedSlices, decoded: np.ndarray) -> dict:
        """The 8-bit atlas's error: factors rebuilt from ``decoded`` exactly as the shader does."""
        if _kind(slices) == "analytic":
            return {}  # the shader reads no texel: nothing was quantized that it uses
        if _kind(slices) == "lut":
            return {}  # a plain slice: the generic quantization error covers it
        cached = getattr(slices, "_separable", None)
        if cached is not None and cached.get("draft"):
            reference = sample = None  # a draft's figures wait for its completion
            name, target = cached["parametrization"], cached["target"]
        elif cached is not None:
            reference, sample = cached["reference"], cached["sample"]
            name, target = cached["parametrization"], cached["target"]
        else:  # slices from the bake cache: only the manifest fields survive
            source = make_source(values)
            sample = _error_samples(source)[1]
            reference, _ = _reference(source, sample)
            name = slices.extra.get("parametrization", values["parametrization"])
            target = slices.extra.get("target", "f_cos")
        k = _term_slices(slices)
        factors = _decoded_factors(slices, encoded, decoded, name, target)
        # The generic quantization error assumes one (rgb, a) scale per slice; with
        # per-factor scale and bias it is measured here, in factor units.
        err = np.abs(factors_to_slices(factors)[..., :3] - np.asarray(slices.values)[:k, ..., :3])
        out = {"quantization_error": {"max": float(err.max()), "rms": float(np.sqrt(np.mean(err**2)))}}
        if sample is None:
            return out
        approx = evaluate_factors(replace(factors, transmission=None), None, sample.l, sample.v, cosine=True)
        out = {"errors_8bit": measure_errors(reference, approx, sample.weight), **out}
        if factors.transmission is not None:
            out["transmission"] = _transmission_errors(make_source(values), factors, k)
        return out

    # -- shader -----------------------------------------------------------------------------------
    @classmethod
    def include_declarations(cls, entries: list) -> list:
        """The generic rebuild of f cos(theta_l) and its data table (every include language)."""
        analytic = any(isinstance(e.representation, AnalyticRepresentation) for e in entries)
        lut = any(isinstance(e.representation, LutRepresentation) for e in entries)
        return separable_declarations(entries) + (analytic_declarations() if analytic else []) + ([LUT_F_COS] if lut else [])

    def check_cached(self, extra: dict) -> None:
        """The parametrization and target the rebuild looks up (a forged cache entry's 'bogus' was a KeyError)."""
        for field, known in (("parametrization", PARAMETRIZATIONS), ("target", TARGETS)):
            if field in extra and extra[field] not in known:
                raise ValueError(f"a {field} of {shorten(repr(extra[field]))}")

    @classmethod
    def check_entry(cls, entry, shown: str, where: str) -> None:
        """Factors to rebuild, unless the entry is held as one LUT slice or in closed form, in a parametrization
        and of a target the rebuild knows; a closed form's roughness and index within this model's own bounds
        (its shader code divides by alpha^4)."""
        rep = entry.representation
        if entry.factors is None and not isinstance(rep, (AnalyticRepresentation, LutRepresentation)):
            raise ManifestError(shown, f"{where}.factor_scale", "missing; expected a separable entry's factors "
                                "(factor_scale, factor_bias, ...) or a LUT or analytic representation")  # fmt: skip
        if entry.factors is not None:
            for field, value, known in (("parametrization", entry.factors.parametrization, PARAMETRIZATIONS),
                                        ("target", entry.factors.target, TARGETS)):  # fmt: skip
                if value not in known:
                    raise ManifestError(shown, f"{where}.{field}",
                                        f"expected one of {', '.join(known)}, got {shorten(repr(value))}")  # fmt: skip
        if isinstance(rep, AnalyticRepresentation):
            for param in (p for p in cls.params if p.name in ("alpha", "ior")):
                param.coerce(getattr(rep, param.name), shown, ManifestError, f"{where}.representation.{param.name}")
            # The lighting shader's switch codes: an unknown name ended render with an internal KeyError.
            for field, value, known in (("distribution", rep.distribution, DISTRIBUTION_CODES),
                                        ("fresnel", rep.fresnel, FRESNEL_CODES)):  # fmt: skip
                if value not in known:
                    raise ManifestError(shown, f"{where}.representation.{field}",
                                        f"expected one of {', '.join(known)}, got {shorten(repr(value))}")  # fmt: skip

    @classmethod
    def include_data(cls, entries: list) -> bytes:
        """``X.separable.bin``: the include's ``SEPARABLE_TABLE`` for engines that upload it as a buffer; none where
        no entry stores factors (each held as one LUT slice or in closed form), as the include then has no table (a
        side-car of one header row was written beside an include without one)."""
        if not any(e.factors is not None for e in entries):
            return b""
        return separable_table_bytes(entries)

    @classmethod
    def lighting_wgsl(cls, entry) -> str:
        """The include's generic ``separable_f_cos`` at mip level 0, in 1/sr, for this material's ID;
        for an analytic representation, ``analytic_f_cos`` with its parameters."""
        if isinstance(entry.representation, AnalyticRepresentation):
            return analytic_call(entry.representation)
        if isinstance(entry.representation, LutRepresentation):
            return f"lut_slice_f_cos(atlas, samp, {entry.first_slice}u, n, l, v, {float_literal(fit_gloss(entry))})"
        return f"separable_f_cos(atlas, samp, {entry.first_slice}u, n, l, v)"

    # -- references and validation -------------------------------------------------------------
    no_physical_reference = (
        "its model reference is already the source BSDF itself (analytic or Mitsuba's), "
        "the physical material the factors approximate; source = 'thin_film' has the spectral thin film"
    )

    def physical_reference(self, values, albedo=(1.0, 1.0, 1.0), gloss=0.5):
        """For ``source = "materialx"``, the Mitsuba BSDF faithful to it where there is one
        (:func:`atlasgen.models.materialx.materialx_mitsuba_bsdf`). For ``source = "thin_film"``, the iridescent model's spectral reference (``atlasgen_thinfilm``
        in ``llvm_ad_spectral``, wavelengths sampled per sample) with this material's film (its
        back-light included), ``alpha`` and base colour ``diffuse``, the whole film tinted by the
        albedo as the renderer's L += E albedo f cos is: the film the source integrates
        to RGB for white light (:func:`atlasgen.separable.source.thin_film_source`). Other sources:
        ``None`` (their model reference is the source itself)."""
        if values["source"] == "materialx":
            found = materialx_mitsuba_bsdf(values["materialx"], albedo)
            return None if found is None else Reference(found[0], found[1])
        if values["source"] != "thin_film":
            return None
        film = {**FILM_DEFAULTS, **values["film"]}
        back = film.pop("backlight_colour", (1.0, 1.0, 1.0))
        bsdf = {"type": THIN_FILM_REFERENCE, "film": json.dumps(film, sort_keys=True), "alpha": float(values["alpha"])}
        bsdf.update({f"colour_{c}": float(x) for c, x in zip("rgb", values["diffuse"])})
        if _transmits(values):
            bsdf.update({f"backlight_{c}": float(x) for c, x in zip("rgb", back)})
        # The renderer draws albedo * f cos (the model reference too): the whole film is tinted, not only its base.
        bsdf.update({f"tint_{c}": float(x) for c, x in zip("rgb", albedo)})
        return Reference(bsdf, "thin-film GGX microfacet, Airy reflectance per wavelength (llvm_ad_spectral, "
                               "wavelengths sampled per sample)", variant="llvm_ad_spectral", stochastic=True)  # fmt: skip

    def physical_brdf_source(self, values: dict):
        """The source itself is the physical material the factors approximate, except a thin film
        (its physical material is the spectral film of :meth:`physical_reference`)."""
        src = values["source"]
        if src == "thin_film":
            return None
        return dict(values), _source_description(values)

    def model_reference(self, values, albedo=(1.0, 1.0, 1.0), gloss=0.5):
        """The source BSDF itself times the albedo (``atlasgen_brdf``), f cos for the full (w_i, w_o):
        the renderer adds L += E albedo f cos with f rebuilt from the factors."""
        material = {"params": values, "albedo": [float(a) for a in albedo]}
        return Reference({"type": BRDF_REFERENCE, "material": json.dumps(material, sort_keys=True)},
                         _source_description(values, "BSDF"))  # fmt: skip

    def radiance_rebuilds(self, entry, atlas, float_slices=None):
        """``"8bit"``: the include's sum over the 8-bit factors in float64
        (:func:`atlasgen.separable.rebuild.evaluate_factors`), L = E albedo f cos. The float
        factors are not in the atlas, so there is no ``"float"`` rebuild."""
        if isinstance(entry.representation, AnalyticRepresentation):
            return {"8bit": RadianceRebuild("the closed form in float64 (atlasgen.separable.analytic), as the shader evaluates it",
                                            representation_radiance(entry, None))}  # fmt: skip
        if isinstance(entry.representation, LutRepresentation):
            return {
                "8bit": RadianceRebuild(
                    "the baked 8-bit slice in the renderer's equation at the fitted gloss, times the albedo",
                    representation_radiance(entry, as_atlas(atlas).decode_slice(entry.first_slice)),
                )
            }
        factors = read_separable_factors(atlas, entry.name)

        def radiance(n, l, v, albedo, gloss, irradiance):
            return irradiance * albedo * evaluate_factors(factors, n, l, v, cosine=True)

        return {"8bit": RadianceRebuild("the include's rebuild in float64 on the CPU (atlasgen.separable)", radiance)}

    def claimed_errors(self, entry):
        """The manifest's relative RMS of f cos over uniform (l, v) pairs, 8-bit and float, and K. Where ``auto``
        judged by the relative log RMS (a MaterialX document), ``error_budget`` is None, since the budget
        bounds that figure instead, and ``relative_log_rms_8bit`` (with its SE and ``relative_log_rms_budget``) is it."""
        claim = self._claimed_errors(entry)
        auto = getattr(entry.representation, "auto", None) or {}
        if claim is None or auto.get("error_measure", "relative_rms") == "relative_rms":
            return claim
        reported = auto.get("reported") or {}
        if isinstance(entry.representation, LutRepresentation):
            claim = {**claim, "relative_rms_8bit_se": None}  # its candidates' SEs are the log measure's
        return {**claim, "error_budget": None, "relative_log_rms_8bit": reported.get("error"),
                "relative_log_rms_8bit_se": reported.get("error_se"), "relative_log_rms_budget": auto.get("error_budget")}  # fmt: skip

    def _claimed_errors(self, entry):
        if isinstance(entry.representation, AnalyticRepresentation):
            return None  # the closed form itself: nothing approximated
        if isinstance(entry.representation, LutRepresentation):
            return {"relative_rms_8bit": entry.representation.reconstruction_error, "relative_rms_float": None, "terms": None,
                    "error_budget": entry.representation.error_budget,
                    "relative_rms_8bit_se": _lut_error_se(entry.representation)}  # fmt: skip
        factors = entry.factors
        return {
            "relative_rms_8bit": None if factors.errors_8bit is None else factors.errors_8bit.relative_rms,
            "relative_rms_float": None if factors.errors is None else factors.errors.float_error.relative_rms,
            "terms": factors.terms,
            "error_budget": getattr(entry.representation, "error_budget", None),
            "relative_rms_8bit_se": None if factors.errors_8bit is None else factors.errors_8bit.relative_rms_se,
        }

    # -- reports ----------------------------------------------------------------------------------
    def describe_representation(self, entry) -> str:
        text = self._describe_representation(entry)
        if entry.params.get("source") == "materialx" and isinstance(entry.params.get("materialx"), dict):
            return f"{describe_materialx(entry.params['materialx'])}: {text}"
        return text

    def _describe_representation(self, entry) -> str:
        factors, rep = entry.factors, entry.representation
        if isinstance(rep, AnalyticRepresentation):
            how = f", chosen by run-time cost (budget {rep.auto['error_budget']:g})" if rep.auto else ""
            return f"analytic {rep.distribution} evaluated in the lighting shader, no atlas data{how}"
        if isinstance(rep, LutRepresentation):
            return (
                f"one LUT slice fitted from physics, drawn at gloss {fit_gloss(entry):g}, "
                f"chosen by run-time cost (budget {rep.error_budget:g})"
            )
        terms = factors.terms if factors.terms is not None else factors.term_slices
        param = factors.parametrization
        grid = factors.sampling_grid
        budget = getattr(rep, "error_budget", None)
        back = " and a transmission slice for light from behind" if factors.transmission is not None else ""
        return (
            f"separable, {terms} term(s){', ' + param if param else ''}"
            f"{f', sampled on {grid}x{grid}' if grid else ''}{back}{f' (budget {budget:g})' if budget else ''}"
        )


#: The renderer's equation for a LUT slice at a fixed gloss, as f cos in 1/sr (the separable
#: path multiplies by the albedo): f cos = A.rgb / pi + A.a D(N.H) V(N.L, N.V) max(N.L, 0).
LUT_F_COS = Function("lut_slice_f_cos", "vec3", (("atlas", "texture_array"), ("samp", "sampler"), ("material", "u32"),
                                                 ("n", "vec3"), ("l", "vec3"), ("v", "vec3"), ("gloss", "f32")), (
    Let("vec4", "a", "atlas_sample(atlas, samp, material, dot(n, l), dot(n, v), 0.0)"),
    Return("a.rgb / ATLAS_PI + splat3(a.a * specular(n, l, v, specular_alpha(gloss)))"),
), "f cos of one LUT slice in the renderer's equation at a fixed gloss (a material fitted from physics), level 0.")  # fmt: skip


def error_measure(values: dict) -> str:
    """The error ``representation = "auto"`` judges candidates by: ``"relative_log_rms"`` where a
    MaterialX document's reader asked for it (``materialx.error_measure``), else ``"relative_rms"``."""
    spec = values.get("materialx") if values.get("source") == "materialx" else None
    return str((spec or {}).get("error_measure") or "relative_rms")


def quantized_factors(cached: dict):
    """The 8-bit factors of a separable bake's private hand-over (``SliceSet._separable``), as the atlas returns them."""
    stored = dequantize_rgba(quantize_rgba(cached["stored"], True), True)
    return factors_from_slices(stored, cached["scale"], cached["bias"], cached["parametrization"], cached["target"])


def _lut_error_se(rep) -> float | None:
    """The standard error of a fitted LUT slice's error, from the candidate chosen (``auto``)."""
    auto = rep.auto or {}
    chosen = next((c for c in auto.get("candidates", []) if c.get("representation") == auto.get("chosen")), None)
    return None if chosen is None else chosen.get("error_se")


def _source_description(values: dict, what: str = "BRDF") -> str:
    """``source BRDF (ggx)``; a Mitsuba source with its dict, a MaterialX one with its document and material."""
    src = values["source"]
    if src == "mitsuba":
        return f"source {what} ({src}): {values.get('bsdf')}"
    if src == "materialx" and isinstance(values.get("materialx"), dict):
        return f"source {what}: {describe_materialx(values['materialx'])}, its GLSL evaluated by the MaterialX oracle"
    return f"source {what} ({src})"


def fit_gloss(entry) -> float:
    """The renderer gloss a slice fitted from physics was made for (the manifest's ``fit.gloss``)."""
    return float(entry.fit.gloss) if entry.fit is not None else 0.5


def representation_radiance(entry, first_slice):
    """``radiance(n, l, v, albedo, gloss, irradiance)`` of a separable material held as one LUT slice or
    a closed form, as the lighting pass shades it (``first_slice``: its decoded slice, what
    ``atlas_sample`` returns; unused by a closed form); None for one held as factors."""
    if isinstance(entry.representation, AnalyticRepresentation):
        return _analytic_radiance(entry.representation)
    if isinstance(entry.representation, LutRepresentation):
        return _lut_radiance(first_slice, fit_gloss(entry))
    return None


def _lut_radiance(table, gloss: float):
    table = np.asarray(table, dtype=np.float64)

    def radiance(n, l, v, albedo, _gloss, irradiance):
        n, l, v = (np.asarray(x, dtype=np.float64) for x in (n, l, v))
        nl, nv = np.sum(n * l, axis=-1), np.sum(n * v, axis=-1)
        nh, degenerate = half_vector_cosine(l, v, n)
        m = sample_slice(table, np.clip(nl, -1.0, 1.0), np.clip(nv, 0.0, 1.0))
        return irradiance * albedo * renderer_f_cos(m, 1.0, gloss, nl, nv, nh, degenerate)

    return radiance


def analytic_params(rep: AnalyticRepresentation) -> dict:
    """The :func:`atlasgen.separable.analytic.evaluate_analytic` parameters of an analytic representation."""
    return {
        "source": rep.distribution,
        "alpha": rep.alpha,
        "fresnel": rep.fresnel,
        "f0": rep.f0,
        "ior": rep.ior,
        "specular": rep.specular,
        "diffuse": rep.diffuse,
    }


def _analytic_radiance(rep: AnalyticRepresentation):
    params = analytic_params(rep)

    def radiance(n, l, v, albedo, gloss, irradiance):
        return irradiance * albedo * analytic_f_cos_world(params, n, l, v)

    return radiance


def stored_factors(slices: SliceSet, srgb: bool = True):
    """The factors of a separable bake (:meth:`Separable.bake`), with its transmission slice, as an
    8-bit atlas returns them (:class:`~atlasgen.separable.factorize.Factors`)."""
    encoded = Separable().encode({}, slices)
    decoded = dequantize_rgba(quantize_rgba(encoded.stored, srgb), srgb)
    return _decoded_factors(slices, encoded, decoded, slices.extra["parametrization"], slices.extra["target"])


def _decoded_factors(slices: SliceSet, encoded: EncodedSlices, decoded: np.ndarray, parametrization: str, target: str):
    """Factors from decoded slices: the terms by their factor scales, a transmission slice by its slice scale."""
    k = _term_slices(slices)
    pair = None if k == decoded.shape[0] else (encoded.scale[k][0], encoded.bias[k][0])
    return factors_from_slices(decoded, encoded.extra["factor_scale"], encoded.extra["factor_bias"], parametrization,
                               target, pair)  # fmt: skip


def _term_slices(slices: SliceSet) -> int:
    """How many of a separable bake's slices hold terms (all but a transmission slice)."""
    back = slices.extra.get("transmission")
    return slices.values.shape[0] - (back is not None)


def _transmission_errors(source, factors, offset: int) -> dict:
    """The manifest's ``transmission``: the slice's offset and the relative RMS of the whole f cos the
    include rebuilds (8-bit terms above the surface, the 8-bit slice below) against the source,
    l over the whole sphere (:func:`atlasgen.separable.error.error_sample_for`, ``sphere=True``)."""
    sample = error_sample_for(source, ERROR_SEED, sphere=True)
    reference, _ = _reference(source, sample)
    approx = evaluate_factors(factors, None, sample.l, sample.v, cosine=True)
    return {"slice": offset, "estimator": sample.estimator, "pairs": sample.count, "seed": sample.seed,
            "errors_8bit_sphere": measure_errors(reference, approx, sample.weight)}  # fmt: skip


def _f32(x) -> float:
    return float(np.float32(x))


def _kind(slices: SliceSet) -> str | None:
    return (slices.extra.get("representation") or {}).get("kind")


def _rounded(array) -> list:
    """Floats as float32-exact values: deterministic JSON, and what the shader's f32 constants hold."""
    return np.asarray(array, dtype=np.float32).astype(np.float64).tolist()
