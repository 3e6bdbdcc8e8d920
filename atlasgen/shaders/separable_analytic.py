"""Shader code that evaluates an analytic BRDF in closed form: the renderer's no-atlas baseline.

``analytic_f_cos(n, l, v, p, f0, specular, diffuse)`` mirrors
:func:`atlasgen.separable.analytic.evaluate_analytic` times cos(theta_l) term by term: the
same GGX / Beckmann D (Walter et al. 2007, eqs. 33 and 25), the same separable Smith
G1 / cos forms (eqs. 34 and 27, :mod:`atlasgen.optics.microfacet`), the same Fresnel
(Schlick 1994 eq. 15 with an RGB F0, or the exact dielectric) and the same clamps.
A material's parameters are the small table of :class:`atlasgen.io.manifest.AnalyticRepresentation`;
the lighting pass passes them as literals (:func:`analytic_call`).
"""

from __future__ import annotations

from atlasgen.optics.microfacet import COS_EPSILON
from atlasgen.shaders.lang import Assign, Comment, Function, If, Let, Return, Var, float_literal

__all__ = ["DISTRIBUTION_CODES", "FRESNEL_CODES", "analytic_declarations", "analytic_call"]

#: ``p.x`` of the shader call: the lobe (``lambert``: no lobe, diffuse only).
DISTRIBUTION_CODES = {"ggx": 0, "beckmann": 1, "lambert": 2}
#: ``p.z`` of the shader call.
FRESNEL_CODES = {"schlick": 0, "exact": 1, "none": 2}

_EPS = float_literal(COS_EPSILON)


def analytic_declarations() -> list:
    """The generic closed-form evaluation, for every include language (:mod:`atlasgen.shaders.lang`)."""
    g1 = (("c", "f32"), ("a", "f32"), ("beckmann", "bool"))
    return [
        Comment("---- atlasgen: analytic BRDFs evaluated in closed form (no atlas data) ----\n"
                "f = diffuse / pi + specular * F D G1(l) G1(v) / (4 cos_l cos_v), Walter et al. 2007;\n"
                "p = (distribution 0 ggx / 1 beckmann / 2 none, alpha, fresnel 0 schlick / 1 exact / 2 none, ior)."),
        Function("analytic_g1_over_cos", "f32", g1, (
            Let("f32", "cc", "clamp(c, 0.0, 1.0)"),
            If("!beckmann", (Return("2.0 / (cc + sqrt(a * a + (1.0 - a * a) * cc * cc))"),)),
            Let("f32", "s", "sqrt(max(1.0 - cc * cc, 1e-30))"),
            Let("f32", "t", "cc / (a * s)"),
            If("t < 1.6", (Return("(3.535 + 2.181 * t) / (a * s * (1.0 + 2.276 * t + 2.577 * t * t))"),)),
            Return(f"1.0 / max(cc, {_EPS})"),
        ), "Smith G1 / cos (GGX exact, Beckmann's rational fit), finite at grazing."),
        Function("analytic_distribution", "f32", g1, (
            If("c <= 0.0", (Return("0.0"),)),
            Let("f32", "a2", "a * a"),
            If("!beckmann", (
                Let("f32", "d", "c * c * (a2 - 1.0) + 1.0"),
                Return("a2 / (ATLAS_PI * d * d)"),
            )),
            Let("f32", "cm", f"max(c, {_EPS})"),
            Let("f32", "c2", "cm * cm"),
            Return("exp(-((1.0 - c2) / c2) / a2) / (ATLAS_PI * a2 * c2 * c2)"),
        ), "GGX (Walter eq. 33) or Beckmann (eq. 25) normal distribution D(cos theta_h)."),
        Function("analytic_fresnel", "vec3", (("c", "f32"), ("p", "vec4"), ("f0", "vec3")), (
            Let("f32", "cd", "clamp(c, 0.0, 1.0)"),
            If("p.z < 0.5", (Return("f0 + (splat3(1.0) - f0) * pow(1.0 - cd, 5.0)"),)),
            If("p.z > 1.5", (Return("splat3(1.0)"),)),
            Let("f32", "eta", "p.w"),
            Let("f32", "st2", "(1.0 - cd * cd) / (eta * eta)"),
            If("st2 >= 1.0", (Return("splat3(1.0)"),)),
            Let("f32", "ct", "sqrt(1.0 - st2)"),
            Let("f32", "rs", "(cd - eta * ct) / (cd + eta * ct)"),
            Let("f32", "rp", "(eta * cd - ct) / (eta * cd + ct)"),
            Return("splat3(0.5 * (rs * rs + rp * rp))"),
        ), "Schlick with RGB F0 (p.z = 0), exact dielectric of index p.w (1), or 1 (2)."),
        Function("analytic_f_cos", "vec3", (("n", "vec3"), ("l", "vec3"), ("v", "vec3"), ("p", "vec4"),
                                             ("f0", "vec3"), ("specular", "vec3"), ("diffuse", "vec3")), (
            Let("f32", "nl", "dot(n, l)"),
            Let("f32", "nv", "dot(n, v)"),
            If("nl <= 0.0 || nv <= 0.0", (Return("splat3(0.0)"),)),
            Var("vec3", "f", "diffuse / ATLAS_PI"),
            If("p.x < 1.5", (
                Let("vec3", "h", "atlas_half_vector(l, v, n)"),
                Let("bool", "beckmann", "p.x > 0.5"),
                Let("f32", "d", "analytic_distribution(clamp(dot(n, h), 0.0, 1.0), p.y, beckmann)"),
                Let("f32", "g", "analytic_g1_over_cos(nl, p.y, beckmann) * analytic_g1_over_cos(nv, p.y, beckmann)"),
                Assign("f", "specular * analytic_fresnel(dot(l, h), p, f0) * (0.25 * d * g)", "+="),
            )),
            Return("f * nl"),
        ), "f cos(theta_l) of an analytic BRDF in 1/sr; 0 below the horizon."),
    ]  # fmt: skip


def _vec(values) -> str:
    return ", ".join(float_literal(float(x)) for x in values)


def analytic_call(rep, n: str = "n", l: str = "l", v: str = "v") -> str:
    """The WGSL call of ``analytic_f_cos`` for one :class:`~atlasgen.io.manifest.AnalyticRepresentation`,
    its parameters as f32 literals."""
    p = (DISTRIBUTION_CODES[rep.distribution], rep.alpha, FRESNEL_CODES[rep.fresnel], rep.ior)
    return (
        f"analytic_f_cos({n}, {l}, {v}, vec4<f32>({_vec(p)}), vec3<f32>({_vec(rep.f0)}), "
        f"vec3<f32>({_vec(rep.specular)}), vec3<f32>({_vec(rep.diffuse)}))"
    )
