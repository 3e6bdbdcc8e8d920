"""Thin-film iridescence: an Airy summation with exact Fresnel per polarisation, integrated to sRGB
(the optics: :mod:`atlasgen.optics.film`).

Belcour & Barla, "A Practical Extension to Microfacet Theory for the Modeling of
Varying Iridescence", ACM TOG 36(4), 2017. The spectral integral is a quadrature over
wavelength, with a step fine enough for the film's fringes, not the paper's Fourier-space
approximation, so the film-free limit is exact.
"""

from __future__ import annotations

import json

import numpy as np

from atlasgen.errors import MaterialError
from atlasgen.io.fields import Param
from atlasgen.models.backlit import VIEW_MODES, translucency
from atlasgen.models.base import THIN_FILM_REFERENCE, Model, PhysicalFCos, Reference, SliceSet
from atlasgen.models.physical_fit import fit_to_reference
from atlasgen.optics.film import (
    MAX_PHASE_STEP,
    MIN_SAMPLES,
    VISIBLE_NM,
    XYZ_TO_LINEAR_SRGB,
    cie_xyz_cmfs,
    film_reflectance,
    film_reflectance_on_grid,
    spectral_grid,
    spectral_samples,
    spectrum_to_rgb,  # fmt: skip
)
from atlasgen.optics.fresnel import normal_reflectance
from atlasgen.optics.quadrature import cosine_rule
from atlasgen.optics.specular import specular_alpha, specular_fresnel_cosine
from atlasgen.optics.thin_film import PHYSICAL_FILM, thin_film_rgb_f_cos
from atlasgen.optics.translucency import transmitted_albedo

__all__ = [
    "Iridescent",
    "physical_film",
    "PHYSICAL_DESCRIPTION",
    "film_reflectance",
    "spectrum_to_rgb",
    "cie_xyz_cmfs",
    "film_reflectance_on_grid",
    "spectral_samples",
    "spectral_grid",
    "XYZ_TO_LINEAR_SRGB",
    "VISIBLE_NM",
    "MIN_SAMPLES",
    "MAX_PHASE_STEP",
]


_CHUNK = 256
_STACK_KEYS = ("thickness", "film_ior", "base_ior", "base_k")
_BACK_KEYS = ("backlight", "backlight_distortion", "backlight_power")
PHYSICAL_DESCRIPTION = ("physical thin film: Airy reflectance per wavelength at the half-vector on a GGX lobe, "
                        "base coupled to the lobe's albedo (reciprocal, energy-conserving; llvm_ad_spectral, "
                        "wavelengths sampled per sample)")  # fmt: skip


def physical_film(values: dict):
    """``(film, colour, backlight_colour)`` of the iridescent material ``values``'s physical thin film.

    The film (:func:`atlasgen.optics.thin_film.thin_film_f_cos`'s ``film``) is the material's stack
    (``thickness``, ``film_ior``, ``base_ior``, ``base_k``) with
    :data:`~atlasgen.optics.thin_film.PHYSICAL_FILM`: no strength, no split, the base coupled to
    the lobe's albedo. Where ``backlight`` > 0 it keeps the back-light's energy
    B T_B (:func:`atlasgen.optics.translucency.transmitted_albedo`) as diffuse transmission. The
    base passes at most what enters it: where colour + B T_B backlight_colour exceeds 1 in a
    channel, both are scaled down by that channel's sum, so the film's albedo stays <= 1.
    """
    film = {k: float(values[k]) for k in _STACK_KEYS}
    film.update(PHYSICAL_FILM)
    colour = np.asarray(values["colour"], dtype=np.float64)
    back = np.asarray(values["backlight_colour"], dtype=np.float64)
    if values["backlight"] <= 0.0:
        return film, colour, back
    film.update({k: float(values[k]) for k in _BACK_KEYS})
    gain = float(values["backlight"]) * transmitted_albedo(values["backlight_distortion"], values["backlight_power"])
    total = float(np.max(colour + gain * back))
    if total > 1.0:
        colour, back = colour / total, back / total
    return film, colour, back


class Iridescent(Model):
    """A diffuse base under a thin dielectric film; the film's hue in RGB, the rest of it in A.

    Let R(theta) be the film stack's spectral reflectance (:func:`film_reflectance`),
    R_rgb its linear sRGB (:func:`spectrum_to_rgb`, clipped at 0) and Y its luminance.
    With s = ``film_split`` and k = ``film_strength``,

        RGB = max(N.L, 0) [colour T + k s R_rgb(N.V)] + backlight B (1 - R_rgb(N.V)) t(N.L, N.V)
        A   = k (1 - s) Y(c)            (normalise = false)
        A   = k (1 - s) Y(c) / F0       (normalise = true; F0 = the bare base's normal reflectance)

    with c = :func:`atlasgen.optics.specular.specular_fresnel_cosine` (N.L, N.V), L.H where
    the renderer's GGX lobe peaks for this (N.L, N.V): A stands for the film's F(L.H) in
    the microfacet lobe, as in the ``fresnel`` model (whose docstring has the derivation).

    T = (1 - R_rgb(N.L)) (1 - R_rgb(N.V)) / (1 - R_avg), R_avg = 2 int_0^1 R_rgb(c) c dc,
    when ``energy = "coupled"`` (as in the ``fresnel`` model), else 1.

    The renderer scales its specular lobe by the scalar A only, so the film's hue cannot
    ride on A. The film's reflection is therefore split: a fraction s goes into RGB as
    its colour times the cosine (the rough limit of a coloured lobe; the renderer's
    albedo * RGB / pi then reflects R_rgb(N.V) in total), the rest into A as the white
    highlight's luminance, evaluated at c. The split keeps the film's energy counted once; k scales it.
    The optional back-lighting is the Barré-Brisebois & Bouchard term t (shared with the
    ``backlit`` model), seen through the film, hence (1 - R_rgb). At zero thickness (or
    film_ior = 1) R_rgb = F (1, 1, 1) and Y = F exactly, so with s = 0 and
    k = 1 the model equals ``fresnel`` (exact) with ior = base_ior.
    """

    type_name = "iridescent"
    reference = "Belcour & Barla, ACM TOG 36(4) 2017; Wyman, Sloan & Shirley, JCGT 2(2) 2013"
    params = (
        Param("colour", (0.0, 0.0, 0.0), "colour", doc="diffuse colour of the base under the film, linear"),
        Param("thickness", 500.0, lo=0.0, hi=2000.0, doc="film thickness in nm"),
        Param("film_ior", 1.33, lo=1.0, hi=3.0, doc="refractive index of the film"),
        Param("base_ior", 1.5, lo=0.05, hi=5.0, doc="refractive index of the base (real part)"),
        Param("base_k", 0.0, lo=0.0, hi=10.0, doc="extinction coefficient of the base; 0 = dielectric"),
        Param("film_strength", 1.0, lo=0.0, hi=64.0, doc="multiplier on the film's reflection"),
        Param("film_split", 0.5, lo=0.0, hi=1.0, doc="fraction of the film's reflection shown as colour in RGB; the rest is A"),
        Param("normalise", False, "bool", doc="A = k(1-s)Y (false) or k(1-s)Y/F0 (true)"),
        Param(
            "energy",
            "coupled",
            "choice",
            choices=("coupled", "none"),
            doc="diffuse weighted by (1-R(N.L))(1-R(N.V))/(1-R_avg), or not",
        ),
        Param("backlight", 0.0, lo=0.0, hi=16.0, doc="strength of light transmitted from behind; 0 = off"),
        Param("backlight_colour", (1.0, 1.0, 1.0), "colour", doc="colour of the transmitted light"),
        Param("backlight_distortion", 0.2, lo=0.0, hi=1.0, doc="delta of the transmission term"),
        Param("backlight_power", 4.0, lo=0.0, hi=64.0, lo_open=True, doc="p of the transmission term"),
        Param("backlight_view", "average", "choice", choices=VIEW_MODES, doc="azimuth average or coplanar view term"),
    )

    def check(self, values, path):
        f0 = float(normal_reflectance(values["base_ior"], values["base_k"]))
        if f0 < 1e-4:
            raise MaterialError(
                path,
                "base_ior",
                f"expected a base reflecting at least 1e-4 at normal incidence (ior away from 1 or k > 0), got F0 = {f0:.2g}",
            )

    @staticmethod
    def film_colour(values, cos_theta):
        """(R_rgb, Y) of the film stack at ``cos_theta`` (any shape), one spectrum per distinct value."""
        c = np.clip(np.asarray(cos_theta, dtype=np.float64), 0.0, 1.0)
        unique, inverse = np.unique(c.ravel(), return_inverse=True)
        samples = spectral_samples(values["thickness"], values["film_ior"])
        rgb = np.empty((len(unique), 3))
        lum = np.empty(len(unique))
        for start in range(0, len(unique), _CHUNK):
            spectra = film_reflectance_on_grid(
                unique[start : start + _CHUNK],
                samples,
                values["thickness"],
                values["film_ior"],
                values["base_ior"],
                values["base_k"],
            )
            rgb[start : start + _CHUNK], lum[start : start + _CHUNK] = spectrum_to_rgb(spectra, samples)
        rgb = np.maximum(rgb, 0.0)  # out-of-gamut film colours clip to the sRGB gamut's edge
        return rgb[inverse].reshape(c.shape + (3,)), lum[inverse].reshape(c.shape)

    def evaluate(self, values, n_dot_l, n_dot_v):
        # Kept at their own shapes until the end: the film colour depends on one cosine at a
        # time, so (1, W) and (H, 1) axes cost W + H spectra, not W * H.
        nl = np.clip(np.asarray(n_dot_l, dtype=np.float64), -1.0, 1.0)
        nv = np.clip(np.asarray(n_dot_v, dtype=np.float64), 0.0, 1.0)
        shape = np.broadcast_shapes(nl.shape, nv.shape)
        lit = np.maximum(nl, 0.0)
        coupled = values["energy"] == "coupled"
        # One spectral pass for every cosine needed: N.V, the lobe's L.H (for A), and for the
        # coupled diffuse N.L and the nodes of R_avg = 2 int_0^1 R_rgb(c) c dc (the rule the
        # fresnel model uses).
        nodes, node_weights = cosine_rule()
        peak = specular_fresnel_cosine(lit, nv)
        cosines = [peak.ravel(), nv.ravel(), lit.ravel(), nodes] if coupled else [peak.ravel(), nv.ravel()]
        rgb_all, lum_all = self.film_colour(values, np.concatenate(cosines))
        lum_peak = lum_all[: peak.size].reshape(peak.shape)
        rgb_all, lum_all = rgb_all[peak.size :], lum_all[peak.size :]
        rgb_v = rgb_all[: nv.size].reshape(nv.shape + (3,))
        colour = np.asarray(values["colour"], dtype=np.float64)
        transmit_v = np.maximum(1.0 - rgb_v, 0.0)
        if coupled:
            rgb_l = rgb_all[nv.size : nv.size + lit.size].reshape(lit.shape + (3,))
            rgb_avg = node_weights @ rgb_all[nv.size + lit.size :]
            # R_avg < 1 for any real stack; the floor only keeps a pathological gamut clip finite.
            colour = colour * np.maximum(1.0 - rgb_l, 0.0) * transmit_v / np.maximum(1.0 - rgb_avg, 1e-6)
        strength, split = values["film_strength"], values["film_split"]
        out = np.empty(shape + (4,))
        out[..., :3] = lit[..., None] * (colour + (strength * split) * rgb_v)
        if values["backlight"] > 0.0:
            t = translucency(nl, nv, values["backlight_distortion"], values["backlight_power"], values["backlight_view"])
            out[..., :3] += (values["backlight"] * t)[..., None] * np.asarray(values["backlight_colour"]) * transmit_v
        alpha = strength * (1.0 - split) * lum_peak
        if values["normalise"]:
            alpha = alpha / float(normal_reflectance(values["base_ior"], values["base_k"]))
        out[..., 3] = alpha
        return out

    physical_omissions = {
        "normalise": "an encoding for engines whose specular term already carries F0 (A = k(1-s)Y/F0); "
        "the physical highlight is the film's own reflectance, and the report measures the 1/F0 gap",
        "film_strength": "stylisation: k > 1 reflects more than the film does (about 1.9x the incident energy at "
        "grazing for k = 3); the physical film is the Airy reflectance itself, and the manifest's "
        "fit.stylisation_psnr_db measures the model's deviation from it",
        "film_split": "stylisation: the share of the film shown as a rough colour R(N.V) in RGB, which depends on the "
        "view only and so is not reciprocal; the physical film reflects on its lobe alone, at the half-vector",
        "energy": "how the model weights its base; the physical film always couples the base to the lobe's own "
        "albedo E (energy-conserving and reciprocal), neither the model's (1-R)(1-R)/(1-R_avg) nor 1",
        "backlight_view": "how the model reduces the back-light's azimuth to (N.L, N.V); the film transmits "
        "diffusely, with no azimuth, the energy of the model's term (transmitted_albedo), "
        "as the backlit model's thin sheet does, the same in both modes",
    }

    def physical_reference(self, values, albedo=(1.0, 1.0, 1.0), gloss=0.5):
        """``atlasgen_thinfilm`` in ``llvm_ad_spectral``: the physical thin film of :func:`physical_film`
        (the film stack's Airy reflectance per wavelength at the half-vector on the renderer's GGX lobe,
        its roughness, over the base colour coupled to the lobe's albedo, and the back-light as
        reciprocal diffuse transmission of the energy of the model's term through the film), with the
        object's ``albedo`` on the base (:func:`atlasgen.optics.thin_film.thin_film_f_cos`).

        Stochastic: Mitsuba samples the wavelengths per sample, so the render converges
        with ``--physical-spp``.
        """
        film, colour, back = physical_film(values)
        colour = colour * np.asarray(albedo, dtype=np.float64)
        back = back * np.asarray(albedo, dtype=np.float64)
        return Reference({
            "type": THIN_FILM_REFERENCE,
            "film": json.dumps(film, sort_keys=True),
            "alpha": float(specular_alpha(gloss)),
            "colour_r": float(colour[0]), "colour_g": float(colour[1]), "colour_b": float(colour[2]),
            "backlight_r": float(back[0]), "backlight_g": float(back[1]), "backlight_b": float(back[2]),
        }, PHYSICAL_DESCRIPTION, variant="llvm_ad_spectral", stochastic=True)  # fmt: skip

    def physical_fit_problem(self, values):
        """``normalise = true`` encodes A for engines whose specular term carries F0; a fit to the
        physical reference is made for the renderer's equation, which does not."""
        if values["normalise"]:
            return "normalise = true divides A by F0 for another engine's lobe; a physical fit is for atlasgen's renderer"
        return None

    def physical_f_cos(self, values, gloss) -> PhysicalFCos:
        """:meth:`physical_reference` as NumPy: :func:`atlasgen.optics.thin_film.thin_film_rgb_f_cos`
        (its w_i the view, w_o the light), the plugin's per-wavelength f cos integrated to linear
        sRGB for white light, with that function's approximations against Mitsuba's spectral
        render. It transmits where ``backlight`` > 0. It is the separable model's
        ``source = "thin_film"`` with this film (``energy = "conserving"``, its back-light included),
        GGX alpha and base colour."""
        ref = self.physical_reference(values, gloss=gloss)
        bsdf = ref.bsdf
        film = json.loads(bsdf["film"])
        colour = [bsdf[f"colour_{c}"] for c in "rgb"]
        back = [bsdf[f"backlight_{c}"] for c in "rgb"]

        def f_cos(l, v):
            return thin_film_rgb_f_cos(v, l, film, bsdf["alpha"], colour, back)

        stack = {k: film[k] for k in _STACK_KEYS + tuple(PHYSICAL_FILM) + _BACK_KEYS if k in film}
        if values["backlight"] > 0.0:
            stack["backlight_colour"] = back
        source = {"source": "thin_film", "film": stack, "alpha": bsdf["alpha"], "diffuse": colour}
        return PhysicalFCos(f_cos, ref.description, alpha=bsdf["alpha"], transmits=values["backlight"] > 0.0, source=source)

    def fit_physical(self, values, gloss) -> SliceSet:
        """The slice fitted to :meth:`physical_reference` at the renderer gloss ``gloss``
        (:func:`atlasgen.models.physical_fit.fit_to_reference`), from
        :func:`atlasgen.optics.thin_film.thin_film_rgb_f_cos`: the per-wavelength f cos the
        ``atlasgen_thinfilm`` plugin evaluates (:func:`~atlasgen.optics.thin_film.thin_film_terms`),
        integrated to linear sRGB for white light. No Mitsuba is needed; the approximations
        against Mitsuba's spectral render (white light, RGB colours taken per channel) are
        that function's.

        A is one scalar per texel: the lobe's colour (the film's R(l.h), which varies over the
        azimuth) goes into the slice only as its best grey fit, and RGB takes the rest.
        """
        physical = self.physical_f_cos(values, gloss)
        samples = spectral_samples(values["thickness"], values["film_ior"])
        return fit_to_reference(self, values, physical.f_cos, physical.description, gloss, deviation=True,
                                transmits=physical.transmits, wavelengths=samples)  # fmt: skip
