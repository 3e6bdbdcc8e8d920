"""Reference BSDFs for a baked material: the *model* reference and, where one exists, a *physical* one.

Model reference (``atlasgen_model``)
    The renderer's shading equation with the atlas lookup replaced by the exact model
    the slice was baked from. Per light, the renderer adds (lighting.wgsl, docs/scenes.md)

        L += E (albedo * A.rgb / pi + A.a * f_s cos),
        f_s cos = k(s) max(N.H, 0)^s max(N.L, 0),   s = 2^(1 + 12 gloss),

    with A = atlas(N.L, N.V) and the renderer's own normalisation k(s)
    (:func:`atlasgen.render.lighting.specular_normalisation`). As a BSDF, eval(w_i, w_o) must return f cos(theta_o), and
    the terms in brackets are exactly that: A.rgb already holds the cosine fall-off
    (a ``lambert`` slice is colour * max(N.L, 0)), and the specular lobe is a BRDF times
    max(N.L, 0). So the model reference returns

        albedo * M.rgb(N.L, N.V) / pi + M.a(N.L, N.V) f_s cos,   M = model.evaluate,

    with N.L = cos(theta_o) and N.V = cos(theta_i) clamped to the table's domain as the
    sampler's clamp-to-edge addressing does. Rendering it and the atlas with the same
    scene isolates what the atlas costs: resolution, 8-bit quantization, filtering.
    Like the renderer's g-buffer, a back face is shaded with the flipped normal.

Separable materials
    The renderer adds L += E albedo f cos with f rebuilt from the factors (lighting.wgsl),
    so the reference (``atlasgen_brdf``) is the source BSDF itself, f cos for the full
    (w_i, w_o), times the albedo: the Mitsuba BSDF given in the material
    (``source = "mitsuba"``, evaluated by Mitsuba) or the analytic source.

Physical references (:func:`physical_reference`)
    - ``fresnel``: Mitsuba's ``roughplastic`` (exact Fresnel, Beckmann lobe of the
      same width as the renderer's Blinn-Phong, alpha = sqrt(2 / (s + 2))).
    - ``sss``: ``volpath`` through a homogeneous skin medium inside the sphere (index-matched boundary).
    - ``iridescent``: a thin-film microfacet BSDF evaluated per wavelength in the
      ``llvm_ad_spectral`` variant (``atlasgen_thinfilm``).
    - ``lambert``: Mitsuba's ``diffuse`` with reflectance albedo * colour, the
      consistency gate: it shares no code with atlasgen, so agreement proves that units,
      pi, camera and tone map line up.
    ``backlit`` and ``toon`` are artistic models with no physical counterpart.
"""

from __future__ import annotations

import json

import numpy as np

from atlasgen.errors import InputError

__all__ = [
    "MODEL_REFERENCE",
    "BRDF_REFERENCE",
    "LUT_TYPES",
    "renderer_f_cos",
    "register_references",
    "model_reference",
    "physical_reference",
    "PHYSICAL_TYPES",
    "blinn_phong_alpha",
]

MODEL_REFERENCE = "atlasgen_model"
BRDF_REFERENCE = "atlasgen_brdf"
#: Model types whose slice is one (N.L, N.V) table evaluated by ``Model.evaluate``.
LUT_TYPES = ("lambert", "fresnel", "iridescent", "sss", "backlit", "toon")
#: Model types with a physical reference.
PHYSICAL_TYPES = ("lambert", "fresnel", "sss", "iridescent")
_registered: set = set()


def _specular_exponent(gloss):
    from atlasgen.render.lighting import specular_exponent

    return specular_exponent(gloss)


def _specular_normalisation(s):
    # The renderer's own k(s), so the reference can never drift from lighting.wgsl.
    from atlasgen.render.lighting import specular_normalisation

    return specular_normalisation(s)


def blinn_phong_alpha(gloss: float) -> float:
    """Beckmann roughness of the same width as the renderer's Blinn-Phong exponent.

    alpha = sqrt(2 / (s + 2)) (Walter et al., "Microfacet Models for Refraction through
    Rough Surfaces", EGSR 2007, section 5.2).
    """
    return float(np.sqrt(2.0 / (float(_specular_exponent(gloss)) + 2.0)))


def renderer_f_cos(model, values: dict, albedo, gloss: float, n_dot_l, n_dot_v, n_dot_h, lv_degenerate=None):
    """f cos(theta_l) of the renderer's equation with the exact model in place of the atlas.

    f cos = albedo * M.rgb / pi + M.a * k(s) * max(N.H, 0)^s * max(N.L, 0)
    (lighting.wgsl: Blinn 1977 with the renderer's exact normalisation k(s)),
    with M = ``model.evaluate(values, clamp(N.L, -1, 1), clamp(N.V, 0, 1))``. The
    specular term is 0 where N.L <= 0 or l + v is degenerate (``lv_degenerate``), as in
    the shader. Returns ``(..., 3)``.
    """
    nl = np.asarray(n_dot_l, dtype=np.float64)
    nv = np.asarray(n_dot_v, dtype=np.float64)
    nh = np.asarray(n_dot_h, dtype=np.float64)
    m = np.asarray(model.evaluate(values, np.clip(nl, -1.0, 1.0), np.clip(nv, 0.0, 1.0)), dtype=np.float64)
    s = float(_specular_exponent(gloss))
    lobe = float(_specular_normalisation(s)) * np.power(np.maximum(nh, 0.0), s) * np.maximum(nl, 0.0)
    lobe = np.where(nl > 0.0, lobe, 0.0)
    if lv_degenerate is not None:
        lobe = np.where(lv_degenerate, 0.0, lobe)
    return np.asarray(albedo, dtype=np.float64) * m[..., :3] / np.pi + (m[..., 3] * lobe)[..., None]


def _local_arrays(dr, si, wo):
    """(w_i, w_o, side) as NumPy: side = -1 on back faces, where the renderer flips n."""
    back = dr.dot(si.n, si.to_world(si.wi)) < 0.0
    side = np.where(np.asarray(back.numpy(), dtype=bool), -1.0, 1.0)
    wi = np.stack([np.asarray(c.numpy(), dtype=np.float64) for c in (si.wi.x, si.wi.y, si.wi.z)], -1)
    w = np.stack([np.asarray(c.numpy(), dtype=np.float64) for c in (wo.x, wo.y, wo.z)], -1)
    return wi, w, side


def _colour(mi, rgb: np.ndarray):
    rgb = np.ascontiguousarray(rgb, dtype=np.float32)
    return mi.Color3f(mi.Float(rgb[:, 0].copy()), mi.Float(rgb[:, 1].copy()), mi.Float(rgb[:, 2].copy()))


def register_references(mi) -> None:
    """Register ``atlasgen_model`` and ``atlasgen_brdf`` (``mi.register_bsdf``) for the current variant."""
    variant = mi.variant()
    if variant in _registered:
        return
    import drjit as dr

    from atlasgen.models import get_model

    flags = (
        mi.BSDFFlags.DiffuseReflection
        | mi.BSDFFlags.GlossyReflection
        | mi.BSDFFlags.DiffuseTransmission
        | mi.BSDFFlags.FrontSide
        | mi.BSDFFlags.BackSide
    )

    class _NumpyBSDF(mi.BSDF):
        """Evaluates f cos in NumPy; samples the cosine-weighted hemisphere of w_i's side."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.m_flags = flags
            self.m_components = [flags]

        def f_cos(self, wi, wo, side):  # (N, 3) arrays -> (N, 3)
            raise NotImplementedError

        def eval(self, ctx, si, wo, active=True):
            wi_np, wo_np, side = _local_arrays(dr, si, wo)
            if wi_np.shape[0] == 0:
                return mi.Color3f(0.0)
            value = np.nan_to_num(self.f_cos(wi_np, wo_np, side), nan=0.0, posinf=0.0, neginf=0.0)
            return dr.select(active, _colour(mi, value), 0.0)

        def pdf(self, ctx, si, wo, active=True):
            cos = dr.abs(wo.z)
            return dr.select(active & (wo.z * si.wi.z > 0), cos / dr.pi, 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            wo = mi.warp.square_to_cosine_hemisphere(sample2)
            wo = mi.Vector3f(wo.x, wo.y, dr.select(si.wi.z < 0, -wo.z, wo.z))
            bs = mi.BSDFSample3f()
            bs.wo = wo
            bs.pdf = dr.abs(wo.z) / dr.pi
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.DiffuseReflection)
            bs.sampled_component = 0
            value = self.eval(ctx, si, wo, active)
            return bs, dr.select(active & (bs.pdf > 0), value / bs.pdf, 0.0)

    class ModelReference(_NumpyBSDF):
        """The renderer's equation with the exact atlasgen model in place of the atlas."""

        def __init__(self, props):
            _NumpyBSDF.__init__(self, props)
            spec = json.loads(props["material"])
            self.model = get_model(spec["type"])
            self.values = spec["params"]
            self.albedo = np.asarray(spec.get("albedo", (1.0, 1.0, 1.0)), dtype=np.float64)
            self.gloss = float(spec.get("gloss", 0.5))

        def f_cos(self, wi, wo, side):
            h = wi + wo
            h2 = (h * h).sum(-1)
            nh = np.divide(h[:, 2], np.sqrt(h2), out=np.zeros_like(h2), where=h2 > 1e-12) * side
            return renderer_f_cos(self.model, self.values, self.albedo, self.gloss,
                                  wo[:, 2] * side, wi[:, 2] * side, nh, lv_degenerate=h2 < 1e-12)  # fmt: skip

        def to_string(self):
            return f"ModelReference[{self.model.type_name}]"

    class BrdfReference(_NumpyBSDF):
        """A separable material's source BSDF times the object's albedo, f cos(theta_o) for the full (w_i, w_o)."""

        def __init__(self, props):
            _NumpyBSDF.__init__(self, props)
            from atlasgen.separable.source import make_source

            spec = json.loads(props["material"])
            self.source = make_source(spec["params"])
            self.albedo = np.asarray(spec.get("albedo", (1.0, 1.0, 1.0)), dtype=np.float64)

        def f_cos(self, wi, wo, side):
            l, v = wo * side[:, None], wi * side[:, None]
            value = self.source.f_cos(l, v) * self.albedo
            return np.where((l[:, 2:3] > 0.0) & (v[:, 2:3] > 0.0), value, 0.0)

        def to_string(self):
            return f"BrdfReference[{self.source.kind}]"

    mi.register_bsdf(MODEL_REFERENCE, lambda props: ModelReference(props))
    mi.register_bsdf(BRDF_REFERENCE, lambda props: BrdfReference(props))
    _registered.add(variant)


def model_reference(entry: dict, albedo=(1.0, 1.0, 1.0), gloss: float = 0.5) -> dict:
    """The Mitsuba BSDF dict of a manifest entry's model reference.

    LUT materials get ``atlasgen_model`` (see the module docstring); separable ones their
    source BSDF. Raises :class:`InputError` for a material no reference can be built
    for (an unknown type).
    """
    kind = entry.get("type")
    if kind in LUT_TYPES:
        material = {"type": kind, "params": entry["params"], "albedo": [float(a) for a in albedo], "gloss": float(gloss)}
        return {"type": MODEL_REFERENCE, "material": json.dumps(material, sort_keys=True)}
    if kind == "separable":
        material = {"params": entry["params"], "albedo": [float(a) for a in albedo]}
        return {"type": BRDF_REFERENCE, "material": json.dumps(material, sort_keys=True)}
    raise InputError(
        f"material {entry.get('name')!r}: no reference for model type {kind!r}; "
        f"expected one of {', '.join(LUT_TYPES + ('separable',))}"
    )


def physical_reference(entry: dict, albedo=(1.0, 1.0, 1.0), gloss: float = 0.5):
    """``(bsdf dict, extras)`` of the physical reference, or ``None`` where there is none.

    ``extras`` may hold ``variant`` (a Mitsuba variant other than ``llvm_ad_rgb``),
    ``integrator`` (a dict; default ``atlasgen_direct``), ``interior`` (a medium dict for
    closed objects), ``stochastic`` (render with ``--physical-spp``) and ``builtin_only``
    (no Python plugins: keep Dr.Jit's symbolic calls).
    """
    kind, p = entry.get("type"), entry.get("params", {})
    colour = np.asarray(p.get("colour", (1.0, 1.0, 1.0)), dtype=np.float64) * np.asarray(albedo, dtype=np.float64)
    if kind == "lambert":
        # Mitsuba's own Lambertian: the consistency gate (units, pi, camera, tone map).
        return {"type": "diffuse", "reflectance": {"type": "rgb", "value": colour.tolist()}}, {}
    if kind == "fresnel":
        return {
            "type": "roughplastic",
            "distribution": "beckmann",
            "alpha": blinn_phong_alpha(gloss),
            "int_ior": float(p["ior"]),
            "ext_ior": 1.0,
            "diffuse_reflectance": {"type": "rgb", "value": colour.tolist()},
            "specular_reflectance": {"type": "rgb", "value": [min(1.0, float(p["specular"]))] * 3},
            "nonlinear": False,
        }, {}
    if kind == "sss":
        from atlasgen.validate.physical import skin_medium

        medium, _ = skin_medium(entry, colour)
        # An index-matched (null) boundary: next-event estimation cannot pass a smooth
        # dielectric to reach a point light, so a dielectric sphere would be lit only
        # indirectly. The interface's Fresnel reflection is the price (docs/validation.md).
        return {"type": "null"}, {
            "integrator": {"type": "volpath", "max_depth": 256, "rr_depth": 64},
            "interior": medium,
            "stochastic": True,
            "builtin_only": True,
        }
    if kind == "iridescent":
        from atlasgen.validate.physical import THIN_FILM_REFERENCE

        film = {k: p[k] for k in ("thickness", "film_ior", "base_ior", "base_k")}
        return {
            "type": THIN_FILM_REFERENCE,
            "film": json.dumps(film, sort_keys=True),
            "alpha": blinn_phong_alpha(gloss),
            "colour_r": float(p["colour"][0] * albedo[0]),
            "colour_g": float(p["colour"][1] * albedo[1]),
            "colour_b": float(p["colour"][2] * albedo[2]),
        }, {"variant": "llvm_ad_spectral"}
    return None
