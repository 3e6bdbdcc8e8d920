"""Fresnel reflectance: exact for a dielectric interface, Schlick's approximation, and F0.

Every function takes the cosine of the angle of incidence, measured from the normal on
the side the light comes from, and returns unpolarised reflectance shaped like its
broadcast inputs.
"""

from __future__ import annotations

import numpy as np

__all__ = ["normal_reflectance", "fresnel_dielectric", "fresnel_schlick"]


def normal_reflectance(ior, k=0.0):
    """Reflectance at normal incidence from air, F0.

    F0 = ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2) for a complex index n + ik (Born & Wolf,
    *Principles of Optics*, 7th ed., ch. 14, optics of metals); k = 0 gives a
    dielectric's ((n - 1) / (n + 1))^2.
    """
    n = np.asarray(ior, dtype=np.float64)
    k = np.asarray(k, dtype=np.float64)
    return ((n - 1.0) ** 2 + k**2) / ((n + 1.0) ** 2 + k**2)


def fresnel_dielectric(cos_i, eta):
    """Exact unpolarised Fresnel reflectance at an interface of relative index ``eta``.

    With c = cos_i clamped to [0, 1] and cos_t = sqrt(1 - (1 - c^2) / eta^2),

        r_s = (c - eta cos_t) / (c + eta cos_t),
        r_p = (eta c - cos_t) / (eta c + cos_t),
        F = (r_s^2 + r_p^2) / 2

    (the Fresnel formulae, Born & Wolf, *Principles of Optics*, 7th ed., section 1.5.2).
    ``eta`` is n_transmitted / n_incident: from air onto glass it is 1.5. F(1) = F0 and,
    for eta > 1, F(0) = 1.

    For eta < 1 (light leaving the denser medium) there is total internal reflection past
    the critical angle, (1 - c^2) / eta^2 >= 1: F = 1 there, exactly, which is the limit
    of the formula as cos_t -> 0 from the transmitting side. At eta = 1 there is no
    interface and F = 0 for every c > 0; grazing incidence, c = 0, is then on the critical
    angle and counts as reflected (F = 1), so the function never divides 0 by 0.

    Parameters
    ----------
    cos_i : array_like
        Cosine of the angle of incidence; clamped to [0, 1].
    eta : float or array_like
        Relative refractive index, > 0; broadcast against ``cos_i``.

    Returns
    -------
    ndarray
        F, shaped like ``cos_i`` and ``eta`` broadcast.
    """
    c = np.clip(np.asarray(cos_i, dtype=np.float64), 0.0, 1.0)
    eta = np.asarray(eta, dtype=np.float64)
    sin_t2 = (1.0 - c * c) / (eta * eta)
    tir = sin_t2 >= 1.0
    cos_t = np.sqrt(np.maximum(1.0 - sin_t2, 0.0))
    # Under total internal reflection both denominators may be 0: the result is replaced by 1.
    with np.errstate(divide="ignore", invalid="ignore"):
        r_s = (c - eta * cos_t) / (c + eta * cos_t)
        r_p = (eta * c - cos_t) / (eta * c + cos_t)
    return np.where(tir, 1.0, 0.5 * (r_s * r_s + r_p * r_p))


def fresnel_schlick(cos_i, f0):
    """Schlick's approximation F = F0 + (1 - F0) (1 - cos_i)^5, cos_i clamped to [0, 1].

    Schlick, "An Inexpensive BRDF Model for Physically-based Rendering", Computer
    Graphics Forum 13(3), 1994, eq. 15. ``f0`` broadcasts against ``cos_i`` (an RGB F0
    needs ``cos_i[..., None]``). For n = 1.5 at 60 degrees it gives 0.070 where the exact
    value is 0.089.
    """
    c = np.clip(np.asarray(cos_i, dtype=np.float64), 0.0, 1.0)
    f0 = np.asarray(f0, dtype=np.float64)
    return f0 + (1.0 - f0) * (1.0 - c) ** 5
