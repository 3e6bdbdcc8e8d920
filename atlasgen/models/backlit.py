"""Semi-transparent material lit from behind (Barré-Brisebois & Bouchard 2011).

:func:`translucency` is the transmission term in (N.L, N.V) form; the iridescent model's
optional back-lighting uses it too.
"""

from __future__ import annotations

from functools import cache

import numpy as np

from atlasgen.io.fields import Param
from atlasgen.models.base import THIN_SHEET_REFERENCE, Model, PhysicalFCos, Reference, SliceSet
from atlasgen.models.physical_fit import fit_to_reference
from atlasgen.optics.microfacet import ggx_distribution, smith_visibility_correlated_ggx
from atlasgen.optics.quadrature import gauss_legendre_rule
from atlasgen.optics.specular import half_vector_cosine, specular_alpha
from atlasgen.optics.translucency import transmitted_albedo

__all__ = ["Backlit", "translucency", "transmitted_albedo", "thin_sheet_f_cos", "VIEW_MODES"]

#: How the view term V.(-L) is reduced to (N.L, N.V); see :func:`translucency`.
VIEW_MODES = ("average", "coplanar")


@cache
def _azimuth_rule(n: int = 12):
    """Nodes g_k and weights h_k of the substituted azimuth integral (see :func:`translucency`)."""
    x, w = gauss_legendre_rule(n)
    t = 0.5 * np.pi * (x + 1.0)
    nodes, weights = 0.5 * (1.0 - np.cos(t)), 0.5 * np.pi * w * np.cos(0.5 * t)
    nodes.setflags(write=False)
    weights.setflags(write=False)
    return nodes, weights


def _power(x, p: float):
    """x ** p, by repeated squaring when p is a whole number (artists' usual choice)."""
    if float(p).is_integer() and 1 <= p <= 64:
        n, result, base = int(p), None, x
        while n:
            if n & 1:
                result = base if result is None else result * base
            n >>= 1
            if n:
                base = base * base
        return result
    return x**p


def translucency(n_dot_l, n_dot_v, distortion: float, power: float, view: str = "average"):
    """The back-lit transmission t = saturate(V.-(L + N delta))^p, reduced to (N.L, N.V).

    Barré-Brisebois & Bouchard, "Approximating Translucency for a Fast, Cheap and
    Convincing Subsurface Scattering Look", GDC 2011: ``vLTLight = L + N * distortion``
    (not renormalised, as in the talk's shader) and ``pow(saturate(dot(V, -vLTLight)), p)``.

    With N.L = cos(theta_l), N.V = cos(theta_v) and phi the azimuth between L and V,

        V.-(L + delta N) = a - b cos(phi),  a = -N.L N.V - delta N.V,
                                           b = sin(theta_l) sin(theta_v).

    The table has no azimuth. ``view = "average"`` bakes the mean over a uniform azimuth,
    (1/pi) int_0^pi saturate(a - b cos phi)^p dphi: the value that minimises the squared
    error over all azimuths. The integrand vanishes for cos(phi) > c0 = a/b, so with
    u = cos(phi) the mean is (1/pi) int_-1^c0 (a - b u)^p / sqrt(1 - u^2) du; substituting
    u = -1 + (1 + c0)(1 - cos s)/2, s in [0, pi], removes the 1/sqrt(1 + u) end point:

        t = sqrt(1 + c0)/pi int_0^pi (a - b u)^p cos(s/2) / sqrt(1 - u) ds,

    integrated with 12-point Gauss-Legendre: within 1e-4 of a dense rule for p >= 0.3
    (1/40 of an 8-bit step), within 1e-5 for 0.5 <= p <= 40.
    ``view = "coplanar"`` bakes phi = pi, V and L on opposite sides of N, looking into
    the light: the peak over azimuth. Both are exact where b = 0 (N.L = -1, or N.V = 1).
    """
    nl = np.clip(np.asarray(n_dot_l, dtype=np.float64), -1.0, 1.0)
    nv = np.clip(np.asarray(n_dot_v, dtype=np.float64), 0.0, 1.0)
    nl, nv = np.broadcast_arrays(nl, nv)
    a = -nl * nv - distortion * nv
    b = np.sqrt(np.maximum(1.0 - nl * nl, 0.0)) * np.sqrt(np.maximum(1.0 - nv * nv, 0.0))
    if view == "coplanar":
        return _power(np.clip(a + b, 0.0, 1.0), power)
    if view != "average":
        raise ValueError(f"view must be one of {VIEW_MODES}, got {view!r}")
    # b = 0 means no azimuth dependence: all of the circle (a > 0) or none of it.
    ratio = np.divide(a, b, out=np.where(a > 0.0, np.inf, -np.inf), where=b > 0.0)
    c0 = np.clip(ratio, -1.0, 1.0)
    g, h = _azimuth_rule()
    u = (1.0 + c0)[..., None] * g - 1.0
    # 1 - u >= (1 - c0) g_min > 0 unless c0 = 1, where the integrand's cos(s/2) cancels it;
    # the floor only guards 0/0 at that removable point.
    f = _power(np.clip(a[..., None] - b[..., None] * u, 0.0, 1.0), power) / np.sqrt(np.maximum(1.0 - u, 1e-300))
    return np.sqrt(1.0 + c0) * (f @ h) / np.pi


def thin_sheet_f_cos(wi, wo, reflectance, transmittance, specular: float, alpha: float):
    """f |cos(theta_o)| of a thin diffuse sheet with a specular coat, ``(N, 3)`` RGB.

    With w_i and w_o in the sheet's local frame (either side),

        f = R / pi + specular D(h) V(w_i, w_o)                     w_o on w_i's side (reflection)
        f = T / pi                                                 w_o on the other side (transmission)

    D is GGX and V the height-correlated Smith visibility, the renderer's lobe (Walter et al.
    2007; Heitz 2014), with the normal flipped to w_i's side; a
    sheet with R + T <= 1 and no coat neither creates nor loses energy beyond absorption.
    """
    ci, co = wi[:, 2], wo[:, 2]
    side = np.where(ci < 0.0, -1.0, 1.0)
    ci, co = ci * side, co * side
    same = co > 0.0
    nh = half_vector_cosine(wi, wo)[0] * side
    with np.errstate(divide="ignore", invalid="ignore"):
        lobe = np.nan_to_num(ggx_distribution(nh, alpha) * smith_visibility_correlated_ggx(ci, np.abs(co), alpha))
    reflected = np.asarray(reflectance) / np.pi + (specular * lobe)[:, None]
    value = np.where(same[:, None], reflected, np.asarray(transmittance) / np.pi) * np.abs(co)[:, None]
    return np.where((ci > 0.0)[:, None], value, 0.0)


class Backlit(Model):
    """A thin, semi-transparent surface: diffuse in front, transmitted light from behind.

    RGB = colour * max(N.L, 0) + transmission_colour * (scale * t(N.L, N.V) + ambient),
    A = specular, with t from :func:`translucency` (Barré-Brisebois & Bouchard 2011).
    ``view`` picks the azimuth average (default) or the coplanar case. As in the talk's
    shader the transmission is not masked by N.L: it peaks at N.L = -1 and fades towards
    N.L = 0, continuously, so filtering across N.L = 0 is smooth.
    """

    type_name = "backlit"
    reference = "Barré-Brisebois & Bouchard, GDC 2011: t = pow(saturate(V.-(L + N delta)), p) * scale"
    params = (
        Param("colour", (0.5, 0.5, 0.5), "colour", doc="diffuse colour for front lighting, linear"),
        Param("transmission_colour", (1.0, 1.0, 1.0), "colour", doc="colour of light transmitted from behind"),
        Param("distortion", 0.2, lo=0.0, hi=1.0, doc="delta: shifts the transmitted direction towards -N"),
        Param("power", 4.0, lo=0.0, hi=64.0, lo_open=True, doc="p: sharpness of the transmission lobe"),
        Param("scale", 1.0, lo=0.0, hi=16.0, doc="strength of the transmission"),
        Param("ambient", 0.0, lo=0.0, hi=1.0, doc="constant transmission, independent of angle"),
        Param("view", "average", "choice", choices=VIEW_MODES, doc="azimuth average or coplanar view term"),
        Param("specular", 0.0, lo=0.0, hi=16.0, doc="A, constant"),
    )

    def evaluate(self, values, n_dot_l, n_dot_v):
        nl, nv = np.broadcast_arrays(
            np.clip(np.asarray(n_dot_l, dtype=np.float64), -1.0, 1.0),
            np.clip(np.asarray(n_dot_v, dtype=np.float64), 0.0, 1.0),
        )
        t = translucency(nl, nv, values["distortion"], values["power"], values["view"])
        out = np.empty(nl.shape + (4,))
        out[..., :3] = np.maximum(nl, 0.0)[..., None] * np.asarray(values["colour"])
        out[..., :3] += (values["scale"] * t + values["ambient"])[..., None] * np.asarray(values["transmission_colour"])
        out[..., 3] = values["specular"]
        return out

    physical_omissions = {
        "view": "how the model reduces its lobe's azimuth to (N.L, N.V); the sheet transmits diffusely, "
        "with no azimuth, and takes the lobe's energy (transmitted_albedo), the same in both modes",
    }

    def physical_reference(self, values, albedo=(1.0, 1.0, 1.0), gloss=0.5):
        """``atlasgen_thinsheet``: a thin sheet with diffuse reflection ``colour``, diffuse transmission
        T = transmission_colour (scale 2 (1 - delta)^p / (p + 2) + ambient) (:func:`transmitted_albedo`:
        the energy the model's term passes for light from behind along -N) and a GGX coat of
        constant reflectance ``specular``: the renderer's lobe at its width."""
        a = np.asarray(albedo, dtype=np.float64)
        reflectance = np.asarray(values["colour"], dtype=np.float64) * a
        gain = values["scale"] * transmitted_albedo(values["distortion"], values["power"]) + values["ambient"]
        transmittance = np.asarray(values["transmission_colour"], dtype=np.float64) * gain * a
        bsdf = {"type": THIN_SHEET_REFERENCE, "specular": float(values["specular"]), "alpha": float(specular_alpha(gloss))}
        bsdf.update({f"reflectance_{c}": float(v) for c, v in zip("rgb", reflectance)})
        bsdf.update({f"transmittance_{c}": float(v) for c, v in zip("rgb", transmittance)})
        return Reference(bsdf, "thin sheet: diffuse reflection, diffuse transmission of the model's energy, GGX coat")

    def physical_f_cos(self, values, gloss) -> PhysicalFCos:
        """:meth:`physical_reference` as NumPy: :func:`thin_sheet_f_cos`, the function the
        ``atlasgen_thinsheet`` plugin evaluates, with its w_i the view and w_o the light. It
        transmits (l below the surface) where T > 0. No separable source holds transmission."""
        ref = self.physical_reference(values, gloss=gloss)
        bsdf = ref.bsdf
        reflectance = np.array([bsdf[f"reflectance_{c}"] for c in "rgb"])
        transmittance = np.array([bsdf[f"transmittance_{c}"] for c in "rgb"])

        def f_cos(l, v):
            return thin_sheet_f_cos(v, l, reflectance, transmittance, bsdf["specular"], bsdf["alpha"])

        return PhysicalFCos(f_cos, ref.description, alpha=bsdf["alpha"] if bsdf["specular"] > 0.0 else None,
                            transmits=bool(np.any(transmittance > 0.0)),
                            no_source="no separable source holds a thin sheet (its diffuse transmission, N.L < 0)")  # fmt: skip

    def fit_physical(self, values, gloss) -> SliceSet:
        """The slice fitted to :meth:`physical_reference` at the renderer gloss ``gloss``
        (:func:`atlasgen.models.physical_fit.fit_to_reference`), from :meth:`physical_f_cos`
        (:func:`thin_sheet_f_cos`, the NumPy function the ``atlasgen_thinsheet`` plugin evaluates):
        no Mitsuba needed.

        The renderer's equation holds the sheet exactly at texel centres: its transmission
        T |N.L| / pi (N.L < 0) is the diffuse term RGB / pi with RGB = T |N.L|, its reflection
        R N.L / pi likewise, and its coat is the renderer's lobe at this gloss, A = ``specular``;
        what is left is the 8-bit rounding and the bilinear filter.
        """
        physical = self.physical_f_cos(values, gloss)
        return fit_to_reference(self, values, physical.f_cos, physical.description, gloss)
