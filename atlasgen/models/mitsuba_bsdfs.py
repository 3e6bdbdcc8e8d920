"""atlasgen's Mitsuba 3 BSDF plugins: the references models return from their hooks.

``atlasgen_model`` (:data:`MODEL_REFERENCE`)
    The renderer's shading equation with the atlas lookup replaced by the exact model the
    slice was baked from (:meth:`atlasgen.models.base.Model.renderer_f_cos`). As a BSDF,
    eval(w_i, w_o) must return f cos(theta_o), which is what that equation gives: A.rgb
    already holds the cosine fall-off and the specular lobe is a BRDF times max(N.L, 0)
    (:mod:`atlasgen.optics.specular`). N.L = cos(theta_o) and N.V = cos(theta_i). Like
    the renderer's g-buffer, a back face is shaded with the flipped normal. It samples
    the renderer's GGX lobe (D cos theta_m, reflected about m; Walter et al. 2007,
    section 5.3) with probability 1/2 and the cosine-weighted hemisphere otherwise,
    with the mixture's pdf; a slice without specular scale (A.a = 0) samples the cosine alone.
``atlasgen_brdf`` (:data:`BRDF_REFERENCE`)
    A separable material's source BSDF times the object's albedo, f cos for the full
    (w_i, w_o): the analytic source, or the Mitsuba BSDF given in the material.
``atlasgen_thinfilm`` (:data:`THIN_FILM_REFERENCE`)
    The iridescent model's physical reference, a thin-film microfacet BSDF evaluated per
    wavelength (:mod:`atlasgen.optics.thin_film`), meant for ``llvm_ad_spectral``.
``atlasgen_thinsheet`` (:data:`THIN_SHEET_REFERENCE`)
    The backlit model's physical reference: a thin sheet that reflects diffusely, transmits
    diffusely and has a GGX specular lobe (the renderer's) of constant reflectance (:func:`atlasgen.models.backlit.thin_sheet_f_cos`).
    It samples both hemispheres (reflection and transmission), each cosine-weighted.

Each is a Python plugin (Mitsuba runs those in the ``llvm_ad_*`` variants only) that
evaluates in NumPy; all but ``atlasgen_model`` sample the cosine-weighted hemisphere. mitsuba and drjit are
imported by the caller and handed in as ``mi``.
"""

from __future__ import annotations

import json

import numpy as np

from atlasgen.models import get_model
from atlasgen.models.backlit import thin_sheet_f_cos
from atlasgen.models.base import BRDF_REFERENCE, MODEL_REFERENCE, THIN_FILM_REFERENCE, THIN_SHEET_REFERENCE
from atlasgen.models.physical_fit import FittedSlice
from atlasgen.optics.specular import half_vector_cosine, specular_alpha
from atlasgen.optics.thin_film import thin_film_f_cos
from atlasgen.separable.source import make_source

__all__ = ["MODEL_REFERENCE", "BRDF_REFERENCE", "THIN_FILM_REFERENCE", "THIN_SHEET_REFERENCE", "LOBE_SAMPLING_PROBABILITY",
           "register_bsdfs", "thin_sheet_f_cos", "reflection_probability"]  # fmt: skip

_registered: set = set()
#: How often ``atlasgen_model`` samples its specular lobe rather than the cosine-weighted hemisphere.
LOBE_SAMPLING_PROBABILITY = 0.5


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


def reflection_probability(reflectance, transmittance) -> float:
    """The share of samples a thin sheet draws on w_i's side: its reflectance's part of R + T
    (mean over RGB), kept within [0.1, 0.9] so neither side goes unsampled."""
    r, t = float(np.mean(reflectance)), float(np.mean(transmittance))
    return 0.5 if r + t <= 0.0 else min(0.9, max(0.1, r / (r + t)))


def register_bsdfs(mi) -> None:
    """Register ``atlasgen_model``, ``atlasgen_brdf``, ``atlasgen_thinfilm`` and ``atlasgen_thinsheet`` (``mi.register_bsdf``)
    for the current variant; Mitsuba keeps plugins per variant, so call it after each ``set_variant``."""
    variant = mi.variant()
    if variant in _registered:
        return
    import drjit as dr

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
            if "fit_gloss" in spec:  # a from = "physical" material: its slice is the fit
                self.model = FittedSlice(self.model, spec["fit_gloss"])
            self.values = spec["params"]
            self.albedo = np.asarray(spec.get("albedo", (1.0, 1.0, 1.0)), dtype=np.float64)
            self.gloss = float(spec.get("gloss", 0.5))
            self.distribution = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, float(specular_alpha(self.gloss)), False)
            # A slice whose A.a is 0 everywhere has no lobe: cosine sampling alone is then f cos's own shape for a
            # lambert slice (each sample exactly its albedo), where half the samples in an empty lobe add variance.
            nl, nv = np.meshgrid(np.linspace(-1.0, 1.0, 64), np.linspace(0.0, 1.0, 32))
            alpha = np.asarray(self.model.evaluate(self.values, nl, nv))[..., 3]
            self.lobe_probability = LOBE_SAMPLING_PROBABILITY if np.any(alpha != 0.0) else 0.0

        def f_cos(self, wi, wo, side):
            nh, degenerate = half_vector_cosine(wi, wo)
            return self.model.renderer_f_cos(self.values, self.albedo, self.gloss,
                                             wo[:, 2] * side, wi[:, 2] * side, nh * side, lv_degenerate=degenerate)  # fmt: skip

        @staticmethod
        def _upper(si, wo):
            """(w_i, w_o) mirrored onto the side where w_i lies above the (flipped) normal, and the flip."""
            flip = dr.select(si.wi.z < 0, -1.0, 1.0)
            return mi.Vector3f(si.wi.x, si.wi.y, si.wi.z * flip), mi.Vector3f(wo.x, wo.y, wo.z * flip), flip

        def pdf(self, ctx, si, wo, active=True):
            wi_up, wo_up, _ = self._upper(si, wo)
            m = dr.normalize(wi_up + wo_up)
            o_dot_m = dr.dot(wo_up, m)
            # D(m) cos(theta_m) per microfacet normal; reflection maps d omega_m to d omega_o / (4 o.m).
            lobe = dr.select(o_dot_m > 0, self.distribution.pdf(wi_up, m) / (4.0 * dr.maximum(o_dot_m, 1e-12)), 0.0)
            p = self.lobe_probability
            mixed = (1.0 - p) * wo_up.z / dr.pi + p * lobe
            return dr.select(active & (wo_up.z > 0) & (wi_up.z > 0), mixed, 0.0)

        def sample(self, ctx, si, sample1, sample2, active=True):
            wi_up, _, flip = self._upper(si, si.wi)
            m, _ = self.distribution.sample(wi_up, sample2)
            mirrored = 2.0 * dr.dot(wi_up, m) * m - wi_up
            lobe = sample1 < self.lobe_probability
            wo_up = dr.select(lobe, mirrored, mi.warp.square_to_cosine_hemisphere(sample2))
            bs = mi.BSDFSample3f()
            bs.wo = mi.Vector3f(wo_up.x, wo_up.y, wo_up.z * flip)
            bs.pdf = self.pdf(ctx, si, bs.wo, active)
            bs.eta = 1.0
            bs.sampled_type = dr.select(lobe, mi.UInt32(+mi.BSDFFlags.GlossyReflection),
                                        mi.UInt32(+mi.BSDFFlags.DiffuseReflection))  # fmt: skip
            bs.sampled_component = 0
            value = self.eval(ctx, si, bs.wo, active)
            return bs, dr.select(active & (bs.pdf > 0), value / bs.pdf, 0.0)

        def to_string(self):
            return f"ModelReference[{self.model.type_name}]"

    class BrdfReference(_NumpyBSDF):
        """A separable material's source BSDF times the object's albedo, f cos(theta_o) for the full (w_i, w_o)."""

        def __init__(self, props):
            _NumpyBSDF.__init__(self, props)
            spec = json.loads(props["material"])
            self.source = make_source(spec["params"])
            self.albedo = np.asarray(spec.get("albedo", (1.0, 1.0, 1.0)), dtype=np.float64)

        def f_cos(self, wi, wo, side):
            l, v = wo * side[:, None], wi * side[:, None]
            value = self.source.f_cos(l, v) * self.albedo
            # A source that transmits (a film's back-light) sends light from below to the viewer too.
            lit = (l[:, 2:3] > 0.0) | ((l[:, 2:3] < 0.0) & self.source.transmits)
            return np.where(lit & (v[:, 2:3] > 0.0), value, 0.0)

        def to_string(self):
            return f"BrdfReference[{self.source.kind}]"

    class ThinSheet(_NumpyBSDF):
        """A thin sheet: diffuse reflection, diffuse transmission, a GGX coat (:func:`atlasgen.models.backlit.thin_sheet_f_cos`)."""

        def __init__(self, props):
            _NumpyBSDF.__init__(self, props)
            self.reflectance = np.array([props[f"reflectance_{c}"] for c in "rgb"], dtype=np.float64)
            self.transmittance = np.array([props[f"transmittance_{c}"] for c in "rgb"], dtype=np.float64)
            self.specular = float(props["specular"])
            self.alpha = float(props["alpha"])
            self.p_reflect = reflection_probability(self.reflectance, self.transmittance)

        def eval(self, ctx, si, wo, active=True):
            wi_np = np.stack([np.asarray(c.numpy(), np.float64) for c in (si.wi.x, si.wi.y, si.wi.z)], -1)
            if wi_np.shape[0] == 0:
                return mi.Color3f(0.0)
            wo_np = np.stack([np.asarray(c.numpy(), np.float64) for c in (wo.x, wo.y, wo.z)], -1)
            value = thin_sheet_f_cos(wi_np, wo_np, self.reflectance, self.transmittance, self.specular, self.alpha)
            return dr.select(active, _colour(mi, np.nan_to_num(value)), 0.0)

        def pdf(self, ctx, si, wo, active=True):
            same = wo.z * si.wi.z > 0
            side = dr.select(same, self.p_reflect, 1.0 - self.p_reflect)
            return dr.select(active & (si.wi.z != 0), side * dr.abs(wo.z) / dr.pi, 0.0)

        def sample(self, ctx, si, sample1, sample2, active=True):
            reflect = sample1 < self.p_reflect
            wo = mi.warp.square_to_cosine_hemisphere(sample2)
            below = dr.select(reflect, si.wi.z < 0, si.wi.z >= 0)
            wo = mi.Vector3f(wo.x, wo.y, dr.select(below, -wo.z, wo.z))
            bs = mi.BSDFSample3f()
            bs.wo = wo
            bs.pdf = self.pdf(ctx, si, wo, active)
            bs.eta = 1.0
            bs.sampled_type = dr.select(reflect, mi.UInt32(+mi.BSDFFlags.DiffuseReflection),
                                        mi.UInt32(+mi.BSDFFlags.DiffuseTransmission))  # fmt: skip
            bs.sampled_component = 0
            value = self.eval(ctx, si, wo, active)
            return bs, dr.select(active & (bs.pdf > 0), value / bs.pdf, 0.0)

        def to_string(self):
            return "ThinSheet[]"

    film_flags = (mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.DiffuseTransmission
                  | mi.BSDFFlags.FrontSide)  # fmt: skip

    class ThinFilm(mi.BSDF):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.m_flags = film_flags
            self.m_components = [film_flags]
            self.film = json.loads(props["film"])
            self.alpha = float(props["alpha"])
            self.base = self._spectrum(props, "colour")
            self.backlight = self._spectrum(props, "backlight") if "backlight_r" in props else None
            # A separable material's renderer draws albedo * f cos: its reference scales the whole film.
            self.tint = self._spectrum(props, "tint") if "tint_r" in props else None

        @staticmethod
        def _spectrum(props, name):
            """A diffuse BSDF whose eval carries the RGB colour ``name`` as Mitsuba upsamples it per wavelength."""
            return mi.load_dict({"type": "diffuse", "reflectance": {
                "type": "rgb", "value": [props[f"{name}_r"], props[f"{name}_g"], props[f"{name}_b"]]}})  # fmt: skip

        def _reflectance(self, plugin, ctx, si, active, count):
            """The plugin's reflectance at each lane's wavelengths, ``(N, count)`` (diffuse eval is R/pi cos)."""
            value = plugin.eval(ctx, si, mi.Vector3f(0.0, 0.0, 1.0), active)
            return np.stack([np.asarray(value[k].numpy(), np.float64) for k in range(count)], -1) * np.pi

        def eval(self, ctx, si, wo, active=True):
            wi_np = np.stack([np.asarray(c.numpy(), np.float64) for c in (si.wi.x, si.wi.y, si.wi.z)], -1)
            if wi_np.shape[0] == 0:
                return mi.Spectrum(0.0)
            wo_np = np.stack([np.asarray(c.numpy(), np.float64) for c in (wo.x, wo.y, wo.z)], -1)
            if mi.is_spectral:
                lam = np.stack([np.asarray(si.wavelengths[k].numpy(), np.float64) for k in range(len(si.wavelengths))], -1)
            else:  # RGB variants: the film at representative wavelengths of R, G, B
                lam = np.broadcast_to(np.array([610.0, 550.0, 465.0]), (wi_np.shape[0], 3))
            # Lanes with wi below the surface get 0 from the diffuse plugin, and from thin_film_f_cos too.
            base_np = self._reflectance(self.base, ctx, si, active, lam.shape[1])
            back_np = None if self.backlight is None else self._reflectance(self.backlight, ctx, si, active, lam.shape[1])
            value = thin_film_f_cos(wi_np, wo_np, lam, self.film, self.alpha, base_np, back_np)
            if self.tint is not None:
                value = value * self._reflectance(self.tint, ctx, si, active, lam.shape[1])
            value = np.ascontiguousarray(np.nan_to_num(value), dtype=np.float32)
            out = mi.Spectrum(*[mi.Float(value[:, k].copy()) for k in range(value.shape[1])])
            return dr.select(active, out, 0.0)

        def pdf(self, ctx, si, wo, active=True):
            return dr.select(active & (wo.z > 0), wo.z / dr.pi, 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            bs = mi.BSDFSample3f()
            bs.wo = mi.warp.square_to_cosine_hemisphere(sample2)
            bs.pdf = bs.wo.z / dr.pi
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.DiffuseReflection)
            bs.sampled_component = 0
            return bs, dr.select(active & (bs.pdf > 0), self.eval(ctx, si, bs.wo, active) / bs.pdf, 0.0)

        def to_string(self):
            return "ThinFilm[]"

    mi.register_bsdf(MODEL_REFERENCE, lambda props: ModelReference(props))
    mi.register_bsdf(BRDF_REFERENCE, lambda props: BrdfReference(props))
    mi.register_bsdf(THIN_FILM_REFERENCE, lambda props: ThinFilm(props))
    mi.register_bsdf(THIN_SHEET_REFERENCE, lambda props: ThinSheet(props))
    _registered.add(variant)
