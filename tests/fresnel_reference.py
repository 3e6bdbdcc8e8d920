"""Fresnel's equations in his own sine/tangent form: an independent reference for the tests."""

from __future__ import annotations

import numpy as np


def fresnel_by_angles(theta_i, n):
    """Unpolarised reflectance from r_s = -sin(ti - tt)/sin(ti + tt), r_p = tan(ti - tt)/tan(ti + tt).

    Born & Wolf, *Principles of Optics*, 7th ed., section 1.5.2 (Snell: sin tt = sin ti / n).
    Undefined at normal incidence (0/0) and past the critical angle.
    """
    theta_t = np.arcsin(np.sin(theta_i) / n)
    r_s = -np.sin(theta_i - theta_t) / np.sin(theta_i + theta_t)
    r_p = np.tan(theta_i - theta_t) / np.tan(theta_i + theta_t)
    return 0.5 * (r_s**2 + r_p**2)
