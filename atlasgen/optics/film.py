"""Thin-film optics: the Airy reflectance of air / film / base per angle and wavelength, and its
integral to linear sRGB.

Belcour & Barla, "A Practical Extension to Microfacet Theory for the Modeling of
Varying Iridescence", ACM TOG 36(4), 2017. The spectral integral is a quadrature over
wavelength, with a step fine enough for the film's fringes, not the paper's Fourier-space
approximation, so the film-free limit is exact. The iridescent model
(:mod:`atlasgen.models.iridescent`) and its physical reference (:mod:`atlasgen.optics.thin_film`)
share it.
"""

from __future__ import annotations

from functools import cache

import numpy as np

__all__ = ["film_reflectance", "film_reflectance_on_grid", "spectrum_to_rgb", "cie_xyz_cmfs", "spectral_samples",
           "spectral_grid", "XYZ_TO_LINEAR_SRGB", "D65_5NM", "d65", "ILLUMINANTS", "VISIBLE_NM", "MIN_SAMPLES", "MAX_PHASE_STEP"]  # fmt: skip

#: The visible range integrated over, in nm (the CIE 1931 tabulation range).
VISIBLE_NM = (360.0, 830.0)
#: Fewest quadrature samples, and the sample counts' granularity (grids are cached by count).
MIN_SAMPLES = 64
_SAMPLE_QUANTUM = 32
#: Largest film phase advance per sample, in radians. Sampling uniformly in wavenumber
#: 1/lambda makes the advance the same everywhere: 4 pi d n2 cos(theta2) d(1/lambda).
#: Against a 0.1 nm rule the colours stay within 1e-4 (1/40 of an 8-bit step) over the
#: whole parameter range (tests/models/test_iridescent.py).
MAX_PHASE_STEP = 0.5

#: CIE XYZ -> linear sRGB (IEC 61966-2-1:1999; D65 white).
XYZ_TO_LINEAR_SRGB = np.array(
    [
        [3.2406, -1.5372, -0.4986],
        [-0.9689, 1.8758, 0.0415],
        [0.0557, -0.2040, 1.0570],
    ]
)

# Multi-lobe piecewise-Gaussian fit of the CIE 1931 2-degree CMFs: (amplitude, mean nm,
# inverse sigma below the mean, inverse sigma above). Wyman, Sloan & Shirley, "Simple
# Analytic Approximations to the CIE XYZ Color Matching Functions", JCGT 2(2), 2013,
# section 2 (the multi-lobe fit).
_WSS_LOBES = (
    ((1.056, 599.8, 0.0264, 0.0323), (0.362, 442.0, 0.0624, 0.0374), (-0.065, 501.1, 0.0490, 0.0382)),
    ((0.821, 568.8, 0.0213, 0.0247), (0.286, 530.9, 0.0613, 0.0322)),
    ((1.217, 437.0, 0.0845, 0.0278), (0.681, 459.0, 0.0385, 0.0725)),
)


def cie_xyz_cmfs(wavelengths):
    """CIE 1931 x-bar, y-bar, z-bar at ``wavelengths`` (nm), shape (3, L).

    Wyman, Sloan & Shirley (JCGT 2013, multi-lobe fit): each curve is a sum of piecewise
    Gaussians a exp(-((lambda - mu) s)^2 / 2), with s = s1 below mu and s2 above.
    """
    lam = np.asarray(wavelengths, dtype=np.float64)
    out = np.zeros((3,) + lam.shape)
    for row, lobes in enumerate(_WSS_LOBES):
        for amplitude, mean, below, above in lobes:
            t = (lam - mean) * np.where(lam < mean, below, above)
            out[row] += amplitude * np.exp(-0.5 * t * t)
    return out


def spectral_samples(thickness: float, film_ior: float) -> int:
    """How many wavenumber samples resolve the film's interference fringes.

    The film phase phi = 4 pi d q2 / lambda (q2 = n2 cos(theta2) <= n2) is linear in the
    wavenumber 1/lambda, so uniform wavenumber samples advance it by the same amount
    each; the count keeps that below MAX_PHASE_STEP, with at least MIN_SAMPLES for the
    colour-matching functions themselves, rounded up to a multiple of 32.
    """
    span = 1.0 / VISIBLE_NM[0] - 1.0 / VISIBLE_NM[1]
    needed = 4.0 * np.pi * float(thickness) * float(film_ior) * span / MAX_PHASE_STEP + 1.0
    count = max(MIN_SAMPLES, int(np.ceil(needed)))
    return -(-count // _SAMPLE_QUANTUM) * _SAMPLE_QUANTUM


#: CIE standard illuminant D65, relative spectral power at 360, 365, ..., 830 nm, 100 at 560 nm
#: (CIE S 014-2/E:2006, ISO 11664-2; the 5 nm table, as Mitsuba 3's ``cie_d65`` tabulates it,
#: rescaled to 100 at 560 nm). Mitsuba's spectral variants upsample an RGB light to this
#: spectrum times a smooth reflectance curve (flat for white).
D65_5NM = (
    46.6383,
    49.3637,
    52.0891,
    51.0323,
    49.9755,
    52.3118,
    54.6482,
    68.7015,
    82.7549,
    87.1204,
    91.486,
    92.4589,
    93.4318,
    90.057,
    86.6823,
    95.7736,
    104.865,
    110.936,
    117.008,
    117.41,
    117.812,
    116.336,
    114.861,
    115.392,
    115.923,
    112.367,
    108.811,
    109.082,
    109.354,
    108.578,
    107.802,
    106.296,
    104.79,
    106.239,
    107.689,
    106.047,
    104.405,
    104.225,
    104.046,
    102.023,
    100,
    98.1671,
    96.3342,
    96.0611,
    95.788,
    92.2368,
    88.6856,
    89.3459,
    90.0062,
    89.8026,
    89.5991,
    88.6489,
    87.6987,
    85.4936,
    83.2886,
    83.4939,
    83.6992,
    81.863,
    80.0268,
    80.1207,
    80.2146,
    81.2462,
    82.2778,
    80.281,
    78.2842,
    74.0027,
    69.7213,
    70.6652,
    71.6091,
    72.979,
    74.349,
    67.9765,
    61.604,
    65.7448,
    69.8856,
    72.4863,
    75.087,
    69.3398,
    63.5927,
    55.0054,
    46.4182,
    56.6118,
    66.8054,
    65.0941,
    63.3828,
    63.8434,
    64.304,
    61.8779,
    59.4519,
    55.7054,
    51.959,
    54.6998,
    57.4406,
    58.8765,
    60.3125,
)


def d65(wavelengths):
    """D65's relative power at ``wavelengths`` (nm): :data:`D65_5NM`, linearly interpolated (0 outside 360-830 nm)."""
    grid = np.arange(len(D65_5NM)) * 5.0 + 360.0
    return np.interp(np.asarray(wavelengths, dtype=np.float64), grid, np.asarray(D65_5NM), left=0.0, right=0.0)


#: Illuminants a colour integral can weight by: the equal-energy E (the iridescent model's own
#: colours) and D65 (white light in Mitsuba's spectral render).
ILLUMINANTS = ("E", "D65")


@cache
def spectral_grid(samples: int, illuminant: str = "E"):
    """Wavelengths (nm), uniform in wavenumber over 360-830 nm, and (R, G, B, Y) weights on them.

    The integral int f(lambda) S(lambda) dlambda, S the illuminant, becomes
    int f(1/s) S(1/s) / s^2 ds, so each sample's colour-matching values carry S and the
    Jacobian lambda^2. Each weight row is normalised to sum to 1, so a spectrally flat
    reflectance of 1 maps exactly to RGB (1, 1, 1) and Y = 1: the illuminant is
    white-balanced to the sRGB white by a diagonal scaling of the linear channels (for D65,
    sRGB's own white, that scaling is the identity up to the CMF fit's error).
    """
    if illuminant not in ILLUMINANTS:
        raise ValueError(f"illuminant must be one of {ILLUMINANTS}, got {illuminant!r}")
    wavenumbers = np.linspace(1.0 / VISIBLE_NM[1], 1.0 / VISIBLE_NM[0], samples)
    wavelengths = 1.0 / wavenumbers
    xyz = cie_xyz_cmfs(wavelengths) * wavelengths**2
    if illuminant == "D65":
        xyz = xyz * d65(wavelengths)
    rows = np.vstack([XYZ_TO_LINEAR_SRGB @ xyz, xyz[1:2]])
    weights = rows / rows.sum(axis=1, keepdims=True)
    wavelengths.setflags(write=False)
    weights.setflags(write=False)
    return wavelengths, weights


def spectrum_to_rgb(reflectance, samples: int = MIN_SAMPLES, illuminant: str = "E"):
    """Linear sRGB and luminance Y of reflectance spectra sampled on ``spectral_grid(samples)``,
    lit by ``illuminant`` (:data:`ILLUMINANTS`).

    ``reflectance`` has shape (..., samples); returns (..., 3) RGB and (...) Y. RGB is
    the XYZ integral (Wyman et al. CMFs) through the sRGB matrix, normalised so that a
    flat spectrum of 1 gives (1, 1, 1); out-of-gamut negatives are not clipped here.
    """
    _, weights = spectral_grid(samples, illuminant)
    out = np.asarray(reflectance, dtype=np.float64) @ weights.T
    return out[..., :3], out[..., 3]


def _interface(q_i, q_j, eps_i, eps_j):
    """Fresnel amplitude coefficients (s, p) between media i and j.

    With q = n cos(theta) (so Snell's law is built in) and eps = n^2:
    r_s = (q_i - q_j) / (q_i + q_j), r_p = (eps_j q_i - eps_i q_j) / (eps_j q_i + eps_i q_j)
    (the Fresnel formulae, Born & Wolf section 1.5.2, multiplied through by n_i n_j).
    """
    # Both denominators vanish only where q_i = q_j = 0: media of equal index at grazing
    # incidence, i.e. no interface at all, so r = 0 there (the limit from inside).
    r_s = _divide(q_i - q_j, q_i + q_j)
    r_p = _divide(eps_j * q_i - eps_i * q_j, eps_j * q_i + eps_i * q_j)
    return r_s, r_p


def _divide(num, den):
    num, den = np.broadcast_arrays(num, den)
    return np.divide(num, den, out=np.zeros(num.shape, dtype=np.result_type(num, den)), where=den != 0)


def _amplitudes(c1, film_ior, base_ior, base_k):
    """q2 = n2 cos(theta2) and the (r12, r23) pairs for s and p polarisation."""
    sin2 = 1.0 - c1 * c1
    eps2 = float(film_ior) ** 2
    eps3 = complex(base_ior, base_k) ** 2
    q2 = np.sqrt(eps2 - sin2)
    q3 = np.sqrt(eps3 - sin2 + 0j)  # principal root: Im >= 0, the decaying wave
    pairs = zip(_interface(c1, q2, 1.0, eps2), _interface(q2 + 0j, q3, eps2, eps3))
    return q2, list(pairs)


def _airy(pairs, phase):
    """Unpolarised |r|^2 of the film from its amplitude pairs and e^{i phi}, shape (P, L)."""
    total = 0.0
    for r12, r23 in pairs:
        # u + i w = r23 e^{i phi}; |r12 + u + i w|^2 and |1 + r12 (u + i w)|^2 as sums of
        # squares: no cancellation beyond the one inherent in r12 + r23.
        z = r23[..., None] * phase
        u, w2 = z.real, z.imag**2
        r12 = r12[..., None]
        num = (r12 + u) ** 2 + w2
        den = (1.0 + r12 * u) ** 2 + r12 * r12 * w2
        # den vanishes only at grazing incidence with |r12 r23| = 1, where every stack
        # with an interface reflects fully: |r|^2 -> 1.
        total = total + np.divide(num, den, out=np.ones(num.shape), where=den > 0.0)
    return 0.5 * total


def film_reflectance(cos_theta, wavelengths, thickness, film_ior, base_ior, base_k=0.0):
    """Unpolarised reflectance of air / film / base, per angle and wavelength.

    Airy summation of the multiple reflections in the film, per polarisation
    (Born & Wolf section 1.6.4; Belcour & Barla 2017, section 3):

        r = (r12 + r23 e^{i phi}) / (1 + r12 r23 e^{i phi}),  phi = 4 pi d n2 cos(theta2) / lambda,
        R = (|r_s|^2 + |r_p|^2) / 2,

    with exact Fresnel amplitudes at both interfaces. The base may absorb
    (n3 = base_ior + i base_k, time convention e^{-i omega t}). Light comes from air and
    film_ior >= 1, so r12 and phi are real; with u + i w = r23 e^{i phi},

        |r|^2 = ((r12 + u)^2 + w^2) / ((1 + r12 u)^2 + r12^2 w^2).

    At d = 0, r reduces to the air/base coefficient r13 identically (the amplitudes
    compose as a tanh sum), so R is the base's Fresnel reflectance.

    Returns an array of shape ``cos_theta.shape + wavelengths.shape``.
    """
    c1 = np.clip(np.asarray(cos_theta, dtype=np.float64), 0.0, 1.0)
    lam = np.asarray(wavelengths, dtype=np.float64)
    q2, pairs = _amplitudes(c1, film_ior, base_ior, base_k)
    phase = np.exp(1j * (4.0 * np.pi * float(thickness)) * q2[..., None] / lam)
    return _airy(pairs, phase)


def film_reflectance_on_grid(cos_theta, samples: int, thickness, film_ior, base_ior, base_k=0.0):
    """:func:`film_reflectance` on ``spectral_grid(samples)``, without a trigonometric call per sample.

    The grid is uniform in wavenumber, so e^{i phi} is a geometric sequence in the sample
    index: e^{i phi_0} (e^{i dphi})^k, built by a cumulative product (rounding grows as
    k eps, below 1e-13 here). At d = 0 every factor is exactly 1.
    """
    c1 = np.clip(np.asarray(cos_theta, dtype=np.float64), 0.0, 1.0)
    wavelengths, _ = spectral_grid(samples)
    q2, pairs = _amplitudes(c1, film_ior, base_ior, base_k)
    k_phase = 4.0 * np.pi * float(thickness) * q2[..., None]
    step = np.exp(1j * k_phase * (1.0 / wavelengths[1] - 1.0 / wavelengths[0]))
    phase = np.repeat(step, samples, axis=-1)
    phase[..., 0] = np.exp(1j * k_phase[..., 0] / wavelengths[0])
    np.cumprod(phase, axis=-1, out=phase)
    return _airy(pairs, phase)
