"""Pairs of figures that measure the same thing in different ways, for the reports to show side by side.

A reader who sees a separable material's claimed 2.58% beside 12.32% measured in the scenes, with
no word on why, cannot tell which to believe. Each pair here names what both figures measure, the
two figures with how each was measured, and one sentence on why they differ. The figures are read
from what the bake and validation recorded (the manifest's ``fit`` and representation, validation's
``report.json``); nothing is re-measured.
"""

from __future__ import annotations

__all__ = ["validation_pairs", "manifest_pairs", "SEPARABLE_WHY", "SEPARABLE_WHY_LOWER"]

#: Why a separable material's error in the scenes is above its manifest claim.
SEPARABLE_WHY = (
    "The manifest weights every (l, v) pair of the hemisphere alike; the scenes weight them by what the camera "
    "sees and how bright it is, so a glossy lobe's peak, where the factorization errs most, dominates the image figure."
)
#: Why it is below (or equal): the same weighting, the other way round.
SEPARABLE_WHY_LOWER = (
    "The manifest weights every (l, v) pair of the hemisphere alike, grazing pairs and the lobe's far tails included; "
    "the scenes see only the pairs their lights and camera make, weighted by how bright they are, and on this "
    "material those are where the factorization fits best, so the image figure is the lower."
)
_FIT_WHY = (
    "The relative RMS is over uniform (l, v) pairs of the 8-bit slice; the PSNR is over cosine-weighted pairs of the "
    "float slice, against the reference's peak: grazing pairs count less in it, and a bright peak sets its scale."
)
_MODEL_WHY = (
    "The same two measures of the model's own look (no fit): its stylisation (strength, split, back-light) against "
    "the physical film, as relative RMS over uniform pairs and as PSNR over cosine-weighted ones."
)
_MATERIALX_PHYSICAL_WHY = (
    "Both divide MaterialX's shading by its physical twin's (same n, k and alpha); the pairs weight the hemisphere "
    "uniformly, the pixels by what the camera sees: MaterialX's height-correlated G2 and energy compensation lift "
    "grazing pairs most, and the scenes show few of them."
)
_SKIN_WHY = (
    "The slice holds one curvature: it is fitted between the two fitted spheres' curvatures, so the validation sphere, "
    "which it never saw, lies inside what it learnt, while flat skin, which no light from behind reaches, lies outside it."
)


def _pct(x) -> str:
    return "n/a" if x is None else f"{100.0 * float(x):.2f}%"


def _pair(material: str, measures: str, first: tuple, second: tuple, why: str) -> dict:
    return {"material": material, "measures": measures, "first_label": first[0], "first": first[1],
            "second_label": second[0], "second": second[1], "why": why}  # fmt: skip


def validation_pairs(data: dict) -> list[dict]:
    """The pairs of a validation report dict: each separable material's claimed 8-bit error (the manifest's
    relative RMS of f cos over the hemisphere) beside the worst it measures in the scenes (relative
    RMS of the atlas's radiance against its source BSDF's), with the reason for the side it falls on."""
    out, seen = [], set()
    for row in data.get("results", []):
        claimed = row.get("claimed_errors") or {}
        if row["material"] in seen or claimed.get("relative_rms_8bit") is None:
            continue
        seen.add(row["material"])
        measured = [(r.get("claimed_errors") or {}).get("measured_relative_rms_atlas_vs_source") for r in data["results"]
                    if r["material"] == row["material"]]  # fmt: skip
        measured = [m for m in measured if m is not None]
        if not measured:
            continue
        out.append(_pair(row["material"], "the separable atlas's error against its source BSDF",
                         (f"manifest claim (8-bit, K={claimed.get('terms')}, over the hemisphere)", _pct(claimed["relative_rms_8bit"])),
                         ("measured in the scenes (worst scene, radiance per pixel)", _pct(max(measured))),
                         SEPARABLE_WHY if max(measured) > claimed["relative_rms_8bit"] else SEPARABLE_WHY_LOWER))  # fmt: skip
    return out + _materialx_pairs(data)


def _materialx_pairs(data: dict) -> list[dict]:
    """Per MaterialX material with a physical twin (the gold's ``roughconductor``): MaterialX's shading
    over the twin's, as f cos over uniform (l, v) pairs and per pixel in the scenes (median and range)."""
    out, seen = [], set()
    for row in data.get("results", []):
        ratio = (row.get("materialx") or {}).get("oracle_over_physical")
        if not ratio or row["material"] in seen or not ratio.get("bsdf_p1_p50_p99"):
            continue
        seen.add(row["material"])
        pixels = [q for r in data["results"] if r["material"] == row["material"]
                  for q in [((r.get("materialx") or {}).get("oracle_over_physical") or {}).get("pixel_p1_p50_p99")] if q]  # fmt: skip
        if not pixels:
            continue
        low, mid, high = ratio["bsdf_p1_p50_p99"]
        bsdf = f"{mid:.3f} ({low:.3f} to {high:.3f})"
        pix = f"{pixels[0][1]:.3f} ({min(q[0] for q in pixels):.3f} to {max(q[2] for q in pixels):.3f})"
        out.append(_pair(row["material"], f"MaterialX's shading over its physical twin's ({ratio.get('reference')})",
                         (f"f cos over {ratio.get('pairs')} uniform (l, v) pairs, N.L, N.V >= 0.2 (median, 1st to 99th percentile)", bsdf),
                         ("per pixel in the scenes (first scene's median, 1st to 99th percentile of all)", pix),
                         _MATERIALX_PHYSICAL_WHY))  # fmt: skip
    return out


def manifest_pairs(name: str, fit: dict | None, validation: dict | None = None) -> list[dict]:
    """The pairs of one manifest entry: a fit from physics as relative RMS (uniform pairs) and as PSNR
    (cosine-weighted pairs), the model's look the same two ways, a skin fit in and out of sample, and a
    separable claim against the scenes (from validation's report dict, when given)."""
    out = []
    fit = fit or {}
    if "fit_psnr_db" in fit:
        out.append(_pair(name, "the fitted slice against the physical reference",
                         ("relative RMS, 8-bit slice (fit.relative_rms)", _pct(fit.get("relative_rms"))),
                         ("PSNR, float slice (fit.fit_psnr_db)", f"{fit['fit_psnr_db']:.2f} ± {fit.get('fit_psnr_se_db', 0.0):.2f} dB"),
                         _FIT_WHY))  # fmt: skip
    if "model_psnr_db" in fit:
        out.append(_pair(name, "the model's stylised look against the physical reference",
                         ("relative RMS (fit.model_relative_rms)", _pct(fit.get("model_relative_rms"))),
                         ("PSNR (fit.model_psnr_db)", f"{fit['model_psnr_db']:.2f} ± {fit.get('model_psnr_se_db', 0.0):.2f} dB"),
                         _MODEL_WHY))  # fmt: skip
    scored = fit.get("out_of_sample") or {}
    for geometry, label in (("validation_sphere", "the validation sphere"), ("flat", "a flat part")):
        if geometry in scored:
            radii = ", ".join(f"{r:g}" for r in fit.get("fit_radii", []))
            out.append(_pair(name, f"the skin slice against the fit's own volpath ray renders: fitted spheres against {label}",
                             (f"in sample (spheres of radius {radii})", _pct(fit.get("relative_rms"))),
                             (f"out of sample, the fit's own geometry ({label}, radius {scored[geometry]['radius']:g}; "
                              f"the validation scenes score the sphere and a flat part apart)",
                              _pct(scored[geometry]["relative_rms"])), _SKIN_WHY))  # fmt: skip
    if validation is not None:
        out += [p for p in validation_pairs(validation) if p["material"] == name]
    return out
