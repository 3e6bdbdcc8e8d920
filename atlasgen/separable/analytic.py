"""Analytic BRDFs built into atlasgen, evaluated vectorised on (l, v) in the local frame (n = +z).

Every function returns f (not f cos), RGB, shaped ``(..., 3)``. Directions below
the horizon give 0. Cosines in denominators are clamped to ``COS_EPSILON`` so
grazing configurations give large but finite values, never inf or NaN.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "COS_EPSILON",
    "ANALYTIC_SOURCES",
    "fresnel_schlick",
    "fresnel_dielectric",
    "ggx_distribution",
    "beckmann_distribution",
    "smith_g1_ggx",
    "smith_g1_beckmann",
    "smith_g1_over_cos_ggx",
    "smith_g1_over_cos_beckmann",
    "microfacet_brdf",
    "blinn_phong_brdf",
    "ward_brdf",
    "lambert_brdf",
    "evaluate_analytic",
]

#: Smallest cosine used in a denominator (about 0.0057 degrees from the horizon).
COS_EPSILON = 1e-4

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


def fresnel_schlick(cos_d, f0):
    """Schlick 1994, eq. 15: F = F0 + (1 - F0) (1 - cos theta_d)^5, per RGB channel."""
    c = np.asarray(cos_d, dtype=np.float64)[..., None]
    f0 = np.asarray(f0, dtype=np.float64)
    return f0 + (1.0 - f0) * (1.0 - c) ** 5


def fresnel_dielectric(cos_d, eta):
    """Exact unpolarised Fresnel reflectance of a dielectric of relative index eta.

    R = (r_s^2 + r_p^2) / 2 with r_s = (c - eta c_t) / (c + eta c_t), r_p = (eta c - c_t) /
    (eta c + c_t), c_t = sqrt(1 - (1 - c^2) / eta^2) (Born & Wolf, Principles of Optics,
    sec. 1.5.2); total internal reflection (eta < 1) gives 1. Returned as ``(..., 1)``.
    """
    c = np.clip(np.asarray(cos_d, dtype=np.float64), 0.0, 1.0)
    sin_t2 = (1.0 - c * c) / (eta * eta)
    tir = sin_t2 >= 1.0
    ct = np.sqrt(np.maximum(1.0 - sin_t2, 0.0))
    rs = (c - eta * ct) / np.maximum(c + eta * ct, 1e-300)
    rp = (eta * c - ct) / np.maximum(eta * c + ct, 1e-300)
    return np.where(tir, 1.0, 0.5 * (rs * rs + rp * rp))[..., None]


def ggx_distribution(cos_h, alpha):
    """GGX / Trowbridge-Reitz: D = alpha^2 / (pi (cos^2 (alpha^2 - 1) + 1)^2) (Walter et al. 2007, eq. 33)."""
    c2 = np.asarray(cos_h, dtype=np.float64) ** 2
    a2 = alpha * alpha
    return np.where(c2 > 0.0, a2 / (np.pi * (c2 * (a2 - 1.0) + 1.0) ** 2), 0.0)


def beckmann_distribution(cos_h, alpha):
    """Beckmann: D = exp(-tan^2 / alpha^2) / (pi alpha^2 cos^4) (Walter et al. 2007, eq. 25)."""
    c = np.maximum(np.asarray(cos_h, dtype=np.float64), COS_EPSILON)
    c2 = c * c
    tan2 = (1.0 - c2) / c2
    return np.exp(-tan2 / (alpha * alpha)) / (np.pi * alpha * alpha * c2 * c2)


def smith_g1_ggx(cos_t, alpha):
    """Smith masking for GGX: G1 = 2 c / (c + sqrt(alpha^2 + (1 - alpha^2) c^2)) (Walter et al. 2007, eq. 34)."""
    c = np.clip(np.asarray(cos_t, dtype=np.float64), 0.0, 1.0)
    return c * smith_g1_over_cos_ggx(c, alpha)


def smith_g1_over_cos_ggx(cos_t, alpha):
    """G1 / cos for GGX, 2 / (c + sqrt(alpha^2 + (1 - alpha^2) c^2)): finite at grazing (c = 0)."""
    c = np.clip(np.asarray(cos_t, dtype=np.float64), 0.0, 1.0)
    return 2.0 / (c + np.sqrt(alpha * alpha + (1.0 - alpha * alpha) * c * c))


def smith_g1_beckmann(cos_t, alpha):
    """Smith masking for Beckmann, the rational fit of Walter et al. 2007, eq. 27 (a = 1 / (alpha tan))."""
    c = np.clip(np.asarray(cos_t, dtype=np.float64), 0.0, 1.0)
    return c * smith_g1_over_cos_beckmann(c, alpha)


def smith_g1_over_cos_beckmann(cos_t, alpha):
    """G1 / cos for Beckmann's rational fit, written without dividing by c (finite at grazing).

    With a = c / (alpha s), s = sin theta: G1 / c = (3.535 + 2.181 a) / (alpha s (1 + 2.276 a +
    2.577 a^2)) for a < 1.6, else 1 / c.
    """
    c = np.clip(np.asarray(cos_t, dtype=np.float64), 0.0, 1.0)
    s = np.sqrt(np.maximum(1.0 - c * c, 1e-300))
    a = c / (alpha * s)
    fit = (3.535 + 2.181 * a) / (alpha * s * (1.0 + 2.276 * a + 2.577 * a * a))
    return np.where(a < 1.6, fit, 1.0 / np.maximum(c, COS_EPSILON))


def microfacet_brdf(l, v, distribution="ggx", alpha=0.2, fresnel="schlick", f0=(0.04, 0.04, 0.04), ior=1.5):
    """Cook-Torrance microfacet BRDF f = D F G / (4 cos_i cos_o) (Walter et al. 2007, eq. 20).

    G is the separable Smith form G1(l) G1(v), as Mitsuba 3's ``roughconductor`` uses.
    ``fresnel`` is ``"schlick"`` (with ``f0``), ``"exact"`` (dielectric of index ``ior``)
    or ``"none"`` (F = 1).
    """
    cos_i, cos_o, cos_h, cos_d = _cosines(l, v)
    # G / (cos_i cos_o) is formed as (G1/cos)(G1/cos): finite at grazing, no 0/0.
    if distribution == "ggx":
        d = ggx_distribution(cos_h, alpha)
        g_over = smith_g1_over_cos_ggx(cos_i, alpha) * smith_g1_over_cos_ggx(cos_o, alpha)
    else:
        d = beckmann_distribution(cos_h, alpha)
        g_over = smith_g1_over_cos_beckmann(cos_i, alpha) * smith_g1_over_cos_beckmann(cos_o, alpha)
    if fresnel == "schlick":
        f = fresnel_schlick(cos_d, f0)
    elif fresnel == "exact":
        f = fresnel_dielectric(cos_d, ior)
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
        lobe = microfacet_brdf(
            l, v, source, params["alpha"], params["fresnel"], params["f0"], params["ior"]
        ) * np.asarray(params.get("specular", (1.0, 1.0, 1.0)))
    elif source == "blinn_phong":
        lobe = blinn_phong_brdf(l, v, params["exponent"], params["specular"])
    elif source == "ward":
        lobe = ward_brdf(l, v, params["alpha"], params["specular"])
    elif source == "lambert":
        return out
    else:
        raise ValueError(f"unknown analytic source {source!r}")
    return out + lobe
