"""The bake's verdict on each material: warnings for a measured error the atlas cannot hide, and
the refusal of non-finite samples.

A material warns, with one line naming it, the error and its cause where known, when

- its measured relative RMS exceeds :data:`ERROR_WARNING_THRESHOLD`: the manifest's
  ``fit.relative_rms`` (a slice fitted to a physical reference: ``type = "bsdf"``, ``from =
  "physical"``, skin's volpath fit) or ``errors_8bit.relative_rms`` (a separable material's
  factors as stored, against its BRDF). The cause is anisotropy when ``fit.anisotropic`` is
  set (``accept_anisotropy = true``), else what the model knows no slice holds
  (:meth:`~atlasgen.models.base.Model.fit_limits`: a MaterialX lobe sharper than the renderer's), else
  an unreachable fit: the representation cannot follow its reference (skin at a curvature radius far
  from the pre-integration's, a lobe the renderer's cannot take);
- it dropped a smooth (delta) lobe (``rough_only = true``) holding more than that share of its
  albedo at some view angle (``fit.dropped_delta_fraction``): the fit's own figure never sees it;
- a separable ``max_error`` budget was not met (``max_error_met = false``);
- the bake replaced non-finite samples by 0 that the material tolerates
  (``nonfinite_tolerance``); more than it tolerates are a :class:`~atlasgen.errors.MaterialError`;
- its stored slices lost to 8 bits most of what it gave: over :data:`LOST_WARNING_THRESHOLD` of the
  texels whose RGB (or A) is above 0 are stored as code 0 (:func:`assess_storage`), as when a scale
  far beyond the slice's range stores a lambert black;
- a scale given below its slice's peak clamped texel channels to it (the bake assembling the atlas warns).

``atlasgen bake --strict`` turns any of them into a failure (exit status
:attr:`atlasgen.errors.BakeWarnings.exit_code`, no atlas written; a cache keeps what was baked). None of the shipped materials
warns (tests/bake/test_quality.py reads the goldens' manifest).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from atlasgen.errors import MaterialError

__all__ = ["ERROR_WARNING_THRESHOLD", "LOST_WARNING_THRESHOLD", "MaterialWarning", "assess_material", "assess_storage",
           "count_nonfinite"]  # fmt: skip

#: Relative RMS of f cos (or of skin's radiance) above which a baked material warns: the error at
#: which a material visibly differs from its reference (no shipped material reaches it).
ERROR_WARNING_THRESHOLD = 0.2
#: Share of the texel channels a model gave a value above 0 that may be stored as code 0 before the
#: material warns. The shipped materials stay well under it (skin, whose faint wrap below the horizon rounds to 0,
#: loses the most).
LOST_WARNING_THRESHOLD = 0.5


@dataclass(frozen=True)
class MaterialWarning:
    """One material's warning, handed from the bake to the CLI (which prints ``str(warning)``).

    ``figure`` is the measured error (a fraction) and ``cause`` what is known of why:
    ``"anisotropy"``, ``"dropped delta lobe"``, ``"unreachable fit"``, ``"missed budget"``,
    ``"non-finite samples"``, ``"not in the table"``, ``"flattened"``, ``"lost to 8 bits"`` or ``"clamped to the scale"``
    (a scale given below the slice's peak: the bake's, :func:`atlasgen.bake.pipeline`); ``detail`` the rest of
    the line.
    """

    source: str
    material: str
    cause: str
    figure: float | None
    detail: str

    def __str__(self) -> str:
        return f"{self.source}: material '{self.material}': {self.detail}"


def count_nonfinite(extra: dict) -> int:
    """Samples of the material's source the bake found NaN or infinite and replaced by 0: a separable
    material's ``nonfinite_samples`` and ``nonfinite_reference``, a fit's ``fit.nonfinite_samples``."""
    fit = extra.get("fit") or {}
    return sum(int(v or 0) for v in (extra.get("nonfinite_samples"), extra.get("nonfinite_reference"),
                                     fit.get("nonfinite_samples")))  # fmt: skip


def _field_at_fault(material) -> str:
    return "bsdf" if material.params.get("bsdf") else "type"


def check_nonfinite(material, extra: dict) -> None:
    """Raise :class:`MaterialError` naming the field at fault (:meth:`~atlasgen.models.base.Model.nonfinite_fault`,
    else the material file's ``type`` or ``bsdf``) when the bake replaced more non-finite samples than
    ``material.nonfinite_tolerance`` allows (``extra``: the model's manifest fields so far)."""
    nonfinite = count_nonfinite(extra)
    if nonfinite <= int(getattr(material, "nonfinite_tolerance", 0) or 0):
        return
    model = getattr(material, "model", None)
    fault = model.nonfinite_fault(material.params) if model is not None else None
    field, expected = fault or (_field_at_fault(material),
                                f"expected finite ones, or nonfinite_tolerance >= {nonfinite} to bake them as 0")  # fmt: skip
    raise MaterialError(material.source, field,
                        f"material {material.name!r}: the source gave {nonfinite} non-finite samples (NaN or inf); "
                        f"{expected}")  # fmt: skip


def assess_material(material, extra: dict, threshold: float = ERROR_WARNING_THRESHOLD) -> list[MaterialWarning]:
    """The warnings of one baked material from its manifest fields ``extra`` (the model's, merged).

    Raises :class:`MaterialError` naming the field at fault when the bake replaced more non-finite
    samples than ``material.nonfinite_tolerance`` allows.
    """
    out = []

    def warn(cause, figure, detail):
        out.append(MaterialWarning(material.source, material.name, cause, figure, detail))

    check_nonfinite(material, extra)
    nonfinite = count_nonfinite(extra)
    tolerance = int(getattr(material, "nonfinite_tolerance", 0) or 0)
    model = getattr(material, "model", None)
    unheld = model.unheld_inputs(material.params) if model is not None else []
    if unheld:
        warn("not in the table", None, f"baked without what its slices cannot hold: {'; '.join(unheld)}")
    flattened = model.flattened_inputs(material.params) if model is not None else []
    if flattened:
        warn("flattened", None, f"baked with driven inputs at one value (--flatten): {'; '.join(flattened)}")
    if nonfinite:
        warn("non-finite samples", None, f"{nonfinite} non-finite samples (NaN or inf) baked as 0 "
                                         f"(nonfinite_tolerance = {tolerance})")  # fmt: skip
    fit = extra.get("fit") or {}
    if "relative_rms" in fit:
        error, what = float(fit["relative_rms"]), "its fit"
    elif "relative_rms" in (extra.get("errors_8bit") or {}):
        error, what = float(extra["errors_8bit"]["relative_rms"]), "its stored factors"
    else:
        error, what = None, ""
    if fit.get("anisotropic"):
        warn("anisotropy", error, f"relative RMS error {100 * (error or 0.0):.1f}% of {what}: the BSDF is anisotropic "
                                  "(accept_anisotropy = true), which an (N.L, N.V) slice holds in one tangent frame only")  # fmt: skip
    elif error is not None and error > threshold:
        limits = model.fit_limits(material.params) if model is not None else []
        because = "; ".join(limits) or "an unreachable fit (the representation cannot follow its reference)"
        warn("unreachable fit", error, f"relative RMS error {100 * error:.1f}% of {what} > {100 * threshold:g}%: {because}")
    dropped = fit.get("dropped_delta_fraction") or []
    worst = max(dropped, key=lambda row: row["fraction"], default=None)
    if worst is not None and worst["fraction"] > threshold:
        warn("dropped delta lobe", worst["fraction"],
             f"dropped a smooth (delta) lobe holding {100 * worst['fraction']:.1f}% of the albedo at {worst['view_deg']:g} "
             f"degrees from the normal (rough_only = true) > {100 * threshold:g}%; its fit error ({100 * (error or 0.0):.1f}%) "
             "does not see it")  # fmt: skip
    if extra.get("max_error_met") is False:
        warn("missed budget", error, f"missed its max_error budget {extra.get('max_error'):g}: "
                                     f"relative RMS {100 * (error or 0.0):.1f}% (an unreachable fit)")  # fmt: skip
    return out


def assess_storage(material, values: np.ndarray, codes: np.ndarray, encoded) -> list[MaterialWarning]:
    """A warning for RGB and for A where over :data:`LOST_WARNING_THRESHOLD` of the texels the model gave a
    value above 0 (``values``, linear, ``(n, H, W, 4)``) are stored as code 0 (``codes``, the 8-bit level 0):
    the slice's scale put them below 8 bits' least step. Factors (``encoded.extra``'s ``factor_*``) carry a
    bias of their own, so their code 0 is not 0: they are not judged here."""
    if any(key.startswith("factor_") for key in (encoded.extra or {})):
        return []
    out = []
    for what, channels, column, field in (("RGB", slice(0, 3), 0, "rgb_scale"), ("A", slice(3, 4), 1, "alpha_scale")):
        positive = values[..., channels] > 0.0
        if not positive.any():
            continue
        lost = float((positive & (codes[..., channels] == 0)).sum() / positive.sum())
        if lost > LOST_WARNING_THRESHOLD:
            scale = float(np.max(np.asarray(encoded.scale)[:, column]))
            out.append(MaterialWarning(material.source, material.name, "lost to 8 bits", lost,
                                       f"{100 * lost:.1f}% of the texels whose {what} is above 0 are stored as 0: the "
                                       f"slice's {what} scale {scale:.4g} ({field} = {getattr(material, field, 'auto')}) "
                                       "puts them below 8 bits' least step"))  # fmt: skip
    return out
