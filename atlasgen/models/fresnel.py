"""A diffuse base under a smooth dielectric interface: Fresnel reflectance in A.

The Fresnel equations themselves are :mod:`atlasgen.optics.fresnel`.
"""

from __future__ import annotations

import numpy as np

from atlasgen.io.fields import Param
from atlasgen.models.base import Model, Reference
from atlasgen.optics.fresnel import fresnel_dielectric, fresnel_schlick, normal_reflectance
from atlasgen.optics.quadrature import hemispherical_average
from atlasgen.optics.specular import specular_alpha, specular_fresnel_cosine

__all__ = ["Fresnel"]


class Fresnel(Model):
    """Diffuse colour under a smooth dielectric coat; the coat's Fresnel reflectance goes to A.

    RGB = colour * max(N.L, 0) * T, with

        T = (1 - F(N.L)) (1 - F(N.V)) / (1 - F_avg)     energy = "coupled"
        T = 1                                          energy = "none"

    where F_avg = 2 int_0^1 F(c) c dc (:func:`atlasgen.optics.quadrature.hemispherical_average`). Light crosses the
    coat going in and coming out; the 1 / (1 - F_avg) returns what the coat reflects back
    inside, to first order, as Mitsuba's ``plastic`` does with ``nonlinear = false``
    (there written diff / (1 - F_dr,int) / eta^2; by reciprocity eta^2 (1 - F_dr,int) =
    1 - F_avg).
    With it the diffuse term's directional albedo under the renderer's albedo * RGB / pi
    is colour * (1 - F(N.V)) exactly; the specular term adds about what the coat reflects
    (F(c) below exceeds F(N.V) where l is more grazing than v), so a white coat creates at
    most 0.44% energy (measured; tests/models/test_fresnel.py) and none in the mirror limit.

    A = specular * F(c) by default, c = :func:`atlasgen.optics.specular.specular_fresnel_cosine`
    (N.L, N.V) = cos((theta_l + theta_v) / 2). The renderer's lobe is a GGX microfacet
    BRDF with Fresnel 1 (:mod:`atlasgen.optics.specular`), so A must carry the coat's
    F(L.H); the table has no half vector, and A is baked before the g-buffer's roughness
    is known. c is L.H where the lobe peaks for this (N.L, N.V) (l and v opposite in
    azimuth): F(c) is exact for a mirror and at every lobe's peak, and within 11% (mean
    2-4%) of the least-squares projection of F(L.H) onto a function of (N.L, N.V),
    weighted by the lobe over azimuth, for alpha <= 0.3 (tested; F(N.V), the previous
    choice, is off by up to 10x away from the mirror direction). At N.L = N.V, c = N.V.
    ``normalise = true`` stores specular * F(c) / F0 instead, the angular gain for an engine whose specular term
    already carries F0 (1 at normal incidence, 1 / F0 at grazing). F is the exact
    unpolarised dielectric Fresnel reflectance (Born & Wolf section 1.5.2) or Schlick's
    approximation (Schlick 1994), both with F0 = ((n - 1) / (n + 1))^2.
    """

    type_name = "fresnel"
    reference = "Fresnel formulae (Born & Wolf, Principles of Optics, section 1.5.2); Schlick 1994"
    params = (
        Param("colour", (0.5, 0.5, 0.5), "colour", doc="diffuse colour under the coat, linear"),
        Param(
            "fresnel", "exact", "choice", choices=("exact", "schlick"), doc="exact dielectric Fresnel or Schlick's approximation"
        ),
        Param("ior", 1.5, lo=1.01, hi=4.0, doc="refractive index of the coat (from air)"),
        Param("specular", 1.0, lo=0.0, hi=16.0, doc="multiplier on A"),
        Param("normalise", False, "bool", doc="A = F (false) or A = F/F0 (true)"),
        Param(
            "energy",
            "coupled",
            "choice",
            choices=("coupled", "none"),
            doc="diffuse weighted by (1-F(N.L))(1-F(N.V))/(1-F_avg), or not",
        ),
    )

    physical_omissions = {
        "fresnel": "Schlick's approximation stands in for the exact Fresnel equations, which the reference uses",
        "normalise": "an encoding for engines whose specular term already carries F0 (A = F/F0); the physical "
        "highlight is F, and the report measures the 1/F0 gap",
        "energy": "a physical coat always couples its diffuse base to what it reflects: the reference is "
        "roughplastic's coupled diffuse term whatever the setting",
    }

    @staticmethod
    def reflectance(values, cos_i):
        """F(cos_i) for the material's ``fresnel`` and ``ior``."""
        if values["fresnel"] == "schlick":
            return fresnel_schlick(cos_i, float(normal_reflectance(values["ior"])))
        return fresnel_dielectric(cos_i, values["ior"])

    def evaluate(self, values, n_dot_l, n_dot_v):
        # Clamp to the table's domain, as the sampler's clamp-to-edge addressing would.
        nl = np.clip(np.asarray(n_dot_l, dtype=np.float64), -1.0, 1.0)
        nv = np.clip(np.asarray(n_dot_v, dtype=np.float64), 0.0, 1.0)
        shape = np.broadcast_shapes(nl.shape, nv.shape)
        f_v = self.reflectance(values, nv)
        cos_l = np.maximum(nl, 0.0)
        lit = cos_l
        if values["energy"] == "coupled":
            f_avg = float(hemispherical_average(lambda c: self.reflectance(values, c)))
            lit = cos_l * (1.0 - self.reflectance(values, cos_l)) * (1.0 - f_v) / (1.0 - f_avg)
        out = np.empty(shape + (4,))
        out[..., :3] = lit[..., None] * np.asarray(values["colour"], dtype=np.float64)
        f_lobe = self.reflectance(values, specular_fresnel_cosine(cos_l, nv))
        gain = f_lobe / float(normal_reflectance(values["ior"])) if values["normalise"] else f_lobe
        out[..., 3] = values["specular"] * gain
        return out

    def physical_reference(self, values, albedo=(1.0, 1.0, 1.0), gloss=0.5):
        """Mitsuba's ``roughplastic``: exact Fresnel, and a GGX lobe of the renderer's roughness
        (:func:`atlasgen.optics.specular.specular_alpha`)."""
        colour = np.asarray(values["colour"], dtype=np.float64) * np.asarray(albedo, dtype=np.float64)
        return Reference({
            "type": "roughplastic",
            "distribution": "ggx",
            "alpha": float(specular_alpha(gloss)),
            "int_ior": float(values["ior"]),
            "ext_ior": 1.0,
            "diffuse_reflectance": {"type": "rgb", "value": colour.tolist()},
            # uniform, not rgb: an RGB reflectance must lie in [0, 1], and specular may exceed 1.
            "specular_reflectance": {"type": "uniform", "value": float(values["specular"])},
            "nonlinear": False,
        }, "Mitsuba roughplastic: exact Fresnel, GGX lobe of the renderer's roughness")  # fmt: skip
