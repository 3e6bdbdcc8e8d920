"""A procedural sky: a zenith-to-horizon gradient, a ground colour below the horizon and a soft sun disc.

No scattering model (no turbidity, no Preetham or Hosek-Wilkie): a few numbers an artist can
read, deterministic, in the renderer's units, so that a scene or a test can light with a sky and
no image file. Radiance is W/(m^2 sr) and the sun is given by its irradiance, W/m^2 normal to
its direction, as a ``directional`` light's ``intensity`` is (docs/scenes.md); the defaults give
a sky whose upper hemisphere has a mean radiance of about 0.6 and a sun of irradiance 3, about
the demo scene's key light (docs/scenes.md states both figures, tests/optics/test_sky.py
measures them).

Above the horizon (d.y = cos(theta) >= 0) the sky is horizon + (zenith - horizon) * sqrt(d.y);
below it, ``ground``. The sun adds a disc of angular radius ``sun_radius`` (degrees), flat
inside 3/4 of the radius and falling to 0 at 5/4 of it by a smoothstep, whose radiance is scaled
so that its irradiance on the image's own quadrature, sum_ij Omega_ij L_sun,ij max(d_ij . s, 0)
(:func:`atlasgen.optics.equirect.texel_solid_angles`), is ``sun_irradiance`` * ``sun_colour``
exactly. A disc narrower than the image resolves is widened to 1.5 texel spacings, so that every
resolution has one; the sun's power is the same at every resolution.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from atlasgen.optics.equirect import texel_directions, texel_solid_angles

__all__ = ["SkyParameters", "sky_image", "sun_radius_at"]


@dataclass(frozen=True)
class SkyParameters:
    """The sky's parameters; colours are linear radiance, W/(m^2 sr), per channel.

    ``sun_direction`` points towards the sun (unit length; above the horizon or not, the disc is
    drawn over the sky or the ground alike).
    """

    sun_direction: tuple = (0.0, 0.6, 0.8)
    sun_irradiance: float = 3.0
    sun_colour: tuple = (1.0, 0.95, 0.88)
    sun_radius: float = 2.0
    zenith: tuple = (0.25, 0.42, 0.85)
    horizon: tuple = (0.85, 0.9, 1.0)
    ground: tuple = (0.3, 0.27, 0.24)


def sun_radius_at(radius_degrees: float, height: int, width: int) -> float:
    """The disc's radius in radians at this resolution: ``radius_degrees``, or 1.5 texel spacings if wider.

    >>> round(sun_radius_at(0.25, 129, 256), 6)  # 1.5 x 2 pi / 256
    0.036816
    """
    spacing = max(2.0 * np.pi / width, np.pi / (height - 1))
    return max(np.radians(radius_degrees), 1.5 * spacing)


def _smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def sky_image(height: int, width: int, params: SkyParameters | None = None, scale: float = 1.0) -> np.ndarray:
    """The sky of ``params`` times ``scale`` as an equirectangular float32 image ``(height, width, 3)``
    (Mitsuba's convention). ``scale`` (an environment's intensity) applies before the image is float32:
    a sun of 1e38 W/m^2 at intensity 1e-37 is 10 W/m^2, not an infinity times 1e-37."""
    p = SkyParameters() if params is None else params
    d = texel_directions(height, width)
    up = d[..., 1:2]
    t = np.sqrt(np.clip(up, 0.0, 1.0))
    zenith, horizon, ground = (np.asarray(c, dtype=np.float64) for c in (p.zenith, p.horizon, p.ground))
    sky = np.where(up >= 0.0, horizon + (zenith - horizon) * t, ground)
    s = np.asarray(p.sun_direction, dtype=np.float64)
    s = s / np.linalg.norm(s)
    cos_s = d @ s
    radius = sun_radius_at(p.sun_radius, height, width)
    profile = 1.0 - _smoothstep(0.75 * radius, 1.25 * radius, np.arccos(np.clip(cos_s, -1.0, 1.0)))
    power = float(np.sum(texel_solid_angles(height, width) * profile * np.maximum(cos_s, 0.0)))
    if power > 0.0 and p.sun_irradiance > 0.0:
        sun = (p.sun_irradiance / power) * profile[..., None] * np.asarray(p.sun_colour, dtype=np.float64)
        sky = sky + sun
    # A sun beyond float32 becomes inf, which the environment's check refuses (half-float's range, Environment).
    with np.errstate(over="ignore"):
        return (sky * scale).astype(np.float32)
