"""How a light's irradiance falls off with distance and, for a spot light, off its axis.

The renderer's shader (``atlasgen/shaders/lighting.wgsl``), the Mitsuba references
(:mod:`atlasgen.validate.mitsuba_scene`) and the NumPy rebuilds all apply these two factors;
this module is their one statement in NumPy.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DISTANCE_SQUARED_FLOOR", "range_window", "spot_factor", "windowed_irradiance"]

#: The least d^2 that 1/d^2 is taken at: float32's least normal number (2^-126), the renderer's floor too, so that
#: a light on the surface divides by no zero. It was 1e-12, which dimmed every light of a scene smaller than 1e-6.
DISTANCE_SQUARED_FLOOR = 2.0**-126


def range_window(distance, light_range):
    """W(d, r) = saturate(1 - (d/r)^4)^2, the window that brings inverse-square falloff to exactly 0 at d = r.

    Frostbite's form (Lagarde & de Rousiers 2014, "Moving Frostbite to PBR", eq. 26) and Unreal's
    (Karis 2013, "Real Shading in Unreal Engine 4"): 1 at d = 0, 0 at and beyond the range, with zero
    slope at d = r. ``light_range`` of ``inf`` (a light without a range) gives 1 everywhere.

    >>> float(range_window(0.0, 2.0)), float(range_window(1.0, 2.0)), float(range_window(2.0, 2.0)), float(range_window(3.0, 2.0))
    (1.0, 0.87890625, 0.0, 0.0)
    >>> float(range_window(1e6, float("inf")))
    1.0
    """
    d = np.asarray(distance, dtype=np.float64)
    r = np.asarray(light_range, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        x = np.where(np.isinf(r), 0.0, d / r)
    w = np.clip(1.0 - x**4, 0.0, 1.0) ** 2
    return np.where(d >= r, 0.0, w)


def windowed_irradiance(intensity, distance, light_range):
    """E = I W(d, r) / max(d^2, 2^-126): a point light's irradiance normal to the light direction at distance d.

    >>> float(windowed_irradiance(4.0, 1.0, 2.0))  # 4 * (1 - 1/16)^2
    3.515625
    >>> float(windowed_irradiance(4.0, 2.0, 2.0))
    0.0
    """
    d = np.asarray(distance, dtype=np.float64)
    return np.asarray(intensity, dtype=np.float64) * range_window(d, light_range) / np.maximum(d * d, DISTANCE_SQUARED_FLOOR)


def spot_factor(cos_theta, inner_degrees, outer_degrees):
    """The share of a spot light's axial intensity sent at angle theta off its axis.

    Mitsuba 3's ``spot`` emitter (``beam_width`` = inner, ``cutoff_angle`` = outer): 1 inside
    the inner cone, linear in the angle down to 0 at the outer cone, 0 beyond it (inner < outer):

        S = 1 (theta <= inner),  (outer - theta) / (outer - inner) (inner < theta < outer),  0 (theta >= outer).

    >>> [round(float(spot_factor(np.cos(np.radians(t)), 10.0, 30.0)), 6) for t in (0, 10, 20, 29, 30, 40)]
    [1.0, 1.0, 0.5, 0.05, 0.0, 0.0]
    """
    c = np.clip(np.asarray(cos_theta, dtype=np.float64), -1.0, 1.0)
    theta = np.arccos(c)
    inner, outer = np.radians(float(inner_degrees)), np.radians(float(outer_degrees))
    s = np.clip((outer - theta) / (outer - inner), 0.0, 1.0)
    return np.where(c > np.cos(outer), s, 0.0)
