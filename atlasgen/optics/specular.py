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

from atlasgen.shaderlang import Function, If, Let, Return, float_literal

__all__ = [
    "specular_exponent",
    "specular_normalisation",
    "blinn_phong_alpha",
    "specular_f_cos",
    "renderer_f_cos",
    "specular_declarations",
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


def specular_declarations() -> list:
    """The lobe above as shader declarations (:mod:`atlasgen.shaderlang`): the one shader statement of it.

    ``specular_exponent(gloss)``, ``specular_normalisation(s)`` and
    ``specular(n, l, v, s, k)`` = k max(N.H, 0)^s N.L (0 where N.L <= 0 or l + v
    is degenerate). k(s) = 1 / (2 pi int_0^{pi/2} cos^s(theta/2) cos(theta) sin(theta) dtheta),
    which integrates in closed form with x = cos(theta/2); for large s it tends to the
    familiar (s + 8) / (8 pi) (Akenine-Moeller et al., Real-Time Rendering, 3rd ed., 2008),
    which overshoots 1 for small s.
    """
    pi = float_literal(np.pi)
    return [
        Function("specular_exponent", "f32", (("gloss", "f32"),), (Return("exp2(1.0 + 12.0 * gloss)"),),
                 "gloss 0..1 -> Blinn-Phong exponent 2..8192, log-uniform so equal gloss steps look equal."),
        Function("specular_normalisation", "f32", (("s", "f32"),),
                 (Return(f"(s + 2.0) * (s + 4.0) / (8.0 * {pi} * (s + exp2(-0.5 * s)))"),),
                 "k(s) = (s + 2)(s + 4) / (8 pi (s + 2^(-s/2))): directional albedo exactly 1 at normal view."),
        Function("specular", "f32", (("n", "vec3"), ("l", "vec3"), ("v", "vec3"), ("s", "f32"), ("k", "f32")), (
            Let("f32", "n_dot_l", "dot(n, l)"),
            Let("vec3", "hv", "l + v"),
            Let("f32", "hv2", "dot(hv, hv)"),
            If("n_dot_l <= 0.0 || hv2 < 1e-12", (Return("0.0"),)),
            Let("f32", "n_dot_h", "max(dot(n, hv * inverseSqrt(hv2)), 0.0)"),
            Return("k * pow(n_dot_h, s) * n_dot_l"),
        ), "Energy-normalised Blinn-Phong lobe times the cosine (Blinn 1977): k max(N.H, 0)^s max(N.L, 0).\n"
           "s and k depend on the pixel only: computed once, outside the light loop."),
    ]  # fmt: skip
