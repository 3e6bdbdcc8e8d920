"""Lambertian diffuse: the exact, closed-form slice the rest of the toolchain is checked against."""

from __future__ import annotations

import numpy as np

from atlasgen.io.fields import Param
from atlasgen.models.base import Model, Reference

__all__ = ["Lambert"]


class Lambert(Model):
    """RGB = colour * max(N.L, 0), A = 0.

    The slice carries the cosine fall-off and the colour; the renderer's radiometric
    convention (the 1/pi of a Lambertian BRDF) lives in the renderer, not the atlas.
    Reference: J. H. Lambert, Photometria (1760).
    """

    type_name = "lambert"
    reference = "Lambert 1760; RGB = colour * max(N.L, 0), A = 0"
    params = (Param("colour", (1.0, 1.0, 1.0), "colour", doc="diffuse colour, linear"),)

    def evaluate(self, values, n_dot_l, n_dot_v):
        nl = np.asarray(n_dot_l, dtype=np.float64)
        shape = np.broadcast(nl, np.asarray(n_dot_v)).shape
        out = np.zeros(shape + (4,))
        out[..., :3] = np.maximum(nl, 0.0)[..., None] * np.asarray(values["colour"])
        return out

    def physical_reference(self, values, albedo=(1.0, 1.0, 1.0), gloss=0.5):
        """Mitsuba's own ``diffuse`` with reflectance albedo * colour: the consistency gate.

        It shares no code with atlasgen, so agreement proves that units, pi, camera and
        tone map line up.
        """
        colour = np.asarray(values["colour"], dtype=np.float64) * np.asarray(albedo, dtype=np.float64)
        return Reference({"type": "diffuse", "reflectance": {"type": "rgb", "value": colour.tolist()}},
                         "Mitsuba diffuse (the consistency gate)")  # fmt: skip
