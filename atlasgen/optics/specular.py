"""The renderer's specular lobe and shading equation, in NumPy and as shader declarations (the one statement of both).

Per light, with E the irradiance normal to the light direction, the deferred renderer adds

    L += E (albedo * A.rgb / pi + A.a * f_s cos),
    f_s cos = D(N.H) V(N.L, N.V) max(N.L, 0),
    D = alpha^2 / (pi ((N.H)^2 (alpha^2 - 1) + 1)^2),
    V = 0.5 / (N.L sqrt((N.V)^2 (1 - alpha^2) + alpha^2) + N.V sqrt((N.L)^2 (1 - alpha^2) + alpha^2)),
    alpha = max((1 - gloss)^2, SPECULAR_ALPHA_MIN),

where A is the material's (N.L, N.V) slice: the GGX / Trowbridge-Reitz distribution
(Walter et al., "Microfacet Models for Refraction through Rough Surfaces", EGSR 2007,
eq. 33) with its height-correlated Smith visibility V = G2 / (4 N.L N.V) (Heitz,
"Understanding the Masking-Shadowing Function in Microfacet-Based BRDFs", JCGT 3(2),
2014). f_s is a microfacet BRDF with Fresnel 1; A carries the Fresnel reflectance and
whatever else the lobe cannot express as a function of (N.L, N.V). The roughness
mapping alpha = (1 - gloss)^2 is the usual "perceptual roughness squared" (Burley,
"Physically-Based Shading at Disney", SIGGRAPH 2012 course). N.V is clamped to [0, 1]
as the atlas lookup clamps it. The lobe never creates energy: int f_s cos d omega <= 1
for every alpha and view (tests/optics/test_specular.py).

The renderer (lighting.wgsl, through the generated include), the WGSL/GLSL/HLSL includes
(:func:`atlasgen.shaders.specular.specular_declarations`, the same lobe as shader code), the
CPU rebuild and the Mitsuba model references (:func:`renderer_f_cos`) all take the lobe from here. The equation is documented once,
in docs/atlas-format.md, and recorded in each manifest as ``specular_lobe``
(:data:`atlasgen.contract.SPECULAR_LOBE`).
"""

from __future__ import annotations

import numpy as np

from atlasgen.contract import SPECULAR_ALPHA_MIN
from atlasgen.optics.microfacet import ggx_distribution, smith_visibility_correlated_ggx

__all__ = [
    "half_vector_cosine",
    "specular_alpha",
    "specular_fresnel_cosine",
    "specular_f_cos",
    "renderer_f_cos",
]


def specular_alpha(gloss):
    """GGX roughness of a g-buffer gloss: alpha = max((1 - gloss)^2, SPECULAR_ALPHA_MIN), gloss clamped to [0, 1].

    gloss 0 gives alpha 1 (a very rough lobe), gloss 0.5 gives 0.25, gloss 1 the floor
    :data:`atlasgen.contract.SPECULAR_ALPHA_MIN` (lighting.wgsl ``specular_alpha``).
    """
    r = 1.0 - np.clip(np.asarray(gloss, dtype=np.float64), 0.0, 1.0)
    return np.maximum(r * r, SPECULAR_ALPHA_MIN)


def specular_fresnel_cosine(n_dot_l, n_dot_v):
    """The cosine L.H at which a table model evaluates the Fresnel factor it puts in A.

    For fixed (N.L, N.V) the half vector is closest to N, so D and the lobe are largest,
    where l and v lie in one plane on opposite sides of N (azimuth pi); there
    L.H = cos((theta_l + theta_v) / 2) = sqrt((1 + N.L N.V - sin theta_l sin theta_v) / 2).
    A is baked before the g-buffer's roughness is known, so it cannot be the projection
    for one alpha; F at this cosine is exact at the mirror configuration N.L = N.V (where
    it is N.V) and at every lobe's peak, symmetric in l and v as F(L.H) is, and within
    11% (mean 2-4%) of the lobe-weighted least-squares projection of F(L.H) over azimuth
    for alpha <= 0.3, where F(N.V) is off by up to 10x away from the mirror
    (tests/models/test_fresnel.py).
    Cosines are clamped to [0, 1].
    """
    cl = np.clip(np.asarray(n_dot_l, dtype=np.float64), 0.0, 1.0)
    cv = np.clip(np.asarray(n_dot_v, dtype=np.float64), 0.0, 1.0)
    # The angle form keeps its precision at grazing cosines, where the algebraic one
    # (1 + c_l c_v - s_l s_v) / 2 cancels to 0.
    return np.cos(0.5 * (np.arccos(cl) + np.arccos(cv)))


def half_vector_cosine(l, v, n=None):
    """N.H of unit ``l``, ``v`` ``(..., 3)`` (``n`` per pair, or +z when ``None``), and where
    l + v = 0, which has no half vector: N.H is 0 there (the lobe then adds nothing).

    N.H = n . (l + v) / |l + v|.
    """
    h = np.asarray(l) + np.asarray(v)
    h2 = np.sum(h * h, axis=-1)
    along = h[..., 2] if n is None else np.sum(np.asarray(n) * h, axis=-1)
    return np.divide(along, np.sqrt(h2), out=np.zeros_like(h2), where=h2 > 1e-12), h2 <= 1e-12


def specular_f_cos(gloss: float, n_dot_l, n_dot_v, n_dot_h, lv_degenerate=None) -> np.ndarray:
    """The renderer's specular lobe times the cosine, f_s cos = D(N.H) V(N.L, N.V) max(N.L, 0).

    alpha = :func:`specular_alpha` (gloss); 0 where N.L <= 0, N.H <= 0 or where l + v is
    degenerate (``lv_degenerate``), as in the shader. N.V is clamped to [0, 1].
    """
    nl = np.asarray(n_dot_l, dtype=np.float64)
    alpha = float(specular_alpha(gloss))
    lit = np.clip(nl, 0.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):  # V is infinite only where N.L = N.V = 0 (times N.L = 0), masked below
        lobe = ggx_distribution(n_dot_h, alpha) * smith_visibility_correlated_ggx(lit, n_dot_v, alpha) * lit
    lobe = np.where(nl > 0.0, lobe, 0.0)
    if lv_degenerate is not None:
        lobe = np.where(lv_degenerate, 0.0, lobe)
    return lobe


def renderer_f_cos(rgba, albedo, gloss: float, n_dot_l, n_dot_v, n_dot_h, lv_degenerate=None) -> np.ndarray:
    """f cos(theta_l) of the renderer's equation for a slice value A = ``rgba``.

    f cos = albedo * A.rgb / pi + A.a * f_s cos (:func:`specular_f_cos`); ``rgba`` is
    ``(..., 4)``, what the atlas lookup (or the exact model in its place) returns at
    (N.L, N.V). Returns ``(..., 3)``.
    """
    m = np.asarray(rgba, dtype=np.float64)
    lobe = specular_f_cos(gloss, n_dot_l, n_dot_v, n_dot_h, lv_degenerate)
    return np.asarray(albedo, dtype=np.float64) * m[..., :3] / np.pi + (m[..., 3] * lobe)[..., None]
