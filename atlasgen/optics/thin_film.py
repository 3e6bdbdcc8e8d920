"""The thin-film microfacet BSDF in NumPy: the iridescent model's physical reference (with
:data:`PHYSICAL_FILM`) and the separable model's ``source = "thin_film"``.

A GGX microfacet BSDF (height-correlated Smith visibility, the renderer's lobe:
:mod:`atlasgen.optics.specular`) whose Fresnel term is the film stack's exact Airy reflectance
per wavelength at the half-vector (Belcour & Barla, "A Practical Extension to Microfacet Theory
for the Modeling of Varying Iridescence", SIGGRAPH 2017, eq. 2, without their Fourier-space
approximation), over a Lambertian base weighted by what the film passes: the lobe's own
albedo (``energy = "conserving"``: reciprocal and energy-conserving, the physical film), or
the film's R (the iridescent model's ``coupled``). It can also carry the iridescent model's
stylisation (film strength and split) and a back-light as diffuse transmission through the film.
Mitsuba evaluates it per wavelength in ``llvm_ad_spectral`` through the ``atlasgen_thinfilm``
plugin (:mod:`atlasgen.models.mitsuba_bsdfs`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from atlasgen.optics.film import film_reflectance, spectral_grid, spectral_samples
from atlasgen.optics.interpolation import interpolate_1d, interpolate_2d, linear_stencil
from atlasgen.optics.microfacet import ggx_distribution, smith_visibility_correlated_ggx
from atlasgen.optics.translucency import transmitted_albedo

__all__ = ["film_table", "film_average", "lobe_albedo_kernel", "film_lobe_albedo", "thin_film_terms", "thin_film_f_cos",
           "thin_film_rgb_f_cos", "FILM_DEFAULTS", "PHYSICAL_FILM", "ENERGY_MODES", "FIT_CHUNK"]  # fmt: skip

#: The iridescent model's film parameters beyond the stack itself, at values that make the
#: BSDF the plain thin-film microfacet (full strength, all of it in the lobe, no back-light).
FILM_DEFAULTS = {"film_strength": 1.0, "film_split": 0.0, "energy": "none", "backlight": 0.0,
                 "backlight_distortion": 0.2, "backlight_power": 4.0}  # fmt: skip
#: The physical thin film (:func:`thin_film_f_cos` with these): the Airy film on the GGX lobe,
#: nothing rescaled or split, over a base coupled to the lobe's own albedo (``energy = "conserving"``).
PHYSICAL_FILM = {"film_strength": 1.0, "film_split": 0.0, "energy": "conserving"}
#: How the base under the film is weighted: ``none`` (1), ``coupled`` (the iridescent model's
#: (1 - R(c_o)) (1 - R(c_i)) / (1 - R_avg)) or ``conserving`` (the same with the lobe's albedo E for R).
ENERGY_MODES = ("coupled", "none", "conserving")
#: Cosines of the film's tables (:func:`film_table`, :func:`film_lobe_albedo`).
_COSINES = 1025
#: Gauss-Legendre nodes in the GGX sample coordinate u, and azimuths over [0, pi), of :func:`lobe_albedo_kernel`.
_ALBEDO_NODES = (64, 32)
#: (l, v) pairs per pass of :func:`thin_film_rgb_f_cos`: bounds its (pairs x wavelengths) arrays.
FIT_CHUNK = 8192


@lru_cache(maxsize=16)
def film_table(thickness: float, film_ior: float, base_ior: float, base_k: float):
    """Film reflectance R(cos, lambda) on a grid: cosines 0..1 (1025), wavelengths 360..830 nm (1 nm)."""
    cos = np.linspace(0.0, 1.0, _COSINES)
    lam = np.arange(360.0, 831.0, 1.0)
    table = film_reflectance(cos, lam, thickness, film_ior, base_ior, base_k)
    table.setflags(write=False)
    return cos, lam, table


@lru_cache(maxsize=16)
def film_average(thickness: float, film_ior: float, base_ior: float, base_k: float):
    """(wavelengths, R_avg): R_avg(lambda) = 2 int_0^1 R(c, lambda) c dc, by the trapezoid rule on the table."""
    cos, lam, table = film_table(thickness, film_ior, base_ior, base_k)
    average = 2.0 * np.trapezoid(table * cos[:, None], cos, axis=0)
    average.setflags(write=False)
    return lam, average


def _linear_average_weights(size: int) -> np.ndarray:
    """w with w @ E = 2 int_0^1 E(c) c dc exactly for E linear between ``size`` uniform cosines."""
    c = np.linspace(0.0, 1.0, size)
    h = c[1] - c[0]
    w = np.zeros(size)
    w[:-1] += h / 6.0 * (2.0 * c[:-1] + c[1:])
    w[1:] += h / 6.0 * (c[:-1] + 2.0 * c[1:])
    return 2.0 * w


@lru_cache(maxsize=8)
def lobe_albedo_kernel(alpha: float, size: int = _COSINES):
    """K ``(size, size)`` with E(mu_i) = sum_j K[i, j] F(c_j): the directional albedo of the GGX lobe
    (height-correlated Smith) whose Fresnel term F(w_i.h) is linear between ``size`` uniform cosines c_j,
    at each view cosine mu_i of the same grid.

        E(mu) = int D(h) V(mu, c_o) F(w_i.h) c_o dw_o = int [D cos theta_h] 4 V c_o (w_i.h) / cos theta_h F(w_i.h) dw_h,

    (dw_o = 4 (w_o.h) dw_h, Walter et al. 2007 eq. 14), with h drawn from D cos theta_h:
    tan^2 theta_h = alpha^2 u / (1 - u), u = 1 - t^2 with t on Gauss-Legendre nodes, the azimuth uniform
    (the integrand is even in it). F depends on h only through w_i.h, so the kernel holds the
    lobe's geometry once for every film and wavelength. With F = 1 the row sum is the lobe's
    own albedo (< 1: single scattering loses what the masking hides).
    """
    alpha = float(alpha)
    n_u, n_phi = _ALBEDO_NODES
    x, wx = np.polynomial.legendre.leggauss(n_u)
    t, wt = 0.5 * (x + 1.0), 0.5 * wx
    # u = 1 - t^2: at a grazing view the integrand grows as sqrt(u / (1 - u)), which this makes smooth.
    wu = 2.0 * t * wt
    phi = (np.arange(n_phi) + 0.5) * np.pi / n_phi
    tan2 = alpha * alpha * (1.0 - t * t) / (t * t)
    cos_h = 1.0 / np.sqrt(1.0 + tan2)
    sin_h = np.sqrt(tan2) * cos_h
    h = np.stack([sin_h[:, None] * np.cos(phi), sin_h[:, None] * np.sin(phi), np.broadcast_to(cos_h[:, None], (n_u, n_phi))], -1)
    h = h.reshape(-1, 3)
    weight = np.repeat(wu, n_phi) / n_phi
    mu = np.linspace(0.0, 1.0, size)
    wi = np.stack([np.sqrt(1.0 - mu * mu), np.zeros(size), mu], -1)
    kernel = np.zeros((size, size))
    for start in range(0, size, 64):  # rows in blocks: (64, nodes) arrays
        block = wi[start : start + 64]
        d = np.clip(block @ h.T, 0.0, 1.0)  # w_i.h
        co = 2.0 * d * h[:, 2] - block[:, 2:3]  # w_o.z, w_o = 2 (w_i.h) h - w_i
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            vis = np.nan_to_num(smith_visibility_correlated_ggx(block[:, 2:3], co, alpha))
            g = np.where((co > 0.0) & (d > 0.0), 4.0 * vis * co * d / h[:, 2], 0.0) * weight
        i0, i1, f = linear_stencil(size, d * (size - 1))
        rows = np.arange(len(block))[:, None] + start
        flat = np.concatenate([(rows * size + i0).ravel(), (rows * size + i1).ravel()])
        kernel.ravel()[:] += np.bincount(flat, np.concatenate([(g * (1.0 - f)).ravel(), (g * f).ravel()]), size * size)
    kernel.setflags(write=False)
    return kernel


@lru_cache(maxsize=16)
def film_lobe_albedo(thickness: float, film_ior: float, base_ior: float, base_k: float, alpha: float):
    """(cosines, wavelengths, E, E_avg) of the film's GGX lobe: E(mu, lambda) its directional albedo
    (:func:`lobe_albedo_kernel` applied to :func:`film_table`) on the table's grid, and
    E_avg(lambda) = 2 int_0^1 E(mu) mu dmu, exact for E linear between the cosines."""
    cos, lam, table = film_table(thickness, film_ior, base_ior, base_k)
    albedo = lobe_albedo_kernel(float(alpha), len(cos)) @ table
    average = _linear_average_weights(len(cos)) @ albedo
    for a in (albedo, average):
        a.setflags(write=False)
    return cos, lam, albedo, average


def _lookup(table_set, cos, lam):
    """Bilinear R at (cos, lambda), elementwise: the table's cosine axis is filtered first."""
    grid_c, grid_l, table = table_set
    return interpolate_2d(table.T, cos * (len(grid_c) - 1), (lam - grid_l[0]) / (grid_l[1] - grid_l[0]))


@lru_cache(maxsize=16)
def _table_on_grid(stack: tuple, lam: tuple):
    """:func:`film_table` of ``stack`` filtered along wavelength at ``lam``, ``(cosines, S)``.

    A bilinear lookup at a wavelength grid shared by every lane is then linear along the
    cosine alone: bilinear filtering is separable, so this equals :func:`_lookup` up to
    rounding, and gathers one row per lane instead of four texels per lane and wavelength.
    """
    grid_c, grid_l, table = film_table(*stack)
    on_grid = interpolate_1d(table.T, (np.asarray(lam) - grid_l[0]) / (grid_l[1] - grid_l[0])).T
    on_grid = np.ascontiguousarray(on_grid)
    on_grid.setflags(write=False)
    return on_grid


@lru_cache(maxsize=16)
def _albedo_on_grid(stack: tuple, alpha: float, lam: tuple):
    """:func:`film_lobe_albedo`'s E filtered along wavelength at ``lam``, ``(cosines, S)`` (as :func:`_table_on_grid`)."""
    _, grid_l, albedo, _ = film_lobe_albedo(*stack, alpha)
    on_grid = np.ascontiguousarray(interpolate_1d(albedo.T, (np.asarray(lam) - grid_l[0]) / (grid_l[1] - grid_l[0])).T)
    on_grid.setflags(write=False)
    return on_grid


def _lobe_geometry(wi, wo, alpha):
    """``(c_i, c_o, valid, w_i.h, D V max(c_o, 0))`` of (N, 3) local pairs: the film's lobe without its Fresnel."""
    ci, co = wi[:, 2], wo[:, 2]
    h = wi + wo
    h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
    cos_d = np.clip((wi * h).sum(1), 0.0, 1.0)
    # V stays finite at a grazing cosine (alpha > 0); lanes with both cosines 0 are masked by valid.
    with np.errstate(divide="ignore", invalid="ignore"):
        vis = np.nan_to_num(smith_visibility_correlated_ggx(ci, co, alpha))
    lobe = ggx_distribution(h[:, 2], alpha) * vis * np.maximum(co, 0.0)
    return ci, co, (ci > 0) & (co > 0), cos_d, lobe


def thin_film_terms(wi, wo, lam, film, alpha):
    """The thin-film BSDF's f cos(theta_o) split by what it multiplies, per lane and wavelength.

    Returns ``(own, base_weight, back_weight)``, each ``(N, S)``, with

        f cos = own + base(lambda) * base_weight + colour_B(lambda) * back_weight

    ``own`` the film's lobe and rough part, ``base_weight`` the base's transmission weight
    times cos(theta_o) / pi and ``back_weight`` the back-light's B T_B (1 - R(c_i)) |c_o| / pi
    (0 where ``backlight`` is 0): the terms of :func:`thin_film_f_cos`.
    f cos is linear in the two RGB-upsampled spectra, so one evaluation of the film serves
    both the per-wavelength plugin (:func:`thin_film_f_cos`) and the RGB integral of a fit
    (:func:`thin_film_rgb_f_cos`). ``lam`` is ``(N, S)`` nm, or ``(S,)`` for one grid shared by
    every lane (the RGB integral's), which is looked up faster.
    """
    film = {**FILM_DEFAULTS, **film}
    stack = (film["thickness"], film["film_ior"], film["base_ior"], film["base_k"])
    table = film_table(*stack)
    ci, co, valid, cos_d, lobe = _lobe_geometry(wi, wo, alpha)
    strength, split = float(film["film_strength"]), float(film["film_split"])
    if np.ndim(lam) == 1:  # one grid for every lane
        on_grid = _table_on_grid(stack, tuple(float(x) for x in lam))

        def look(c):
            return interpolate_1d(on_grid, c * (len(on_grid) - 1))
    else:

        def look(c):
            return _lookup(table, c[:, None], lam)

    r_i = look(np.clip(ci, 0.0, 1.0))
    r_o = look(np.clip(co, 0.0, 1.0))
    lit = np.maximum(co, 0.0)[:, None]
    spec = (strength * (1.0 - split)) * lobe[:, None] * look(cos_d)
    rough = (strength * split / np.pi) * r_i * lit
    conserving = film["energy"] == "conserving"
    if conserving:  # the base sees what the lobe does not reflect: its albedo E in place of R
        grid_c, grid_l, albedo, average = film_lobe_albedo(*stack, float(alpha))
        if np.ndim(lam) == 1:
            on_grid = _albedo_on_grid(stack, float(alpha), tuple(float(x) for x in lam))

            def look_albedo(c):
                return interpolate_1d(on_grid, c * (len(on_grid) - 1))
        else:

            def look_albedo(c):
                return _lookup((grid_c, grid_l, albedo), c[:, None], lam)

        e_i = look_albedo(np.clip(ci, 0.0, 1.0))
        g = 1.0 / np.maximum(1.0 - np.interp(lam, grid_l, average), 1e-6)
        weight = (1.0 - look_albedo(np.clip(co, 0.0, 1.0))) * (1.0 - e_i) * g
    else:
        weight = (1.0 - r_o) * (1.0 - r_i)
        if film["energy"] == "coupled":
            grid, average = film_average(*stack)
            weight = weight / np.maximum(1.0 - np.interp(lam, grid, average), 1e-6)
    own = np.where(valid[:, None], spec + rough, 0.0)
    base_weight = np.where(valid[:, None], weight / np.pi * lit, 0.0)
    if film["backlight"] <= 0.0:
        return own, base_weight, np.zeros_like(own)
    gain = float(film["backlight"]) * transmitted_albedo(film["backlight_distortion"], film["backlight_power"])
    if conserving:  # diffuse transmission weighted as the base's reflection is: reciprocal, and within the base's energy
        through = (1.0 - look_albedo(np.clip(-co, 0.0, 1.0))) * (1.0 - e_i) * g
    else:
        through = 1.0 - r_i
    back = (gain / np.pi) * np.where(co < 0.0, -co, 0.0)[:, None] * through
    return own, base_weight, np.where((ci > 0)[:, None], back, 0.0)


def thin_film_f_cos(wi, wo, lam, film, alpha, base_rgb_spectrum, backlight_spectrum=None):
    """f cos(theta_o) of the thin-film BSDF, per lane and wavelength.

    With R the film's Airy reflectance, k = ``film_strength``, s = ``film_split`` and
    c_i = cos(theta_i) the view side (the model's N.V), c_o the light side (N.L):

        f = k (1 - s) D(h) V(wi, wo) R(wi.h)                      the lobe: GGX D, height-correlated Smith V = G2 / (4 c_i c_o)
                                                                   (Cook & Torrance 1982; Walter et al. 2007; Heitz 2014)
          + k s R(c_i) / pi                                        the film's rough part
          + base (1 - R(c_o)) (1 - R(c_i)) / (1 - R_avg) / pi      energy = "coupled" (else base / pi)
          + B T_B colour_B (1 - R(c_i)) / pi                        light from behind (c_o < 0)

    per wavelength, R_avg = 2 int R(c) c dc. With ``energy = "conserving"`` (:data:`PHYSICAL_FILM`, the
    iridescent model's physical reference) R in the base's weight is the lobe's directional albedo
    E(c, lambda) (:func:`film_lobe_albedo`), as in Kelemen & Szirmay-Kalos's coupled matte
    (Eurographics 2001 short paper), and the back-light's weight is the same,
    B T_B colour_B (1 - E(c_i)) (1 - E(|c_o|)) / (1 - E_avg) / pi: both are symmetric in (c_i, c_o),
    the lobe is (D, V and R(w_i.h) = R(w_o.h)), so f is reciprocal, and the albedo at a view c_i is
    E(c_i) + (1 - E(c_i)) (base + B T_B colour_B) <= 1 wherever the base's reflectance plus
    transmittance is. The film's reflection is split between a
    lobe of the renderer's width and a rough (Lambertian-like) part as the model splits it
    between A and RGB: a surface whose micro-roughness is bimodal. The back-light is the
    physical counterpart of the model's Barré-Brisebois & Bouchard term t = saturate(V.-(L +
    delta N))^p, as for the ``backlit`` model's thin sheet: diffuse transmission with the
    energy t passes for light from behind along -N, T_B = 2 (1 - delta)^p / (p + 2)
    (:func:`atlasgen.optics.translucency.transmitted_albedo`), seen through the film. t itself
    is a real-time stand-in for forward scattering, not a physical law: evaluated at the true
    azimuth it peaks when looking into the light, which no (N.L, N.V) table can hold.
    ``wi``, ``wo``: (N, 3)
    local; ``lam``: (N, S) nm; ``base_rgb_spectrum``, ``backlight_spectrum``: (N, S);
    ``film``: the stack (``thickness``, ``film_ior``, ``base_ior``, ``base_k``) and any of
    :data:`FILM_DEFAULTS`. The terms come from :func:`thin_film_terms`.
    """
    own, base_weight, back_weight = thin_film_terms(wi, wo, lam, film, alpha)
    value = own + base_rgb_spectrum * base_weight
    if backlight_spectrum is None:
        return value
    return value + backlight_spectrum * back_weight


def thin_film_rgb_f_cos(wi, wo, film, alpha, colour, backlight_colour=None, chunk: int = FIT_CHUNK):
    """Linear sRGB f cos(theta_o) of the thin-film BSDF lit by white light, ``(N, 3)``.

    The per-wavelength f cos of :func:`thin_film_f_cos` integrated over 360-830 nm as
    Mitsuba's ``llvm_ad_spectral`` render of ``atlasgen_thinfilm`` integrates it under a white
    RGB light, which Mitsuba upsamples to the D65 spectrum: CIE 1931 colour matching functions
    (Wyman et al.'s fit, :func:`atlasgen.optics.film.cie_xyz_cmfs`) times D65 to XYZ to linear
    sRGB, each channel normalised so a spectrally flat response of 1 gives (1, 1, 1)
    (:func:`atlasgen.optics.film.spectrum_to_rgb` with ``illuminant = "D65"``), on the
    iridescent model's wavenumber grid (:func:`~atlasgen.optics.film.spectral_samples` resolves
    the film's fringes).

    Approximations against that render: the CMF fit (a few 1e-3 of f cos against CIE's
    tables), lights of any other colour (taken as white: their upsampled spectra are not flat),
    and the RGB ``colour`` and ``backlight_colour``, which Mitsuba upsamples to smooth spectra
    while here f cos, linear in each, takes them per channel: RGB(base(lambda) w(lambda)) ~
    colour * RGB(w). All are exact for spectrally flat colours; the film's own interference
    colours are integrated, not approximated.
    """
    film = {**FILM_DEFAULTS, **film}
    samples = spectral_samples(film["thickness"], film["film_ior"])
    grid, _ = spectral_grid(samples)
    stack = (film["thickness"], film["film_ior"], film["base_ior"], film["base_k"])
    conserving = film["energy"] == "conserving"
    # The coupled base reads the film's R, the conserving one the lobe's albedo E (which depends on alpha).
    tables = _rgb_tables(stack, tuple(float(x) for x in grid), samples, film["energy"], float(alpha) if conserving else None)
    colour = np.asarray(colour, dtype=np.float64)
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    strength, split = float(film["film_strength"]), float(film["film_split"])
    gain = 0.0
    if backlight_colour is not None and film["backlight"] > 0.0:
        gain = float(film["backlight"]) * transmitted_albedo(film["backlight_distortion"], film["backlight_power"])
    out = np.empty((len(wi), 3))
    for start in range(0, len(wi), chunk):
        part = slice(start, start + chunk)
        ci, co, valid, cos_d, lobe = _lobe_geometry(wi[part], wo[part], alpha)
        ci, co_lit = np.clip(ci, 0.0, 1.0), np.clip(co, 0.0, 1.0)
        lit = co_lit[:, None]
        own = (strength * (1.0 - split)) * lobe[:, None] * tables.look(tables.reflect, cos_d)
        own += (strength * split / np.pi) * tables.look(tables.reflect, ci) * lit
        base = tables.through(co_lit, ci) / np.pi * lit
        out[part] = np.where(valid[:, None], own + colour * base, 0.0)
        if gain > 0.0:
            if conserving:
                through = tables.through(np.clip(-co, 0.0, 1.0), ci)
            else:
                through = tables.white - tables.look(tables.reflect, ci)
            back = (gain / np.pi) * np.where(co < 0.0, -co, 0.0)[:, None] * through
            out[part] += np.asarray(backlight_colour, dtype=np.float64) * np.where((wi[part, 2] > 0)[:, None], back, 0.0)
    return out


class _RgbTables:
    """The film's reflectance already integrated to linear sRGB, for :func:`thin_film_rgb_f_cos`.

    With T[c, s] the reflectance on the cosine grid at the fit's wavelengths (:func:`_table_on_grid`),
    w[s] the D65 weights of :func:`~atlasgen.optics.film.spectrum_to_rgb` and g[s] the coupled
    energy's 1 / (1 - R_avg) (1 without it), f cos is a sum of terms linear in one lookup of T,
    or bilinear in two (the base's (1 - R(c_o)) (1 - R(c_i))). Linear filtering commutes with
    the sum over s, so the RGB integral of each term is a lookup of its table already summed:

        sum_s R(c)_s w_s                = lerp over c of  T w                       (reflect)
        sum_s R(c)_s g_s w_s            = lerp over c of  T (g w)                   (reflect_g)
        sum_s R(a)_s R(b)_s g_s w_s     = bilinear in (a, b) of  T diag(g w) T^T    (pair_g)

    exact up to rounding, and one gather of 3 numbers per lane instead of a spectrum of S.
    """

    def __init__(self, on_grid: np.ndarray, weights: np.ndarray, g: np.ndarray, base_grid: np.ndarray | None = None):
        w = np.ascontiguousarray(weights[:3].T)  # (S, 3)
        gw = g[:, None] * w
        base_grid = on_grid if base_grid is None else base_grid  # what the base's weight subtracts: R, or the lobe's E
        self.size = len(on_grid)
        self.reflect = on_grid @ w
        self.reflect_g = base_grid @ gw
        self.white, self.white_g = w.sum(axis=0), gw.sum(axis=0)
        self.pair_g = np.stack([(base_grid * gw[:, k]) @ base_grid.T for k in range(3)], axis=-1)

    def look(self, table: np.ndarray, c) -> np.ndarray:
        return interpolate_1d(table, c * (self.size - 1))

    def through(self, a, b) -> np.ndarray:
        """sum_s (1 - T(a)_s) (1 - T(b)_s) g_s w_s, T the base's table: the base's weight at cosines (a, b)."""
        return self.white_g - self.look(self.reflect_g, a) - self.look(self.reflect_g, b) + self.look_pair(a, b)

    def look_pair(self, a, b) -> np.ndarray:
        a0, a1, fa = linear_stencil(self.size, a * (self.size - 1))
        b0, b1, fb = linear_stencil(self.size, b * (self.size - 1))
        fa, fb = fa[:, None], fb[:, None]
        p = self.pair_g
        return (1.0 - fa) * ((1.0 - fb) * p[a0, b0] + fb * p[a0, b1]) + fa * ((1.0 - fb) * p[a1, b0] + fb * p[a1, b1])


@lru_cache(maxsize=4)
def _rgb_tables(stack: tuple, lam: tuple, samples: int, energy: str, alpha: float | None = None) -> _RgbTables:
    """:class:`_RgbTables` of a film ``stack`` on the wavelengths ``lam`` of ``spectral_grid(samples)``, its base
    weighted as ``energy`` says (:data:`ENERGY_MODES`; ``conserving`` needs the lobe's ``alpha``)."""
    _, weights = spectral_grid(samples, "D65")
    g = np.ones(len(lam))
    base_grid = None
    if energy == "coupled":
        grid, average = film_average(*stack)
        g = 1.0 / np.maximum(1.0 - np.interp(np.asarray(lam), grid, average), 1e-6)
    elif energy == "conserving":
        if alpha is None:
            raise ValueError("energy = \"conserving\" weights the base by the lobe's albedo: it needs the lobe's alpha")
        _, grid, _, average = film_lobe_albedo(*stack, float(alpha))
        g = 1.0 / np.maximum(1.0 - np.interp(np.asarray(lam), grid, average), 1e-6)
        base_grid = _albedo_on_grid(stack, float(alpha), lam)
    return _RgbTables(_table_on_grid(stack, lam), weights, g, base_grid)
