"""Microfacet terms: the GGX and Beckmann normal distributions and their Smith masking.

Walter, Marschner, Li & Torrance, "Microfacet Models for Refraction through Rough
Surfaces", EGSR 2007. Cosines are measured from the macro-surface normal; ``alpha`` is
the roughness (the slope's RMS for Beckmann). Masking is the separable Smith form
G2 = G1(l) G1(v), as Mitsuba 3's ``roughconductor`` and ``roughplastic`` use.
Functions that a BRDF divides by cos theta come in a ``_over_cos`` form as well, written
without that division, so that f = D F G2 / (4 cos_i cos_o) stays finite at grazing.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "COS_EPSILON",
    "DISTRIBUTIONS",
    "ggx_distribution",
    "beckmann_distribution",
    "smith_g1_ggx",
    "smith_g1_over_cos_ggx",
    "smith_g1_beckmann",
    "smith_g1_over_cos_beckmann",
    "smith_g2_separable_over_cos",
    "smith_visibility_correlated_ggx",
]

#: Smallest cosine used in a denominator (about 0.0057 degrees from the horizon).
COS_EPSILON = 1e-4
#: The normal distributions, by the names materials and Mitsuba give them.
DISTRIBUTIONS = ("ggx", "beckmann")


def ggx_distribution(cos_h, alpha):
    """GGX / Trowbridge-Reitz: D = alpha^2 / (pi (cos^2 (alpha^2 - 1) + 1)^2), 0 for cos_h <= 0.

    Walter et al. 2007, eq. 33. Normalised: int D(h) cos theta_h d omega_h = 1.
    """
    c = np.asarray(cos_h, dtype=np.float64)
    c2 = c * c
    a2 = alpha * alpha
    return np.where(c > 0.0, a2 / (np.pi * (c2 * (a2 - 1.0) + 1.0) ** 2), 0.0)


def beckmann_distribution(cos_h, alpha):
    """Beckmann: D = exp(-tan^2 / alpha^2) / (pi alpha^2 cos^4), 0 for cos_h <= 0.

    Walter et al. 2007, eq. 25. Normalised: int D(h) cos theta_h d omega_h = 1. The cosine
    is clamped to ``COS_EPSILON`` to keep tan^2 finite; below it the exponential is 0 in
    float64 for every alpha < 300.
    """
    raw = np.asarray(cos_h, dtype=np.float64)
    c = np.maximum(raw, COS_EPSILON)
    c2 = c * c
    tan2 = (1.0 - c2) / c2
    return np.where(raw > 0.0, np.exp(-tan2 / (alpha * alpha)) / (np.pi * alpha * alpha * c2 * c2), 0.0)


def smith_g1_over_cos_ggx(cos_t, alpha):
    """G1 / cos for GGX, 2 / (c + sqrt(alpha^2 + (1 - alpha^2) c^2)), c clamped to [0, 1]: finite at c = 0."""
    c = np.clip(np.asarray(cos_t, dtype=np.float64), 0.0, 1.0)
    return 2.0 / (c + np.sqrt(alpha * alpha + (1.0 - alpha * alpha) * c * c))


def smith_g1_ggx(cos_t, alpha):
    """Smith masking for GGX: G1 = 2 c / (c + sqrt(alpha^2 + (1 - alpha^2) c^2)) (Walter et al. 2007, eq. 34).

    G1(1) = 1; G1(0) = 0; G1 -> 1 as alpha -> 0.
    """
    c = np.clip(np.asarray(cos_t, dtype=np.float64), 0.0, 1.0)
    return c * smith_g1_over_cos_ggx(c, alpha)


def smith_g1_over_cos_beckmann(cos_t, alpha):
    """G1 / cos for Beckmann's rational fit, written without dividing by c (finite at grazing).

    With s = sin theta and a = c / (alpha s): G1 / c = (3.535 + 2.181 a) /
    (alpha s (1 + 2.276 a + 2.577 a^2)) for a < 1.6, else 1 / c (Walter et al. 2007,
    eq. 27, divided through by c = a alpha s).
    """
    c = np.clip(np.asarray(cos_t, dtype=np.float64), 0.0, 1.0)
    s = np.sqrt(np.maximum(1.0 - c * c, 1e-300))
    a = c / (alpha * s)
    near = np.minimum(a, 1.6)  # the fit is used below 1.6 only; capped, it cannot overflow elsewhere
    fit = (3.535 + 2.181 * near) / (alpha * s * (1.0 + 2.276 * near + 2.577 * near * near))
    return np.where(a < 1.6, fit, 1.0 / np.maximum(c, COS_EPSILON))


def smith_g1_beckmann(cos_t, alpha):
    """Smith masking for Beckmann, the rational fit of Walter et al. 2007, eq. 27.

    G1 = (3.535 a + 2.181 a^2) / (1 + 2.276 a + 2.577 a^2) for a = 1 / (alpha tan theta) < 1.6,
    else 1.
    """
    c = np.clip(np.asarray(cos_t, dtype=np.float64), 0.0, 1.0)
    return c * smith_g1_over_cos_beckmann(c, alpha)


def smith_g2_separable_over_cos(cos_i, cos_o, alpha, distribution: str):
    """G2 / (cos_i cos_o) for the separable Smith form G2 = G1(l) G1(v) of ``distribution``.

    Formed as (G1 / cos)(G1 / cos), so it stays finite where either cosine is 0; the BRDF
    is then f = D F (G2 / (cos_i cos_o)) / 4 (Walter et al. 2007, eq. 20).
    """
    if distribution == "ggx":
        return smith_g1_over_cos_ggx(cos_i, alpha) * smith_g1_over_cos_ggx(cos_o, alpha)
    if distribution == "beckmann":
        return smith_g1_over_cos_beckmann(cos_i, alpha) * smith_g1_over_cos_beckmann(cos_o, alpha)
    raise ValueError(f"unknown microfacet distribution {distribution!r}; expected one of {DISTRIBUTIONS}")


def smith_visibility_correlated_ggx(cos_i, cos_o, alpha):
    """V = G2 / (4 cos_i cos_o) for GGX's height-correlated Smith masking-shadowing.

    V = 0.5 / (c_i sqrt(c_o^2 (1 - alpha^2) + alpha^2) + c_o sqrt(c_i^2 (1 - alpha^2) + alpha^2)),
    cosines clamped to [0, 1] (Heitz, "Understanding the Masking-Shadowing Function in
    Microfacet-Based BRDFs", JCGT 3(2), 2014, eq. 99 with GGX's Lambda). Finite where one
    cosine is 0 (alpha > 0); f = D F V. V(1, 1) = 1/4; at alpha -> 0 it tends to
    1 / (4 c_i c_o), the mirror limit.
    """
    ci = np.clip(np.asarray(cos_i, dtype=np.float64), 0.0, 1.0)
    co = np.clip(np.asarray(cos_o, dtype=np.float64), 0.0, 1.0)
    a2 = alpha * alpha
    return 0.5 / (ci * np.sqrt(co * co * (1.0 - a2) + a2) + co * np.sqrt(ci * ci * (1.0 - a2) + a2))
