"""Physical references: what the cheap model costs against a physically based render.

- ``sss``: light transport through a homogeneous scattering medium inside the sphere,
  rendered with Mitsuba's ``volpath``. The boundary is index-matched (Mitsuba ``null``):
  next-event estimation cannot reach a point light through a smooth dielectric. The medium is Jensen et al.'s
  measured skin ("A Practical Model for Subsurface Light Transport", SIGGRAPH 2001,
  table 2, Skin1: sigma_s' = (0.74, 0.88, 1.01) /mm, sigma_a = (0.032, 0.17, 0.48) /mm,
  eta = 1.3), with the reduced scattering coefficient and an isotropic phase function
  (the similarity relation). Scene units are scaled so the sphere's radius is the
  material's curvature radius in mm: that is the scale Penner's pre-integration assumes.
- ``iridescent``: ``atlasgen_thinfilm``, a Beckmann microfacet BSDF whose Fresnel term is
  the film stack's exact Airy reflectance per wavelength (Belcour & Barla 2017, eq. 2,
  without their Fourier-space approximation), over a Lambertian base weighted by the
  transmission (1 - R(N.L)) (1 - R(N.V)); rendered in ``llvm_ad_spectral``.
- ``fresnel`` and ``lambert``: Mitsuba built-ins (:func:`.references.physical_reference`).
"""

from __future__ import annotations

import json
from functools import lru_cache

import numpy as np

__all__ = [
    "THIN_FILM_REFERENCE",
    "SKIN1_SIGMA_S_REDUCED",
    "SKIN1_SIGMA_A",
    "SKIN1_IOR",
    "skin_medium",
    "plane_stand_in",
    "describe_physical",
    "register_physical",
    "film_table",
]

THIN_FILM_REFERENCE = "atlasgen_thinfilm"
#: Jensen et al. 2001, table 2, Skin1 (per mm).
SKIN1_SIGMA_S_REDUCED = (0.74, 0.88, 1.01)
SKIN1_SIGMA_A = (0.032, 0.17, 0.48)
SKIN1_IOR = 1.3
#: World radius of the validation scenes' sphere (unit sphere scaled by 0.5).
_SPHERE_RADIUS = 0.5
_registered: set = set()


def skin_medium(entry: dict, colour=None, object_radius: float = _SPHERE_RADIUS):
    """``(homogeneous medium dict, ior)`` for an ``sss`` material.

    Coefficients per scene unit are the per-mm ones times (radius_mm / object_radius),
    so the sphere is as large, in mean free paths, as a ``radius`` mm ball of skin.
    """
    mm_per_unit = float(entry["params"]["radius"]) / float(object_radius)
    s = np.asarray(SKIN1_SIGMA_S_REDUCED) * mm_per_unit
    a = np.asarray(SKIN1_SIGMA_A) * mm_per_unit
    t = s + a
    medium = {
        "type": "homogeneous",
        # RGB values must lie in [0, 1]: the largest coefficient goes into ``scale``.
        "sigma_t": {"type": "rgb", "value": (t / t.max()).tolist()},
        "scale": float(t.max()),
        "albedo": {"type": "rgb", "value": (s / t).tolist()},
        "phase": {"type": "isotropic"},
        "sample_emitters": True,
    }
    return medium, SKIN1_IOR


def plane_stand_in(entry: dict, albedo) -> dict:
    """A diffuse plane for references whose material needs a closed surface."""
    colour = np.asarray(entry["params"].get("colour", (1.0, 1.0, 1.0))) * np.asarray(albedo)
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": colour.tolist()}}


def describe_physical(entry: dict) -> str:
    kind = entry["type"]
    return {
        "lambert": "Mitsuba diffuse (the consistency gate)",
        "fresnel": "Mitsuba roughplastic: exact Fresnel, Beckmann lobe of the renderer's width",
        "sss": "volpath through Jensen 2001 Skin1 inside the sphere, index-matched boundary (plane: diffuse stand-in)",
        "iridescent": "thin-film Beckmann microfacet, Airy reflectance per wavelength (llvm_ad_spectral)",
    }.get(kind, kind)


@lru_cache(maxsize=16)
def film_table(thickness: float, film_ior: float, base_ior: float, base_k: float):
    """Film reflectance R(cos, lambda) on a grid: cosines 0..1 (1025), wavelengths 360..830 nm (1 nm)."""
    from atlasgen.models.iridescent import film_reflectance

    cos = np.linspace(0.0, 1.0, 1025)
    lam = np.arange(360.0, 831.0, 1.0)
    table = film_reflectance(cos, lam, thickness, film_ior, base_ior, base_k)
    table.setflags(write=False)
    return cos, lam, table


def _lookup(table_set, cos, lam):
    """Bilinear R at (cos, lambda), elementwise."""
    grid_c, grid_l, table = table_set
    x = np.clip(cos, 0.0, 1.0) * (len(grid_c) - 1)
    y = np.clip(lam - grid_l[0], 0.0, grid_l[-1] - grid_l[0]) / (grid_l[1] - grid_l[0])
    x0 = np.minimum(x.astype(np.int64), len(grid_c) - 2)
    y0 = np.minimum(y.astype(np.int64), len(grid_l) - 2)
    fx, fy = x - x0, y - y0
    return ((table[x0, y0] * (1 - fx) + table[x0 + 1, y0] * fx) * (1 - fy)
            + (table[x0, y0 + 1] * (1 - fx) + table[x0 + 1, y0 + 1] * fx) * fy)  # fmt: skip


def _beckmann_d(cos_h, alpha):
    c2 = np.clip(cos_h, 1e-6, 1.0) ** 2
    tan2 = (1.0 - c2) / c2
    return np.where(cos_h > 0, np.exp(-tan2 / (alpha * alpha)) / (np.pi * alpha * alpha * c2 * c2), 0.0)


def _smith_g1_beckmann(cos_t, alpha):
    """Walter et al. 2007, eq. 27 (rational fit of the Beckmann Smith G1)."""
    c = np.clip(cos_t, 1e-6, 1.0)
    a = c / (alpha * np.sqrt(np.maximum(1.0 - c * c, 1e-12)))
    g = (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)
    return np.where(a < 1.6, g, 1.0)


def thin_film_f_cos(wi, wo, lam, film, alpha, base_rgb_spectrum):
    """f cos(theta_o) of the thin-film microfacet BSDF, per lane and wavelength.

    f = D(h) G(wi, wo) R(wi.h, lambda) / (4 cos_i cos_o) + base(lambda) (1 - R(cos_o)) (1 - R(cos_i)) / pi
    (Cook & Torrance 1982; Walter et al. 2007; Belcour & Barla 2017).
    ``wi``, ``wo``: (N, 3) local; ``lam``: (N, S) nm; ``base_rgb_spectrum``: (N, S).
    """
    table = film_table(film["thickness"], film["film_ior"], film["base_ior"], film["base_k"])
    ci, co = wi[:, 2], wo[:, 2]
    valid = (ci > 0) & (co > 0)
    h = wi + wo
    h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
    cos_d = np.clip((wi * h).sum(1), 0.0, 1.0)
    d = _beckmann_d(h[:, 2], alpha)
    g = _smith_g1_beckmann(ci, alpha) * _smith_g1_beckmann(co, alpha)
    spec = (d * g / (4.0 * np.maximum(ci, 1e-6)))[:, None] * _lookup(table, cos_d[:, None], lam)
    r_o = _lookup(table, co[:, None], lam)
    r_i = _lookup(table, ci[:, None], lam)
    diffuse = base_rgb_spectrum * (1.0 - r_o) * (1.0 - r_i) / np.pi * np.maximum(co, 0.0)[:, None]
    return np.where(valid[:, None], spec + diffuse, 0.0)


def register_physical(mi) -> None:
    """Register ``atlasgen_thinfilm`` for the current variant (meant for ``llvm_ad_spectral``)."""
    variant = mi.variant()
    if variant in _registered:
        return
    import drjit as dr

    flags = mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide

    class ThinFilm(mi.BSDF):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.m_flags = flags
            self.m_components = [flags]
            self.film = json.loads(props["film"])
            self.alpha = float(props["alpha"])
            self.base = mi.load_dict({"type": "diffuse", "reflectance": {
                "type": "rgb", "value": [props["colour_r"], props["colour_g"], props["colour_b"]]}})  # fmt: skip

        def eval(self, ctx, si, wo, active=True):
            wi_np = np.stack([np.asarray(c.numpy(), np.float64) for c in (si.wi.x, si.wi.y, si.wi.z)], -1)
            if wi_np.shape[0] == 0:
                return mi.Spectrum(0.0)
            wo_np = np.stack([np.asarray(c.numpy(), np.float64) for c in (wo.x, wo.y, wo.z)], -1)
            if mi.is_spectral:
                lam = np.stack([np.asarray(si.wavelengths[k].numpy(), np.float64) for k in range(len(si.wavelengths))], -1)
            else:  # RGB variants: the film at representative wavelengths of R, G, B
                lam = np.broadcast_to(np.array([610.0, 550.0, 465.0]), (wi_np.shape[0], 3))
            # The base's reflectance spectrum: Mitsuba's diffuse eval is albedo/pi cos.
            unit = mi.Vector3f(0.0, 0.0, 1.0)
            base = self.base.eval(ctx, si, unit, active)
            base_np = np.stack([np.asarray(base[k].numpy(), np.float64) for k in range(lam.shape[1])], -1) * np.pi
            value = thin_film_f_cos(wi_np, wo_np, lam, self.film, self.alpha, base_np)
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

    mi.register_bsdf(THIN_FILM_REFERENCE, lambda props: ThinFilm(props))
    _registered.add(variant)
