"""The renderer's specular lobe and shading equation, in NumPy (the twin of lighting.wgsl).

Per light, with E the irradiance normal to the light direction, the deferred renderer adds

    L += E (albedo * A.rgb / pi + A.a * f_s cos),
    f_s cos = k(s) max(N.H, 0)^s max(N.L, 0),   s = 2^(1 + 12 gloss),
    k(s) = (s + 2)(s + 4) / (8 pi (s + 2^(-s/2))),

where A is the material's (N.L, N.V) slice. k(s) gives the Blinn-Phong lobe (Blinn,
"Models of Light Reflection for Computer Synthesized Pictures", SIGGRAPH 1977)
directional albedo exactly 1 at normal view; the derivation is in lighting.wgsl.
Validation evaluates the same equation on the CPU, with the exact model or a sampled
table in place of the atlas, so these functions are the single NumPy statement of it.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "specular_exponent",
    "specular_normalisation",
    "blinn_phong_alpha",
    "specular_f_cos",
    "renderer_f_cos",
]


def specular_exponent(gloss):
    """Blinn-Phong exponent s = 2^(1 + 12 gloss), from 2 (gloss 0) to 8192 (gloss 1).

    Log-uniform in gloss, so equal gloss steps look equal (lighting.wgsl ``specular_exponent``).
    """
    return np.exp2(1.0 + 12.0 * np.asarray(gloss, dtype=np.float64))


def specular_normalisation(s):
    """k(s) = (s + 2)(s + 4) / (8 pi (s + 2^(-s/2))).

    1 / the integral of cos^s(theta/2) cos(theta) over the hemisphere: the lobe's
    directional albedo at normal view is exactly 1 (lighting.wgsl ``specular_normalisation``).
    """
    s = np.asarray(s, dtype=np.float64)
    return (s + 2.0) * (s + 4.0) / (8.0 * np.pi * (s + np.exp2(-0.5 * s)))


def blinn_phong_alpha(gloss: float) -> float:
    """Beckmann roughness of the same width as the renderer's Blinn-Phong exponent.

    alpha = sqrt(2 / (s + 2)), s = :func:`specular_exponent` (Walter et al., "Microfacet
    Models for Refraction through Rough Surfaces", EGSR 2007, section 5.2).
    """
    return float(np.sqrt(2.0 / (float(specular_exponent(gloss)) + 2.0)))


def specular_f_cos(gloss: float, n_dot_l, n_dot_h, lv_degenerate=None) -> np.ndarray:
    """The renderer's specular lobe times the cosine, f_s cos = k(s) max(N.H, 0)^s max(N.L, 0).

    0 where N.L <= 0 or where l + v is degenerate (``lv_degenerate``), as in the shader.
    """
    nl = np.asarray(n_dot_l, dtype=np.float64)
    nh = np.asarray(n_dot_h, dtype=np.float64)
    s = float(specular_exponent(gloss))
    lobe = float(specular_normalisation(s)) * np.power(np.maximum(nh, 0.0), s) * np.maximum(nl, 0.0)
    lobe = np.where(nl > 0.0, lobe, 0.0)
    if lv_degenerate is not None:
        lobe = np.where(lv_degenerate, 0.0, lobe)
    return lobe


def renderer_f_cos(rgba, albedo, gloss: float, n_dot_l, n_dot_h, lv_degenerate=None) -> np.ndarray:
    """f cos(theta_l) of the renderer's equation for a slice value A = ``rgba``.

    f cos = albedo * A.rgb / pi + A.a * f_s cos (:func:`specular_f_cos`); ``rgba`` is
    ``(..., 4)``, what the atlas lookup (or the exact model in its place) returns at
    (N.L, N.V). Returns ``(..., 3)``.
    """
    m = np.asarray(rgba, dtype=np.float64)
    lobe = specular_f_cos(gloss, n_dot_l, n_dot_h, lv_degenerate)
    return np.asarray(albedo, dtype=np.float64) * m[..., :3] / np.pi + (m[..., 3] * lobe)[..., None]
