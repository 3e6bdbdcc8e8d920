"""The renderer's specular lobe as shader declarations: ``specular_alpha`` and ``specular``, in every include language.

The lobe's one statement, and its NumPy twin, are :mod:`atlasgen.optics.specular`; this module
spells the same formulas for :mod:`atlasgen.shaders.lang`, and the include
(:mod:`atlasgen.shaders.include`) and the renderer's lighting pass call them.
"""

from __future__ import annotations

from atlasgen.contract import SPECULAR_ALPHA_MIN
from atlasgen.shaders.lang import Comment, Function, If, Let, Return, float_literal

__all__ = ["specular_declarations"]


def specular_declarations() -> list:
    """The lobe of :mod:`atlasgen.optics.specular` as shader declarations (:mod:`atlasgen.shaders.lang`): its one shader statement.

    ``specular_alpha(gloss)`` and ``specular(n, l, v, alpha)`` = D V max(N.L, 0) (0 where
    N.L <= 0, N.H <= 0 or l + v is degenerate: ``atlas_half_vector``'s fallback is 0,
    :mod:`atlasgen.shaders.common`). In f32, (N.H)^2 (alpha^2 - 1) + 1 loses
    every digit of alpha^2 near N.H = 1 for small alpha, so it is written
    |N x H|^2 + (N.H alpha)^2, the same number without the cancellation (as Filament does).
    """
    return [
        Function("specular_alpha", "f32", (("gloss", "f32"),), (
            Let("f32", "r", "1.0 - clamp(gloss, 0.0, 1.0)"),
            Return(f"max(r * r, {float_literal(SPECULAR_ALPHA_MIN)})"),
        ), "GGX roughness of a gloss: alpha = max((1 - gloss)^2, SPECULAR_ALPHA_MIN)."),
        Function("specular", "f32", (("n", "vec3"), ("l", "vec3"), ("v", "vec3"), ("alpha", "f32")), (
            Let("f32", "n_dot_l", "dot(n, l)"),
            If("n_dot_l <= 0.0", (Return("0.0"),)),
            Comment("l = -v has no half vector: h = 0, so N.H = 0 and the lobe adds nothing."),
            Let("vec3", "h", "atlas_half_vector(l, v, splat3(0.0))"),
            Let("f32", "n_dot_h", "dot(n, h)"),
            If("n_dot_h <= 0.0", (Return("0.0"),)),
            Let("vec3", "n_x_h", "cross(n, h)"),
            Let("f32", "a2", "alpha * alpha"),
            Let("f32", "t", "dot(n_x_h, n_x_h) + n_dot_h * n_dot_h * a2"),
            Let("f32", "nl", "min(n_dot_l, 1.0)"),
            Let("f32", "nv", "clamp(dot(n, v), 0.0, 1.0)"),
            Let("f32", "vis", "0.5 / (nl * sqrt(nv * nv * (1.0 - a2) + a2) + nv * sqrt(nl * nl * (1.0 - a2) + a2))"),
            Return("a2 / (ATLAS_PI * t * t) * vis * nl"),
        ), "GGX lobe with height-correlated Smith visibility, times the cosine (Walter et al. 2007; Heitz 2014):\n"
           "D(N.H) V(N.L, N.V) max(N.L, 0), a microfacet BRDF with Fresnel 1 (A carries F).\n"
           "alpha depends on the pixel only: computed once, outside the light loop."),
    ]  # fmt: skip
