"""Analytic BRDFs built into atlasgen, evaluated vectorised on (l, v) in the local frame (n = +z).

Every function returns f (not f cos), RGB, shaped ``(..., 3)``. Directions below
the horizon give 0. Cosines in denominators are clamped to
:data:`atlasgen.optics.microfacet.COS_EPSILON` so grazing configurations give large but
finite values, never inf or NaN. The Fresnel and microfacet terms are
:mod:`atlasgen.optics.fresnel` and :mod:`atlasgen.optics.microfacet`.
"""

from __future__ import annotations

import numpy as np

from atlasgen.optics.fresnel import fresnel_dielectric, fresnel_schlick
from atlasgen.optics.microfacet import COS_EPSILON, beckmann_distribution, ggx_distribution, smith_g2_separable_over_cos

__all__ = [
    "ANALYTIC_SOURCES",
    "microfacet_brdf",
    "blinn_phong_brdf",
    "ward_brdf",
    "lambert_brdf",
    "evaluate_analytic",
    "to_local_frame",
    "analytic_f_cos_world",
]

ANALYTIC_SOURCES = ("ggx", "beckmann", "blinn_phong", "ward", "lambert")


def _cosines(l, v):
    l = np.asarray(l, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    h = l + v
    length = np.linalg.norm(h, axis=-1)
    # l = -v has no half vector; both lie on the horizon then, where f cos is 0 anyway.
    h = np.where((length > 1e-12)[..., None], h / np.maximum(length, 1e-12)[..., None], np.array([0.0, 0.0, 1.0]))
    cos_i = l[..., 2]
    cos_o = v[..., 2]
    cos_h = np.clip(h[..., 2], 0.0, 1.0)
    cos_d = np.clip(np.sum(l * h, axis=-1), 0.0, 1.0)
    return cos_i, cos_o, cos_h, cos_d


def _above(cos_i, cos_o):
    # The horizon itself counts (as a limit), with slack for rounding in the grid's
    # own construction of horizon directions.
    return (cos_i >= -1e-9) & (cos_o >= -1e-9)


def microfacet_brdf(l, v, distribution="ggx", alpha=0.2, fresnel="schlick", f0=(0.04, 0.04, 0.04), ior=1.5):
    """Cook-Torrance microfacet BRDF f = D F G / (4 cos_i cos_o) (Walter et al. 2007, eq. 20).

    G is the separable Smith form G1(l) G1(v), as Mitsuba 3's ``roughconductor`` uses.
    ``fresnel`` is ``"schlick"`` (with ``f0``), ``"exact"`` (dielectric of index ``ior``)
    or ``"none"`` (F = 1).
    """
    cos_i, cos_o, cos_h, cos_d = _cosines(l, v)
    d = ggx_distribution(cos_h, alpha) if distribution == "ggx" else beckmann_distribution(cos_h, alpha)
    g_over = smith_g2_separable_over_cos(cos_i, cos_o, alpha, distribution)  # finite at grazing
    if fresnel == "schlick":
        f = fresnel_schlick(cos_d[..., None], f0)
    elif fresnel == "exact":
        f = fresnel_dielectric(cos_d, ior)[..., None]
    else:
        f = np.ones(cos_d.shape + (1,))
    value = (0.25 * d * g_over)[..., None] * f
    above = _above(cos_i, cos_o)
    return np.where(above[..., None], np.broadcast_to(value, cos_i.shape + (3,)), 0.0)


def blinn_phong_brdf(l, v, exponent=100.0, specular=(1.0, 1.0, 1.0)):
    """Normalized Blinn-Phong: f = ks (m + 8) / (8 pi) cos^m theta_h (Akenine-Moller et al., RTR 3rd ed., eq. 7.49)."""
    cos_i, cos_o, cos_h, _ = _cosines(l, v)
    lobe = (exponent + 8.0) / (8.0 * np.pi) * np.maximum(cos_h, 0.0) ** exponent
    above = _above(cos_i, cos_o)
    return np.where(above[..., None], lobe[..., None] * np.asarray(specular, dtype=np.float64), 0.0)


def ward_brdf(l, v, alpha=0.2, specular=(1.0, 1.0, 1.0)):
    """Isotropic Ward: f = rho_s exp(-tan^2 theta_h / alpha^2) / (4 pi alpha^2 sqrt(cos_i cos_o)) (Ward 1992, eq. 4)."""
    cos_i, cos_o, cos_h, _ = _cosines(l, v)
    c = np.maximum(cos_h, COS_EPSILON)
    tan2 = (1.0 - c * c) / (c * c)
    denom = 4.0 * np.pi * alpha * alpha * np.sqrt(np.maximum(cos_i, COS_EPSILON) * np.maximum(cos_o, COS_EPSILON))
    lobe = np.exp(-tan2 / (alpha * alpha)) / denom
    above = _above(cos_i, cos_o)
    return np.where(above[..., None], lobe[..., None] * np.asarray(specular, dtype=np.float64), 0.0)


def lambert_brdf(l, v, colour=(1.0, 1.0, 1.0)):
    """Lambert: f = colour / pi above the horizon (Lambert 1760)."""
    cos_i, cos_o, _, _ = _cosines(l, v)
    above = _above(cos_i, cos_o)
    return np.where(above[..., None], np.asarray(colour, dtype=np.float64) / np.pi, 0.0)


def evaluate_analytic(params: dict, l, v):
    """f of the analytic source described by a separable material's params, plus its diffuse term.

    ``params["source"]`` picks the lobe; ``params["diffuse"]`` adds colour / pi
    (for ``lambert`` it is the whole BRDF).
    """
    source = params["source"]
    diffuse = np.asarray(params.get("diffuse", (0.0, 0.0, 0.0)), dtype=np.float64)
    out = lambert_brdf(l, v, diffuse)
    if source in ("ggx", "beckmann"):
        lobe = microfacet_brdf(l, v, source, params["alpha"], params["fresnel"], params["f0"], params["ior"]) * np.asarray(
            params.get("specular", (1.0, 1.0, 1.0))
        )
    elif source == "blinn_phong":
        lobe = blinn_phong_brdf(l, v, params["exponent"], params["specular"])
    elif source == "ward":
        lobe = ward_brdf(l, v, params["alpha"], params["specular"])
    elif source == "lambert":
        return out
    else:
        raise ValueError(f"unknown analytic source {source!r}")
    return out + lobe


def to_local_frame(n, d):
    """Directions ``d`` in a frame whose +z is the unit normal ``n`` (both ``(..., 3)``).

    The tangent is any unit vector orthogonal to ``n``: every analytic source here is
    isotropic, so the azimuth of the frame does not matter.
    """
    n = np.asarray(n, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    helper = np.where((np.abs(n[..., :1]) > 0.9), np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]))
    t = np.cross(helper, n)
    t = t / np.linalg.norm(t, axis=-1, keepdims=True)
    b = np.cross(n, t)
    return np.stack([(d * t).sum(-1), (d * b).sum(-1), (d * n).sum(-1)], axis=-1)


def analytic_f_cos_world(params: dict, n, l, v):
    """f cos(theta_l) of :func:`evaluate_analytic` for world-space unit ``n``, ``l``, ``v`` ``(N, 3)``."""
    ll, lv = to_local_frame(n, l), to_local_frame(n, v)
    return evaluate_analytic(params, ll, lv) * np.maximum(ll[..., 2], 0.0)[..., None]
