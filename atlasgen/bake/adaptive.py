"""Adaptive LUT baking: the cheapest texel pre-filter (supersampling) that meets an error budget."""

from __future__ import annotations

import numpy as np

from atlasgen.contract import HEIGHT, WIDTH, texel_centres
from atlasgen.models.base import DraftSlices, Model, SliceSet
from atlasgen.models.physical_fit import bake_from_physics
from atlasgen.optics.interpolation import sample_slice

__all__ = ["SUPERSAMPLING_FACTORS", "reconstruction_error", "bake_supersampled", "bake_within_budget", "bake_material",
           "draft_material"]  # fmt: skip

#: Sub-samples per texel axis, cheapest first.
SUPERSAMPLING_FACTORS = (1, 2, 4, 8)
#: Dense evaluation grid per texel axis used to measure the error.
ERROR_DENSITY = 8


def _dense_grid():
    nl = np.linspace(-1, 1, (WIDTH - 1) * ERROR_DENSITY + 1)
    nv = np.linspace(0, 1, (HEIGHT - 1) * ERROR_DENSITY + 1)
    return np.meshgrid(nl, nv, indexing="xy")


def reconstruction_error(model, values: dict, slice_rgba: np.ndarray) -> float:
    """RMS over a dense (N.L, N.V) grid of |sampled slice - model|, all four channels, linear units.

    The slice is sampled as the renderer samples it: bilinearly, or nearest for slices
    whose model asks for it (``flags()["nearest"]``).

    This is the error a renderer sees between texel centres, which is where a
    discontinuous model (toon bands) loses most to point sampling.
    """
    nl, nv = _dense_grid()
    truth = np.asarray(model.evaluate(values, nl, nv), dtype=np.float64)
    seen = sample_slice(slice_rgba, nl, nv, nearest=bool(model.flags(values).get("nearest")))
    return float(np.sqrt(np.mean((seen - truth) ** 2)))


def bake_supersampled(model, values: dict, factor: int) -> np.ndarray:
    """One slice whose texels are box-filtered over a factor x factor grid inside each texel.

    factor 1 is plain point sampling at texel centres, the atlas contract's default.
    """
    nl_c, nv_c = texel_centres()
    offsets = (np.arange(factor) + 0.5) / factor - 0.5
    nl = np.clip(nl_c[None, :, None] + offsets[None, None, :] * 2.0 / (WIDTH - 1), -1, 1)  # (1, W, f)
    nv = np.clip(nv_c[:, None, None] + offsets[None, None, :] * 1.0 / (HEIGHT - 1), 0, 1)  # (H, 1, f)
    nl_full = np.broadcast_to(nl[:, :, None, :], (HEIGHT, WIDTH, factor, factor))
    nv_full = np.broadcast_to(nv[:, :, :, None], (HEIGHT, WIDTH, factor, factor))
    rgba = np.asarray(model.evaluate(values, nl_full, nv_full), dtype=np.float64)
    return rgba.mean(axis=(2, 3))


def bake_within_budget(model, values: dict, budget: float) -> SliceSet:
    """The smallest supersampling factor whose reconstruction error is <= ``budget``.

    If none meets it, the factor with the least error is kept, so a tighter budget
    never yields a larger error. The choice and every measured error go into the
    manifest (``representation``).
    """
    measured = []
    best = None
    for factor in SUPERSAMPLING_FACTORS:
        rgba = bake_supersampled(model, values, factor)
        error = reconstruction_error(model, values, rgba)
        measured.append({"supersampling": factor, "error": error})
        if best is None or error < best[1]:
            best = (factor, error, rgba)
        if error <= budget:
            best = (factor, error, rgba)
            break
    factor, error, rgba = best
    representation = {
        "kind": "lut",
        "supersampling": factor,
        "error_budget": budget,
        "reconstruction_error": error,
        "meets_budget": error <= budget,
        "candidates": measured,
    }
    return SliceSet(rgba[None], extra={"representation": representation})


def bake_material(material):
    """Float slices of one material; LUT models with an ``error_budget`` pick their supersampling;
    ``from = "physical"`` fits the slice to the model's physical reference."""
    model = material.model
    if material.fit_from == "physical":
        return bake_from_physics(model, material.params, material.source, material.fit_gloss)
    if material.error_budget is not None and type(model).bake is Model.bake:
        return bake_within_budget(model, material.params, material.error_budget)
    return model.bake(material.params)


def draft_material(material) -> DraftSlices | None:
    """The model's draft of what :func:`bake_material` bakes (:meth:`~atlasgen.models.base.Model.bake_draft`),
    or None where the model has none, or the bake is a fit or a budget's supersampling (drafted by nobody)."""
    model = material.model
    if material.fit_from == "physical" or (material.error_budget is not None and type(model).bake is Model.bake):
        return None
    return model.bake_draft(material.params)
