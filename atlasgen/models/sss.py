"""Pre-integrated subsurface scattering (Penner 2011) with a sum-of-Gaussians diffusion profile."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from atlasgen.errors import MaterialError
from atlasgen.io.fields import Param
from atlasgen.models.base import Model, Reference, SliceSet
from atlasgen.models.sss_fit import fitted_sss_slice
from atlasgen.optics.quadrature import gauss_legendre_rule, integrate_gauss_legendre

__all__ = ["Subsurface", "preintegrate_ring", "skin_medium", "chandrasekhar_h", "diffuse_albedo",
           "single_scattering_albedo", "SKIN_VARIANCES", "SKIN_WEIGHTS", "SKIN1_SIGMA_S_REDUCED",
           "SKIN1_SIGMA_A", "SKIN1_IOR", "FIT_REFERENCE"]  # fmt: skip

#: d'Eon & Luebke, "Advanced Techniques for Realistic Real-Time Skin Rendering",
#: GPU Gems 3 ch. 14 (2007), the six-Gaussian skin fit: variances in mm^2 ...
SKIN_VARIANCES = (0.0064, 0.0484, 0.187, 0.567, 1.99, 7.41)
#: ... and the RGB weight of each Gaussian (each channel sums to 1).
SKIN_WEIGHTS = (
    (0.233, 0.455, 0.649),
    (0.100, 0.336, 0.344),
    (0.118, 0.198, 0.0),
    (0.113, 0.007, 0.007),
    (0.358, 0.004, 0.0),
    (0.078, 0.0, 0.0),
)

#: Jensen, Marschner, Levoy & Hanrahan, "A Practical Model for Subsurface Light Transport",
#: SIGGRAPH 2001, table 2, Skin1 (per mm): the physical reference's medium.
SKIN1_SIGMA_S_REDUCED = (0.74, 0.88, 1.01)
SKIN1_SIGMA_A = (0.032, 0.17, 0.48)
SKIN1_IOR = 1.3
#: What the ``from = "physical"`` slice is fitted to (the manifest's ``fit.reference``): spheres only.
FIT_REFERENCE = "volpathmis through Jensen 2001 Skin1 inside the fitted spheres (fit_radii), index-matched boundary"
#: World radius of the validation scenes' sphere (unit sphere scaled by 0.5).
_SPHERE_RADIUS = 0.5

# Half-width of a Gaussian's kernel on the ring, in standard deviations 1/sqrt(kappa):
# since sin(x/2) >= x/pi on [0, pi], beyond it the kernel is below exp(-2 * 12^2 / pi^2),
# about 2e-13 of its peak.
_KERNEL_SIGMAS = 12.0
_CHUNK = 2048


def _ring_integrals(theta, kappa):
    """Numerator and denominator of Penner's ring integral for one Gaussian each.

    With R(d) a Gaussian of variance v and d = 2 r sin(x/2), R is proportional to
    K(x) = exp(-2 kappa sin^2(x/2)), kappa = r^2 / v: a von Mises kernel on the ring.
    Returns N = int cos+(theta + x) K(x) dx and Z = int K(x) dx over x in [-pi, pi],
    shapes (P, G) and (G,).

    The window is +-min(pi, 12 / sqrt(kappa)), and N is split where cos(theta + x)
    changes sign, so each piece [a, b] is smooth. On it cos(theta + x) =
    cos(theta) cos(x) - sin(theta) sin(x); the cosine part is integrated numerically,
    the sine part in closed form: int_a^b sin(x) K(x) dx = (K(a) - K(b)) / kappa.
    """
    half_width = np.minimum(np.pi, _KERNEL_SIGMAS / np.sqrt(kappa))  # (G,)

    def kernel(x):
        s = np.sin(0.5 * x)
        return np.exp(-2.0 * kappa[:, None] * s * s)

    z = integrate_gauss_legendre(kernel, -half_width, half_width)
    th = theta[:, None]  # (P, 1)
    w = half_width[None, :]  # (1, G)
    k = kappa[None, :]

    def sin_part(a, b):
        # (K(a) - K(b)) / kappa without cancellation when kappa is tiny.
        sa2, sb2 = np.sin(0.5 * a) ** 2, np.sin(0.5 * b) ** 2
        return -np.exp(-2.0 * k * sa2) * np.expm1(-2.0 * k * (sb2 - sa2)) / k

    # cos(theta + x) > 0 on (-pi/2 - theta, pi/2 - theta), and, once theta > pi/2, on
    # (3 pi/2 - theta, pi]: the ring wraps round to the lit side.
    lo_a = np.maximum(-w, -0.5 * np.pi - th)
    hi_a = np.maximum(lo_a, np.minimum(w, 0.5 * np.pi - th))
    lo_b = np.maximum(-w, 1.5 * np.pi - th)
    hi_b = np.maximum(lo_b, w)
    lo = np.stack([lo_a, lo_b])
    hi = np.stack([hi_a, hi_b])
    # Integrate only the non-empty pieces: most are empty once the kernels are narrow.
    pieces = np.nonzero(hi > lo)
    kappa_piece = np.broadcast_to(k, lo.shape)[pieces]

    def cos_kernel(x):
        s2 = np.sin(0.5 * x) ** 2
        return (1.0 - 2.0 * s2) * np.exp(-2.0 * kappa_piece[:, None] * s2)

    c_part = np.zeros(lo.shape)
    c_part[pieces] = integrate_gauss_legendre(cos_kernel, lo[pieces], hi[pieces])
    c_part = c_part.sum(axis=0)
    s_part = sin_part(lo, hi).sum(axis=0)  # exactly 0 on empty pieces
    n = np.cos(th) * c_part - np.sin(th) * s_part
    return n, z


def preintegrate_ring(cos_theta, radius: float, variances=SKIN_VARIANCES, weights=SKIN_WEIGHTS):
    """Penner's pre-integrated diffuse falloff on a ring of radius ``radius`` (mm).

    D(theta, r) = int cos+(theta + x) R(2 r sin(x/2)) dx / int R(2 r sin(x/2)) dx,
    both over x in [-pi, pi] (Penner & Borshukov, "Pre-Integrated Skin Shading", GPU
    Pro 2, 2011; Penner, SIGGRAPH 2011 course), with the profile
    R(d) = sum_i w_i exp(-d^2 / (2 v_i)) / (2 pi v_i) (d'Eon & Luebke 2007),
    evaluated per RGB channel. Limits: r -> inf gives max(cos theta, 0); r -> 0 gives
    the mean of cos+ over the ring, 1/pi, for every theta. Because D is a normalised
    convolution on the circle, int_0^pi D(theta) dtheta = 1 for every r.

    Parameters
    ----------
    cos_theta : array_like
        cos(theta) = N.L, any shape; clamped to [-1, 1].
    radius : float
        Curvature radius r > 0 in mm.
    variances, weights : sequence
        The profile's Gaussian variances (mm^2, > 0) and their RGB weights (G x 3).

    Returns
    -------
    ndarray
        D with shape ``cos_theta.shape + (3,)``.
    """
    c = np.clip(np.asarray(cos_theta, dtype=np.float64), -1.0, 1.0)
    v = np.asarray(variances, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64).reshape(len(v), 3)
    # The falloff depends on N.L only: integrate once per distinct value.
    unique, inverse = np.unique(c.ravel(), return_inverse=True)
    theta = np.arccos(unique)
    kappa = float(radius) ** 2 / v
    # Each Gaussian's 1/(2 pi v) normalisation weighs its ring integrals (2 pi cancels).
    mix = w / v[:, None]  # (G, 3)
    out = np.empty((len(unique), 3))
    for start in range(0, len(unique), _CHUNK):
        n, z = _ring_integrals(theta[start : start + _CHUNK], kappa)
        out[start : start + _CHUNK] = (n @ mix) / (z @ mix)
    return out[inverse].reshape(c.shape + (3,))


_H_NODES = 48


def chandrasekhar_h(albedo: float, nodes: int = _H_NODES):
    """Chandrasekhar's H function of isotropic scattering at Gauss-Legendre nodes on (0, 1):
    ``(mu, weights, H(mu))``.

    Solves 1 / H(mu) = sqrt(1 - w) + (w / 2) int_0^1 mu' H(mu') / (mu + mu') dmu'
    (Chandrasekhar, Radiative Transfer, 1950, ch. V, eq. 39) by fixed-point iteration,
    w the single-scattering albedo in [0, 1].
    """
    x, weights = gauss_legendre_rule(nodes)
    mu, weights = 0.5 * (x + 1.0), 0.5 * weights
    w = float(albedo)
    kernel = 0.5 * w * weights * mu / (mu[:, None] + mu[None, :])
    h = np.ones(nodes)
    for _ in range(2000):
        new = 1.0 / (np.sqrt(max(1.0 - w, 0.0)) + kernel @ h)
        if np.max(np.abs(new - h)) < 1e-13:
            return mu, weights, new
        h = new
    return mu, weights, h


@lru_cache(maxsize=256)
def diffuse_albedo(albedo: float) -> float:
    """Bi-hemispherical reflectance of a semi-infinite, index-matched, isotropically scattering medium.

    The plane albedo for light arriving at cos(theta) = mu is 1 - sqrt(1 - w) H(mu)
    (Chandrasekhar 1950, ch. VI); averaged over a cosine-weighted hemisphere,
    A = 1 - 2 sqrt(1 - w) int_0^1 H(mu) mu dmu. A = 0 at w = 0 and 1 at w = 1.
    """
    mu, weights, h = chandrasekhar_h(albedo)
    return float(1.0 - 2.0 * np.sqrt(max(1.0 - float(albedo), 0.0)) * np.sum(weights * mu * h))


def single_scattering_albedo(colour) -> np.ndarray:
    """Per channel, the single-scattering albedo w whose medium reflects ``colour``: the inverse of
    :func:`diffuse_albedo` (monotone), found by bisection to 1e-12; colours clamp to [0, 0.999].
    (Bisection, not scipy.optimize: that import alone costs a LUT bake a third of a second.)"""
    out = []
    for c in np.clip(np.asarray(colour, dtype=np.float64), 0.0, 0.999):
        lo, hi = 0.0, 1.0
        while c > 0.0 and hi - lo > 1e-12:
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if diffuse_albedo(mid) < c else (lo, mid)
        out.append(0.0 if c <= 0.0 else 0.5 * (lo + hi))
    return np.asarray(out)


class Subsurface(Model):
    """Pre-integrated skin: RGB = colour * D(acos(N.L), radius), A = specular.

    D is :func:`preintegrate_ring` (Penner 2011) with the d'Eon skin profile by default,
    or any sum of Gaussians given as ``variances`` (mm^2) and per-Gaussian RGB
    ``weights``. Light wraps past N.L = 0 and reddens there, since red scatters
    furthest; at large radii (flat skin) D tends to max(N.L, 0).
    """

    type_name = "sss"
    reference = "Penner & Borshukov, Pre-Integrated Skin Shading, GPU Pro 2 (2011); d'Eon & Luebke, GPU Gems 3 ch. 14 (2007)"
    params = (
        Param("colour", (1.0, 1.0, 1.0), "colour", doc="tint multiplied into the falloff, linear"),
        Param("radius", 10.0, lo=0.01, hi=10000.0, doc="curvature radius in mm"),
        Param("variances", SKIN_VARIANCES, "float_list", lo=0.0, lo_open=True, hi=1.0e4, doc="Gaussian variances, mm^2"),
        Param("weights", SKIN_WEIGHTS, "colour_list", doc="RGB weight of each Gaussian"),
        Param("specular", 0.028, lo=0.0, hi=16.0, doc="A, constant; skin's normal reflectance by default"),
    )

    def check(self, values, path):
        variances, weights = values["variances"], values["weights"]
        if not 1 <= len(variances) <= 16:
            raise MaterialError(path, "variances", f"expected 1 to 16 variances, got {len(variances)}")
        if len(weights) != len(variances):
            raise MaterialError(path, "weights", f"expected one RGB weight per variance ({len(variances)}), got {len(weights)}")
        totals = np.sum(np.asarray(weights, dtype=np.float64), axis=0)
        if np.any(totals <= 0.0):
            channel = "RGB"[int(np.argmin(totals))]
            raise MaterialError(path, "weights", f"expected a positive total weight in every channel, {channel} sums to 0")

    def evaluate(self, values, n_dot_l, n_dot_v):
        nl = np.asarray(n_dot_l, dtype=np.float64)
        shape = np.broadcast_shapes(nl.shape, np.shape(n_dot_v))
        out = np.empty(shape + (4,))
        # D depends on N.L alone: integrate at N.L's own shape, then broadcast over N.V.
        d = preintegrate_ring(nl, values["radius"], values["variances"], values["weights"])
        out[..., :3] = d * np.asarray(values["colour"])
        out[..., 3] = values["specular"]
        return out

    no_physical_f_cos = (
        "LUT only, no chart: the reference is light transport through a medium inside a sphere (volpathmis), "
        "not a BRDF of (l, v); what leaves a point depends on the curvature and where the light entered, so there "
        "is no f cos to sample on the (l, v) pairs every other chart is measured on. The fit's own renders "
        "measure its slice (manifest fit.relative_rms, from two seeds); re-using them here would report the "
        "fit on the sample it was fitted to, and fresh renders cost minutes per material"
    )
    physical_omissions = {
        "variances": "the diffusion profile's shape: in the reference it follows from the medium (Jensen's Skin1 "
        "mean free paths); no homogeneous medium scatters exactly as a sum of Gaussians",
        "weights": "the diffusion profile's shape per channel, as for variances",
        "specular": "the reference's boundary is index-matched (Mitsuba null) so that next-event estimation "
        "reaches the point lights; it reflects nothing, so the skin's specular highlight is missing there",
    }

    def physical_reference(self, values, albedo=(1.0, 1.0, 1.0), gloss=0.5):
        """Light transport through skin inside the object (:func:`skin_medium`), by ``volpathmis``.

        Validation fills each object showing the material with the medium, and a plane, which
        cannot hold one, is the top face of a slab of it (:func:`atlasgen.validate.run.render_physical`).
        The medium has Jensen's Skin1 extinction, scaled to the curvature radius, and the
        single-scattering albedo whose diffuse reflectance is the model's ``colour`` times
        the object's albedo (:func:`single_scattering_albedo`), so both describe a skin of
        the same colour. The boundary is index-matched (Mitsuba ``null``): next-event
        estimation cannot pass a smooth dielectric to reach a point light, so a dielectric
        sphere would be lit only indirectly. The interface's Fresnel reflection is the price
        (docs/validation.md).
        """
        colour = np.asarray(values["colour"], dtype=np.float64) * np.asarray(albedo, dtype=np.float64)
        medium, _ = skin_medium(values["radius"], colour=colour)
        return Reference(
            {"type": "null"},
            "volpathmis through Jensen 2001 Skin1 inside the object (a plane: a slab of it), index-matched boundary",
            # volpathmis: volpath's expectation with spectral MIS, whose red fireflies are
            # 2.5x rarer, so the reference converges (its noise floor) in a practical spp.
            integrator={"type": "volpathmis", "max_depth": 256, "rr_depth": 64},
            interior=medium,
            stochastic=True,
            builtin_only=True,
        )

    def fit_physical(self, values, gloss):
        """The slice fitted to volpath renders of a sphere of this skin (:mod:`atlasgen.models.sss_fit`).

        The sphere holds :meth:`physical_reference`'s medium (albedo 1: the model's ``colour``)
        behind its index-matched boundary; each (N.L, N.V, azimuth) configuration is one ray
        into it under one directional light, and the texels are the non-negative least-squares
        solution of L = M.rgb / pi + M.a f_s cos with M bilinear in the texels and
        M.a = ``specular``. The renders use ``volpathmis``: ``volpath``'s estimator with
        spectral MIS over the channel that samples distances, the same expectation with far
        less noise in the red channel (whose extinction differs most from the others).
        """
        ref = self.physical_reference(values)
        integrator = dict(ref.integrator)
        own = self.bake(values).values[0, ..., :3]  # the closed form, to report what the fit gained
        rgba, info, seconds = fitted_sss_slice(ref.interior, integrator, float(values["specular"]), float(gloss),
                                               model_rgb=own)  # fmt: skip
        fit = {"from": "physical", "reference": FIT_REFERENCE, "gloss": float(gloss),
               "integrator": "volpathmis", "specular": float(values["specular"]), **info}  # fmt: skip
        return SliceSet(np.array(rgba).reshape(1, *rgba.shape), extra={"fit": fit}, timings={"physical_renders": seconds})

    def physical_fit_problem(self, values):
        return None


def skin_medium(radius_mm: float, object_radius: float = _SPHERE_RADIUS, colour=None):
    """``(homogeneous medium dict, ior)``: Jensen et al.'s Skin1 scaled to a curvature radius.

    The reduced scattering coefficient with an isotropic phase function (the similarity
    relation). Coefficients per scene unit are the per-mm ones times
    (radius_mm / object_radius), so an object of ``object_radius`` is as large, in mean
    free paths, as a ``radius_mm`` ball of skin: the scale Penner's pre-integration assumes.
    With ``colour`` the extinction stays Skin1's and the single-scattering albedo is the one
    whose diffuse reflectance is ``colour`` (:func:`single_scattering_albedo`); without it,
    Skin1's own.
    """
    mm_per_unit = float(radius_mm) / float(object_radius)
    t = (np.asarray(SKIN1_SIGMA_S_REDUCED) + np.asarray(SKIN1_SIGMA_A)) * mm_per_unit
    s = t * single_scattering_albedo(colour) if colour is not None else np.asarray(SKIN1_SIGMA_S_REDUCED) * mm_per_unit
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
