"""The iridescent model's physical reference in NumPy: a thin-film microfacet BSDF.

A GGX microfacet BSDF (height-correlated Smith visibility, the renderer's lobe:
:mod:`atlasgen.optics.specular`) whose Fresnel term is the film stack's exact Airy reflectance
per wavelength (Belcour & Barla, "A Practical Extension to Microfacet Theory for the
Modeling of Varying Iridescence", SIGGRAPH 2017, eq. 2, without their Fourier-space
approximation), over a Lambertian base weighted by the transmission (1 - R(N.L)) (1 - R(N.V)).
Mitsuba evaluates it per wavelength in ``llvm_ad_spectral`` through the ``atlasgen_thinfilm``
plugin (:mod:`atlasgen.models.mitsuba_bsdfs`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from atlasgen.models.iridescent import film_reflectance
from atlasgen.optics.interpolation import interpolate_2d
from atlasgen.optics.microfacet import ggx_distribution, smith_visibility_correlated_ggx

__all__ = ["film_table", "thin_film_f_cos"]


@lru_cache(maxsize=16)
def film_table(thickness: float, film_ior: float, base_ior: float, base_k: float):
    """Film reflectance R(cos, lambda) on a grid: cosines 0..1 (1025), wavelengths 360..830 nm (1 nm)."""
    cos = np.linspace(0.0, 1.0, 1025)
    lam = np.arange(360.0, 831.0, 1.0)
    table = film_reflectance(cos, lam, thickness, film_ior, base_ior, base_k)
    table.setflags(write=False)
    return cos, lam, table


def _lookup(table_set, cos, lam):
    """Bilinear R at (cos, lambda), elementwise: the table's cosine axis is filtered first."""
    grid_c, grid_l, table = table_set
    return interpolate_2d(table.T, cos * (len(grid_c) - 1), (lam - grid_l[0]) / (grid_l[1] - grid_l[0]))


def thin_film_f_cos(wi, wo, lam, film, alpha, base_rgb_spectrum):
    """f cos(theta_o) of the thin-film microfacet BSDF, per lane and wavelength.

    f = D(h) V(wi, wo) R(wi.h, lambda) + base(lambda) (1 - R(cos_o)) (1 - R(cos_i)) / pi, D GGX
    and V = G2 / (4 cos_i cos_o) height-correlated Smith (Cook & Torrance 1982; Walter et al.
    2007; Heitz 2014; Belcour & Barla 2017).
    ``wi``, ``wo``: (N, 3) local; ``lam``: (N, S) nm; ``base_rgb_spectrum``: (N, S).
    """
    table = film_table(film["thickness"], film["film_ior"], film["base_ior"], film["base_k"])
    ci, co = wi[:, 2], wo[:, 2]
    valid = (ci > 0) & (co > 0)
    h = wi + wo
    h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
    cos_d = np.clip((wi * h).sum(1), 0.0, 1.0)
    d = ggx_distribution(h[:, 2], alpha)
    # V stays finite at a grazing cosine (alpha > 0); lanes with both cosines 0 are masked below.
    with np.errstate(divide="ignore", invalid="ignore"):
        vis = smith_visibility_correlated_ggx(ci, co, alpha)
    spec = np.nan_to_num(d * vis * np.maximum(co, 0.0))[:, None] * _lookup(table, cos_d[:, None], lam)
    r_o = _lookup(table, co[:, None], lam)
    r_i = _lookup(table, ci[:, None], lam)
    diffuse = base_rgb_spectrum * (1.0 - r_o) * (1.0 - r_i) / np.pi * np.maximum(co, 0.0)[:, None]
    return np.where(valid[:, None], spec + diffuse, 0.0)
