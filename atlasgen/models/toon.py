"""Toon shading: flat colour bands over N.L, a silhouette band at low N.V, a stepped specular."""

from __future__ import annotations

import numpy as np

from atlasgen.contract import HEIGHT, WIDTH, texel_centres
from atlasgen.errors import MaterialError
from atlasgen.io.fields import Param, shown
from atlasgen.models.base import Model

__all__ = ["Toon"]


class Toon(Model):
    """Cel shading in the table, outlines from the renderer.

    With thresholds t_1 < ... < t_k and colours c_0 ... c_k,

        RGB = c_i  where t_i <= N.L < t_{i+1}   (t_0 = -inf, t_{k+1} = +inf)
        RGB = silhouette_colour  where N.V < silhouette
        A   = specular  where N.L >= specular_threshold and N.V >= silhouette, else 0

    The bands carry no cosine fall-off: the steps are the shading. A is a step in N.L,
    so the renderer's specular lobe shows only on the brightest part of the surface;
    A can gate the lobe but cannot make its edge hard, since the lobe's own shape is
    the renderer's. The table's silhouette band only darkens where N.V is small: its
    screen width grows with the object and a flat face goes dark all at once below the
    threshold, so ``outline = true`` also asks the renderer (through :meth:`flags` and
    the manifest) for screen-space outlines from depth and normal discontinuities
    (Saito & Takahashi, "Comprehensible Rendering of 3-D Shapes", SIGGRAPH 1990).
    With ``sampling = "nearest"`` (the default) every step is moved to the nearest
    texel boundary (N.L = -1 + (2i+1)/63, N.V = (2j+1)/62) and the manifest flags the
    slice ``nearest``, so the include's ``atlas_sample`` reads single texels: the
    table then reproduces the bands exactly, with hard edges, at any (N.L, N.V). With
    ``"linear"`` the steps stay where the artist put them and bilinear filtering
    softens each edge over one texel (2/63 in N.L, 1/31 in N.V); an ``error_budget``
    then lets the bake pre-filter (supersample) the texels.
    """

    type_name = "toon"
    reference = "Cel bands in an (N.L, N.V) table; outlines: Saito & Takahashi, SIGGRAPH 1990"
    params = (
        Param("thresholds", (0.0, 0.5), "float_list", lo=-1.0, hi=1.0, doc="N.L band edges, strictly ascending"),
        Param(
            "colours",
            ((0.05, 0.05, 0.09), (0.35, 0.35, 0.42), (1.0, 1.0, 1.0)),
            "colour_list",
            doc="one colour per band, one more than thresholds, darkest band first",
        ),
        Param("silhouette", 0.0, lo=0.0, hi=1.0, doc="N.V below which the silhouette colour applies; 0 = off"),
        Param("silhouette_colour", (0.0, 0.0, 0.0), "colour", doc="colour of the silhouette band"),
        Param("specular", 1.0, lo=0.0, hi=16.0, doc="A where the highlight is allowed"),
        Param("specular_threshold", 0.8, lo=-1.0, hi=1.0, doc="N.L from which the highlight is allowed"),
        Param("outline", False, "bool", doc="ask the renderer for screen-space outlines"),
        Param(
            "sampling",
            "nearest",
            "choice",
            choices=("nearest", "linear"),
            doc="nearest: steps snap to texel boundaries and stay hard; linear: steps blur over a texel",
        ),
    )

    no_physical_reference = (
        "an artistic model: cel bands, a silhouette band and outlines describe a look, "
        "not a material, so no physical counterpart exists; it is validated against its model reference only"
    )

    def check(self, values, path):
        thresholds, colours = values["thresholds"], values["colours"]
        if any(b <= a for a, b in zip(thresholds, thresholds[1:])):
            raise MaterialError(path, "thresholds", f"expected strictly ascending values, got {shown(list(thresholds))}")
        if len(colours) != len(thresholds) + 1:
            raise MaterialError(
                path,
                "colours",
                f"expected {len(thresholds) + 1} colours (one more than the {len(thresholds)} thresholds), got {len(colours)}",
            )
        self._check_every_band_is_baked(values, path)

    def _check_every_band_is_baked(self, values, path):
        """Refuse a band no texel centre of the N.L axis falls in (its colour would not be baked): two
        thresholds closer than a texel, or snapped (nearest sampling) to one texel edge."""
        thresholds = self.steps(values)[0]
        centres = texel_centres()[0]
        baked = set(np.searchsorted(thresholds, centres, side="right").tolist())
        for band in range(len(thresholds) + 1):
            if band not in baked:
                lo = "-1" if band == 0 else f"thresholds[{band - 1}] = {values['thresholds'][band - 1]:g}"
                hi = "1" if band == len(thresholds) else f"thresholds[{band}] = {values['thresholds'][band]:g}"
                raise MaterialError(path, "thresholds", f"expected every band to hold a texel of the N.L axis ({WIDTH} "
                                    f"texels, {2 / (WIDTH - 1):.4f} apart), but colours[{band}]'s band, from {lo} to "
                                    f"{hi}, holds none ({values['sampling']} sampling), so its colour would not be baked; "
                                    "move the thresholds apart")  # fmt: skip

    def flags(self, values):
        return {"outline": bool(values["outline"]), "nearest": values["sampling"] == "nearest"}

    @staticmethod
    def snap_n_dot_l(t):
        """The texel boundary of the N.L axis nearest to ``t``: -1 + (2i+1)/63, i in 0..62."""
        i = np.clip(np.rint((np.asarray(t, dtype=np.float64) + 1.0) * (WIDTH - 1) / 2.0 - 0.5), 0, WIDTH - 2)
        return -1.0 + (2.0 * i + 1.0) / (WIDTH - 1)

    @staticmethod
    def snap_n_dot_v(t):
        """The texel boundary of the N.V axis nearest to ``t``: (2j+1)/62, j in 0..30; 0 stays 0 (off)."""
        t = np.asarray(t, dtype=np.float64)
        j = np.clip(np.rint(t * (HEIGHT - 1) - 0.5), 0, HEIGHT - 2)
        return np.where(t > 0, (2.0 * j + 1.0) / (2 * (HEIGHT - 1)), 0.0)

    def steps(self, values):
        """(N.L thresholds, silhouette, specular threshold) as the table and the renderer see them."""
        thresholds = np.asarray(values["thresholds"], dtype=np.float64)
        silhouette, specular_threshold = values["silhouette"], values["specular_threshold"]
        if values["sampling"] == "nearest":
            return (self.snap_n_dot_l(thresholds), float(self.snap_n_dot_v(silhouette)),
                    float(self.snap_n_dot_l(specular_threshold)))  # fmt: skip
        return thresholds, silhouette, specular_threshold

    def evaluate(self, values, n_dot_l, n_dot_v):
        nl, nv = np.broadcast_arrays(
            np.clip(np.asarray(n_dot_l, dtype=np.float64), -1.0, 1.0),
            np.clip(np.asarray(n_dot_v, dtype=np.float64), 0.0, 1.0),
        )
        thresholds, silhouette, specular_threshold = self.steps(values)
        band = np.searchsorted(thresholds, nl, side="right")
        out = np.empty(nl.shape + (4,))
        out[..., :3] = np.asarray(values["colours"], dtype=np.float64)[band]
        edge = nv < silhouette
        out[edge, :3] = values["silhouette_colour"]
        out[..., 3] = np.where((nl >= specular_threshold) & ~edge, values["specular"], 0.0)
        return out
