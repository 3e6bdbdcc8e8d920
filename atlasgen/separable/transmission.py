"""The transmission slice: a separable BRDF's light from below the surface, as one table slice.

Separable factors are defined over the upper hemispheres of l and v (their angles run to
90 degrees), so a BRDF that also transmits light from behind (the iridescent film's
back-light) keeps that part in one ordinary (N.L, N.V) slice after its K terms. The
include reads it where N.L <= 0 < N.V and returns f cos = rgb / pi, the renderer's
Lambertian convention for a slice's RGB (docs/separable.md, "Light from behind").

A table holds such light exactly when it depends on (N.L, N.V) alone, as a diffuse
transmission seen through a film, B T_B |N.L| (1 - R(N.V)) / pi, does; otherwise the slice
is its mean over the azimuth, the least-squares fit of an azimuth-free table.
"""

from __future__ import annotations

import numpy as np

from atlasgen.contract import texel_grid
from atlasgen.optics.projection import pair_directions
from atlasgen.optics.quantize import unorm_scale

__all__ = ["TRANSMISSION_AZIMUTHS", "transmission_slice", "encode_transmission_slice"]

#: Azimuths per texel, midpoints of [0, pi] (an isotropic BRDF is mirror-symmetric beyond pi).
TRANSMISSION_AZIMUTHS = 16


def transmission_slice(f_cos) -> np.ndarray:
    """The slice ``(32, 64, 4)``: RGB = pi mean_phi f cos(l, v) at each texel centre with N.L < 0, else 0; A = 0.

    ``f_cos(l, v)`` takes ``(N, 3)`` unit directions in the local frame (n = +z) and returns
    ``(N, 3)``; l is below the surface, v above it, phi the azimuth between them.
    """
    nl, nv = texel_grid()
    below = nl < 0.0
    phi = (np.arange(TRANSMISSION_AZIMUTHS) + 0.5) * np.pi / TRANSMISSION_AZIMUTHS
    shape = (int(below.sum()), TRANSMISSION_AZIMUTHS)
    l, v = pair_directions(nl[below][:, None], nv[below][:, None], phi, shape)
    value = np.asarray(f_cos(l.reshape(-1, 3), v.reshape(-1, 3)), dtype=np.float64)
    value = np.where(np.isfinite(value), value, 0.0).reshape(shape + (3,))
    out = np.zeros(nl.shape + (4,))
    out[below, :3] = np.pi * value.mean(axis=1)
    return out


def encode_transmission_slice(values: np.ndarray) -> tuple[np.ndarray, float]:
    """One transmission slice ``(32, 64, 4)`` for UNORM8: ``(stored in [0, 1], rgb_scale)``, RGB
    divided by its peak (float32, as the include's constants hold it), so a faint back-light
    keeps all 256 codes (:func:`~atlasgen.optics.quantize.unorm_scale`, as for every table slice). A is 0."""
    values = np.asarray(values, dtype=np.float64)
    scale = unorm_scale(np.max(values[..., :3]))
    stored = np.zeros_like(values)
    stored[..., :3] = np.clip(values[..., :3] / scale, 0.0, 1.0)
    return stored, scale
