"""A diffuse base under a smooth dielectric interface: Fresnel reflectance in A.

Besides the :class:`Fresnel` model the module holds the Fresnel equations the other
models share (:func:`fresnel_dielectric`, :func:`fresnel_schlick`, :func:`normal_reflectance`).
"""

from __future__ import annotations

from functools import cache

import numpy as np

from atlasgen.materials.params import Param
from atlasgen.models.base import Model

__all__ = [
    "Fresnel",
    "fresnel_dielectric",
    "fresnel_schlick",
    "normal_reflectance",
    "hemispherical_average",
    "cosine_rule",
]


def normal_reflectance(ior, k=0.0):
    """Reflectance at normal incidence from air, F0.

    F0 = ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2) for a complex index n + ik (Born & Wolf,
    *Principles of Optics*, 7th ed., ch. 14, optics of metals; k = 0 for a dielectric).
    """
    n = np.asarray(ior, dtype=np.float64)
    k = np.asarray(k, dtype=np.float64)
    return ((n - 1.0) ** 2 + k**2) / ((n + 1.0) ** 2 + k**2)


def fresnel_dielectric(cos_i, ior):
    """Exact unpolarised Fresnel reflectance of light from air onto a dielectric of index ``ior``.

    With n = ior, cos_t = sqrt(1 - (1 - cos_i^2) / n^2),

        r_s = (cos_i - n cos_t) / (cos_i + n cos_t),
        r_p = (n cos_i - cos_t) / (n cos_i + cos_t),
        F = (r_s^2 + r_p^2) / 2

    (the Fresnel formulae, Born & Wolf, *Principles of Optics*, 7th ed., section 1.5.2).
    With ``ior >= 1`` there is no total internal reflection; F(0) = 1, F(1) = F0.
    """
    c = np.clip(np.asarray(cos_i, dtype=np.float64), 0.0, 1.0)
    n = float(ior)
    cos_t = np.sqrt(np.maximum(1.0 - (1.0 - c * c) / (n * n), 0.0))
    r_s = (c - n * cos_t) / (c + n * cos_t)
    r_p = (n * c - cos_t) / (n * c + cos_t)
    return 0.5 * (r_s * r_s + r_p * r_p)


def fresnel_schlick(cos_i, f0):
    """Schlick's approximation F = F0 + (1 - F0) (1 - cos_i)^5.

    Schlick, "An Inexpensive BRDF Model for Physically-based Rendering", Computer
    Graphics Forum 13(3), 1994.
    """
    c = np.clip(np.asarray(cos_i, dtype=np.float64), 0.0, 1.0)
    return f0 + (1.0 - f0) * (1.0 - c) ** 5


@cache
def cosine_rule(n: int = 32):
    """Nodes c_k in [0, 1] and weights w_k with sum_k w_k f(c_k) ~ 2 int_0^1 f(c) c dc (Gauss-Legendre)."""
    x, w = np.polynomial.legendre.leggauss(n)
    c = 0.5 * (x + 1.0)
    weights = w * c  # 2 * (dx / 2) * c
    c.setflags(write=False)
    weights.setflags(write=False)
    return c, weights


def hemispherical_average(reflectance_of_cosine):
    """F_avg = 2 int_0^1 F(c) c dc: the albedo of an interface under uniform (cosine-weighted) light.

    ``reflectance_of_cosine`` maps cosines of shape (n,) to (n,) or (n, k) reflectances;
    32-point Gauss-Legendre (exact Fresnel of a dielectric is smooth on [0, 1]).
    """
    c, w = cosine_rule()
    return np.tensordot(w, np.asarray(reflectance_of_cosine(c), dtype=np.float64), axes=(0, 0))


class Fresnel(Model):
    """Diffuse colour under a smooth dielectric coat; the coat's Fresnel reflectance goes to A.

    RGB = colour * max(N.L, 0) * T, with

        T = (1 - F(N.L)) (1 - F(N.V)) / (1 - F_avg)     energy = "coupled"
        T = 1                                          energy = "none"

    where F_avg = 2 int_0^1 F(c) c dc (:func:`hemispherical_average`). Light crosses the
    coat going in and coming out; the 1 / (1 - F_avg) returns what the coat reflects back
    inside, to first order, as Mitsuba's ``plastic`` does with ``nonlinear = false``
    (there written diff / (1 - F_dr,int) / eta^2; by reciprocity eta^2 (1 - F_dr,int) =
    1 - F_avg).
    With it the diffuse term's directional albedo under the renderer's albedo * RGB / pi
    is colour * (1 - F(N.V)) exactly, so diffuse plus specular albedo is 1 for a white
    colour: the coat neither creates nor loses energy.

    A = specular * F(N.V) by default: this renderer's specular lobe has unit albedo and
    no F0 of its own, so A is the whole specular reflectance. ``normalise = true`` stores
    specular * F(N.V) / F0 instead, the angular gain for an engine whose specular term
    already carries F0 (1 at normal incidence, 1 / F0 at grazing). F is the exact
    unpolarised dielectric Fresnel reflectance (Born & Wolf section 1.5.2) or Schlick's
    approximation (Schlick 1994), both with F0 = ((n - 1) / (n + 1))^2. The table has no
    half vector, so F is taken at N.V: exact at the mirror direction, where the specular
    lobe peaks. A does not depend on N.L; the renderer's lobe carries its own N.L clamp.
    """

    type_name = "fresnel"
    reference = "Fresnel formulae (Born & Wolf, Principles of Optics, section 1.5.2); Schlick 1994"
    params = (
        Param("colour", (0.5, 0.5, 0.5), "colour", doc="diffuse colour under the coat, linear"),
        Param("fresnel", "exact", "choice", choices=("exact", "schlick"), doc="exact dielectric Fresnel or Schlick's approximation"),
        Param("ior", 1.5, lo=1.01, hi=4.0, doc="refractive index of the coat (from air)"),
        Param("specular", 1.0, lo=0.0, hi=16.0, doc="multiplier on A"),
        Param("normalise", False, "bool", doc="A = F (false) or A = F/F0 (true)"),
        Param("energy", "coupled", "choice", choices=("coupled", "none"), doc="diffuse weighted by (1-F(N.L))(1-F(N.V))/(1-F_avg), or not"),
    )

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
        lit = np.maximum(nl, 0.0)
        if values["energy"] == "coupled":
            f_avg = float(hemispherical_average(lambda c: self.reflectance(values, c)))
            lit = lit * (1.0 - self.reflectance(values, lit)) * (1.0 - f_v) / (1.0 - f_avg)
        out = np.empty(shape + (4,))
        out[..., :3] = lit[..., None] * np.asarray(values["colour"], dtype=np.float64)
        gain = f_v / float(normal_reflectance(values["ior"])) if values["normalise"] else f_v
        out[..., 3] = values["specular"] * gain
        return out
