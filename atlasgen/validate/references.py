"""Reference BSDFs for a baked material: the *model* reference and, where one exists, a *physical* one.

Each model supplies its own (:meth:`atlasgen.models.base.Model.model_reference` and
:meth:`~atlasgen.models.base.Model.physical_reference`); this module asks it for a
manifest entry and refuses, with one line, a material no reference can be built for.

Model reference
    What the atlas approximates, exactly. For a table model (``atlasgen_model``): the
    renderer's shading equation with the atlas lookup replaced by the exact model the
    slice was baked from. Per light the renderer adds (lighting.wgsl, docs/scenes.md)

        L += E (albedo * A.rgb / pi + A.a * f_s cos),
        f_s cos = k(s) max(N.H, 0)^s max(N.L, 0),   s = 2^(1 + 12 gloss),

    with A = atlas(N.L, N.V) (:mod:`atlasgen.optics.specular`). As a BSDF, eval(w_i, w_o)
    must return f cos(theta_o), and the terms in brackets are exactly that. So the model
    reference returns albedo * M.rgb(N.L, N.V) / pi + M.a(N.L, N.V) f_s cos with
    M = model.evaluate, N.L and N.V clamped to the table's domain as the sampler's
    clamp-to-edge addressing does. Rendering it and the atlas with the same scene
    isolates what the atlas costs: resolution, 8-bit quantization, filtering. For a
    separable material (``atlasgen_brdf``) it is the source BSDF itself, f cos for the
    full (w_i, w_o), times the albedo.

Physical references
    A physically based render of the same material (``lambert``: Mitsuba's ``diffuse``,
    the consistency gate; ``fresnel``: ``roughplastic``; ``sss``: ``volpath`` through skin
    of the material's colour; ``iridescent``: a thin-film microfacet BSDF in
    ``llvm_ad_spectral``; ``backlit``: a thin diffuse sheet). Every model parameter reaches
    it except the model's ``physical_omissions``; ``toon`` has none
    (``Model.no_physical_reference`` says why).

The Python BSDF plugins live in :mod:`atlasgen.models.mitsuba_bsdfs`.
"""

from __future__ import annotations

from atlasgen.errors import InputError
from atlasgen.io.manifest import MaterialEntry
from atlasgen.models import get_model, model_types
from atlasgen.models.base import Reference
from atlasgen.models.mitsuba_bsdfs import register_bsdfs
from atlasgen.models.physical_fit import FittedSlice

__all__ = ["register_references", "entry_model", "model_reference", "physical_reference"]


def register_references(mi) -> None:
    """Register atlasgen's BSDF plugins for Mitsuba's current variant (``mi.register_bsdf``)."""
    register_bsdfs(mi)


def entry_model(entry: MaterialEntry, float_slices=None):
    """The model a manifest entry's slices were baked from: its registered model, or for a
    ``from = "physical"`` entry that model's fitted slice (:class:`FittedSlice`), so that the
    model reference and the rebuilds measure the atlas against what was baked.

    ``float_slices`` (the bake cache's ``(n, H, W, 4)``, where validation found them) are a
    fitted entry's slice: the fit is then not run again.

    Raises :class:`KeyError` for an unknown type."""
    model = get_model(entry.type)
    if entry.fit is not None and entry.fit.source == "physical":
        fitted = FittedSlice(model, entry.fit.gloss)
        if float_slices is not None:
            fitted.use_table(entry.params, float_slices[0])
        return fitted
    return model


def model_reference(entry: MaterialEntry, albedo=(1.0, 1.0, 1.0), gloss: float = 0.5) -> Reference:
    """The model reference of a manifest entry, for an object of ``albedo`` and ``gloss``.

    Raises :class:`InputError` for a material no reference can be built for (an unknown
    type, or a model without one).
    """
    try:
        model = entry_model(entry)
    except KeyError:
        raise InputError(f"material {entry.name!r}: no reference for model type {entry.type!r}; "
                         f"expected one of {', '.join(model_types())}") from None  # fmt: skip
    reference = model.model_reference(entry.params, albedo, gloss)
    if reference is None:
        raise InputError(f"material {entry.name!r}: the {entry.type!r} model has no model reference to validate against")
    return reference


def physical_reference(entry: MaterialEntry, albedo=(1.0, 1.0, 1.0), gloss: float = 0.5) -> Reference | None:
    """The physical reference of a manifest entry, or ``None`` where its model has none."""
    return entry_model(entry).physical_reference(entry.params, albedo, gloss)
