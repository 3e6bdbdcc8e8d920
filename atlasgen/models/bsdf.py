"""Any Mitsuba BSDF as its best single (N.L, N.V) slice: the cheapest representation of a physical material.

The slice is the non-negative least-squares projection of the BSDF's f cos(theta_l) onto
the renderer's equation, per texel over the azimuth between l and v
(:mod:`atlasgen.models.physical_fit`, :mod:`atlasgen.optics.projection`). Mitsuba is
imported only when a material of this type is checked or baked.
"""

from __future__ import annotations

import numpy as np

from atlasgen.errors import MaterialError
from atlasgen.io.fields import Param
from atlasgen.models.base import Model, Reference, SliceSet
from atlasgen.models.physical_fit import fitted_bsdf_slice
from atlasgen.optics.interpolation import sample_slice
from atlasgen.separable.mitsuba_source import (
    delta_fractions,
    describe_lobes,
    load_mitsuba_bsdf,
    transmitting_field,
    unheld_in_bsdf,
)

__all__ = ["Bsdf"]


class Bsdf(Model):
    """A Mitsuba 3 BSDF dict projected onto one slice: RGB the part of f cos(theta_l) the
    renderer's diffuse term holds, A the scale of its specular lobe, per (N.L, N.V).

    The projection minimises sum_s w_s |f cos(l_s, v) - albedo A.rgb / pi - A.a f_s cos(l_s, v)|^2
    over stratified azimuths, with A.rgb, A.a >= 0 (Lawson & Hanson 1974); the renderer's lobe
    f_s cos is :mod:`atlasgen.optics.specular`'s, at the renderer gloss ``gloss`` (or the one of
    33 that fits best). Objects showing the material should use the gloss recorded in the
    manifest's ``fit.gloss``.
    """

    type_name = "bsdf"
    reference = "least-squares projection of a Mitsuba BSDF onto the renderer's equation (Lawson & Hanson 1974)"
    physical_omissions = {
        "gloss": "the renderer gloss the slice is fitted for; the physical reference is the BSDF itself, with its own roughness",
        "rough_only": "consent to drop the BSDF's delta lobes from the slice; the reference keeps them, so the error shows what was dropped",
        "accept_anisotropy": "consent to bake an anisotropic BSDF's average; the reference keeps the anisotropy, so the error shows it",
    }
    params = (
        Param("bsdf", None, "table", doc='a Mitsuba 3 BSDF dict, e.g. {type = "roughplastic", alpha = 0.2}'),
        Param("gloss", None, "float", lo=0.0, hi=1.0, doc="renderer gloss the slice is fitted for (default: the best fit)"),
        Param(
            "rough_only",
            False,
            "bool",
            doc="bake only the rough lobes of a BSDF with a smooth (delta) one, e.g. plastic (the dropped fraction is recorded)",
        ),
        Param(
            "accept_anisotropy",
            False,
            "bool",
            doc="bake an anisotropic BSDF in one tangent frame (its measured error is recorded and printed)",
        ),
    )

    def check(self, values: dict, path) -> None:
        if values["bsdf"] is None:
            raise MaterialError(path, "bsdf", 'missing; expected a Mitsuba BSDF table, e.g. {type = "roughplastic"}')

        load_mitsuba_bsdf(values["bsdf"], path, anisotropic=values["accept_anisotropy"], rough_only=values["rough_only"])

    def unheld_inputs(self, values: dict) -> list[str]:
        """A lobe sharper than the renderer's and a mask's see-through light (:func:`unheld_in_bsdf`), and the light
        a BSDF transmits (a roughdielectric, a principled spec_trans): the fit's figure sees none of them (3 % of a
        blend transmitting baked without a word, and a roughdielectric's warning blamed an unreachable fit), so the
        bake warns with them."""
        out = unheld_in_bsdf(values["bsdf"])
        transmitting = transmitting_field(values["bsdf"])
        if transmitting is not None:
            out.append(f"{transmitting[0]} = {transmitting[1]!r}: the light it transmits, which no slice holds (the "
                       "reflection that remains is baked)")  # fmt: skip
        return out

    def fitted(self, values: dict):
        """The fitted slice ``(H, W, 4)`` and its description (cached per BSDF and gloss)."""
        return fitted_bsdf_slice(values["bsdf"], values["gloss"])

    def evaluate(self, values, n_dot_l, n_dot_v):
        """The fitted slice, sampled as the renderer does (bilinear, clamp to edge)."""
        table, _ = self.fitted(values)
        nl, nv = np.broadcast_arrays(np.asarray(n_dot_l, dtype=np.float64), np.asarray(n_dot_v, dtype=np.float64))
        return sample_slice(table, nl, nv)

    def bake(self, values: dict) -> SliceSet:
        table, info = self.fitted(values)
        fit = {"from": "bsdf", **info}
        if values["accept_anisotropy"] or values["rough_only"]:
            lobes = describe_lobes(values["bsdf"])
            if values["accept_anisotropy"] and lobes["anisotropic"]:
                fit["anisotropic"] = True  # the slice is the BSDF in one tangent frame: see relative_rms
            if values["rough_only"] and lobes["delta_components"]:
                fit["dropped_delta_fraction"] = delta_fractions(values["bsdf"])
        return SliceSet(np.array(table)[None], extra={"fit": fit})

    def physical_reference(self, values, albedo=(1.0, 1.0, 1.0), gloss=0.5):
        """The BSDF itself (the object's albedo is not applied: a BSDF dict has no one colour to scale)."""
        return Reference(dict(values["bsdf"]), f"Mitsuba {values['bsdf'].get('type')!r} BSDF, as given")
