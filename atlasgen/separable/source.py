"""A BRDF source (analytic or Mitsuba) and its sampling into the factor matrix."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from atlasgen.optics.thin_film import thin_film_rgb_f_cos
from atlasgen.separable.analytic import evaluate_analytic
from atlasgen.separable.materialx_oracle import evaluate_materialx_f_cos
from atlasgen.separable.mitsuba_source import bsdf_alpha, evaluate_mitsuba_f_cos, load_mitsuba_bsdf
from atlasgen.separable.parametrization import HORIZON_COS

__all__ = [
    "BrdfSource",
    "make_source",
    "thin_film_source",
    "materialx_source",
    "film_transmits",
    "sample_matrices",
    "sample_matrix",
    "lobe_alpha",
    "measure_lobe_alpha",
]


class BrdfSource:
    """One material's BRDF as a function of unit (l, v) in the local frame (n = +z), RGB.

    A source gives either f (``evaluate_f``, analytic models) or f cos(theta_l)
    (``evaluate_f_cos``, Mitsuba's ``BSDF.eval``); the other is derived. Values are
    ``(..., 3)``; non-finite values are passed through, so the caller can count and
    mask them (:func:`sample_matrix`).
    """

    def __init__(
        self,
        kind: str,
        evaluate_f=None,
        evaluate_f_cos=None,
        zero_on_horizon: bool = False,
        alpha: float | None = None,
        transmits: bool = False,
    ):
        if (evaluate_f is None) == (evaluate_f_cos is None):
            raise ValueError("give exactly one of evaluate_f, evaluate_f_cos")
        self.kind = kind
        self._f = evaluate_f
        self._f_cos = evaluate_f_cos
        # Mitsuba returns 0 at cos = 0 exactly; the sampling grid then avoids the horizon.
        self.zero_on_horizon = zero_on_horizon
        # The lobe's roughness where the parameters say it (None: measured from f, see lobe_alpha).
        self.alpha = alpha
        # f cos is non-zero for l below the surface (a back-light): the factors hold only the
        # upper hemispheres, so the bake adds a transmission slice (docs/separable.md).
        self.transmits = transmits

    def _shape(self, l, values):
        return np.asarray(values, dtype=np.float64).reshape(np.shape(l)[:-1] + (3,))

    def f_cos(self, l, v) -> np.ndarray:
        l = np.asarray(l, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
        if self._f_cos is not None:
            return self._shape(l, self._f_cos(l, v))
        # A non-finite f (a broken BSDF's NaN or inf; inf times a zero cosine is NaN) is counted and
        # masked by the callers (sample_matrices, reference_values), so its arithmetic is not warned about.
        with np.errstate(invalid="ignore"):
            return self._shape(l, self._f(l, v)) * np.maximum(l[..., 2], 0.0)[..., None]

    def f(self, l, v) -> np.ndarray:
        """f itself; from f cos it is (f cos) / max(cos theta_l, 1e-4), so keep l above the horizon."""
        l = np.asarray(l, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
        if self._f is not None:
            return self._shape(l, self._f(l, v))

        return self._shape(l, self._f_cos(l, v)) / np.maximum(l[..., 2], HORIZON_COS)[..., None]


def film_transmits(film: dict | None) -> bool:
    """Whether a ``film`` table sends light through from behind (``backlight`` > 0): its source is
    then non-zero for l below the surface, and a separable bake adds a transmission slice."""
    return float((film or {}).get("backlight", 0.0)) > 0.0


def thin_film_source(film: dict, alpha: float, diffuse) -> BrdfSource:
    """The thin-film microfacet BSDF (:func:`atlasgen.optics.thin_film.thin_film_rgb_f_cos`, the
    iridescent model's physical reference integrated to linear sRGB for white light) as a source:
    the film stack, split and back-light ``film``, GGX roughness ``alpha``, base colour ``diffuse``.
    f cos is the reflection where l and v are above the surface and, with ``film["backlight"]``
    > 0, the back-light's diffuse transmission where l is below it (v above); 0 at the horizon
    like Mitsuba's."""
    film = dict(film)
    alpha = float(alpha)
    diffuse = np.asarray(diffuse, dtype=np.float64)
    transmits = film_transmits(film)
    back_colour = np.asarray(film.pop("backlight_colour", (1.0, 1.0, 1.0)), dtype=np.float64)
    back = back_colour if transmits else None

    def f_cos(l, v):
        shape = np.shape(l)
        l2 = np.asarray(l, dtype=np.float64).reshape(-1, 3)
        v2 = np.asarray(v, dtype=np.float64).reshape(-1, 3)
        value = thin_film_rgb_f_cos(v2, l2, film, alpha, diffuse, back)  # w_i is the view, w_o the light
        lit = (l2[:, 2:3] > 0.0) | ((l2[:, 2:3] < 0.0) & transmits)
        return np.where(lit & (v2[:, 2:3] > 0.0), value, 0.0).reshape(shape)

    return BrdfSource("thin_film", evaluate_f_cos=f_cos, zero_on_horizon=True, alpha=alpha, transmits=transmits)


def materialx_source(spec: dict) -> BrdfSource:
    """A MaterialX surface shader's reflection as a source: MaterialX's own GLSL
    (:mod:`atlasgen.separable.materialx_oracle`) for ``spec["category"]`` with the constant inputs
    ``spec["oracle_inputs"]``, 0 where l or v is below the surface (the table holds reflection
    only), lobe roughness ``spec["alpha"]`` (the narrowest of its lobes)."""
    category, inputs = str(spec["category"]), dict(spec["oracle_inputs"])

    def f_cos(l, v):
        shape = np.shape(l)
        l2 = np.asarray(l, dtype=np.float64).reshape(-1, 3)
        v2 = np.asarray(v, dtype=np.float64).reshape(-1, 3)
        value = evaluate_materialx_f_cos(category, inputs, l2, v2)
        return np.where((l2[:, 2:3] > 0.0) & (v2[:, 2:3] > 0.0), value, 0.0).reshape(shape)

    alpha = spec.get("alpha")
    return BrdfSource("materialx", evaluate_f_cos=f_cos, zero_on_horizon=True, alpha=None if alpha is None else float(alpha))


def make_source(params: dict, path="<material>") -> BrdfSource:
    """The source a separable material's params describe (Mitsuba and MaterialX loaded lazily)."""
    if params["source"] == "materialx":
        return materialx_source(params["materialx"])
    if params["source"] == "thin_film":
        return thin_film_source(params["film"], params["alpha"], params["diffuse"])
    if params["source"] == "mitsuba":
        bsdf = load_mitsuba_bsdf(params["bsdf"], path)
        return BrdfSource("mitsuba", evaluate_f_cos=lambda l, v: evaluate_mitsuba_f_cos(bsdf, l, v), zero_on_horizon=True,
                          alpha=bsdf_alpha(params["bsdf"]))  # fmt: skip
    snapshot = dict(params)
    return BrdfSource(params["source"], evaluate_f=lambda l, v: evaluate_analytic(snapshot, l, v),
                      alpha=_analytic_alpha(snapshot))  # fmt: skip


def _analytic_alpha(params: dict) -> float | None:
    """The roughness of an analytic lobe; Blinn-Phong's exponent m as the Beckmann alpha
    sqrt(2 / (m + 2)) (Walter et al. 2007, eq. 33); None for a Lambertian."""
    if params["source"] in ("ggx", "beckmann", "ward"):
        return float(params["alpha"])
    if params["source"] == "blinn_phong":
        return float(np.sqrt(2.0 / (float(params["exponent"]) + 2.0)))
    return None


def lobe_alpha(source: BrdfSource) -> float | None:
    """The width the error estimator's lobe samples use: the source's roughness if it has
    one, else :func:`measure_lobe_alpha`; None when f has no lobe around the mirror direction."""
    return source.alpha if source.alpha is not None else measure_lobe_alpha(source)


#: View elevations (degrees from the normal) at which :func:`measure_lobe_alpha` looks for a lobe.
_PROBE_VIEWS = (0.0, 30.0, 60.0)


def measure_lobe_alpha(source: BrdfSource) -> float | None:
    """A roughness found from the sampled f: the narrowest lobe around the mirror direction.

    For each view in :data:`_PROBE_VIEWS`, f cos is sampled at angles t from the mirror
    direction r, out of the plane of incidence (so l stays above the horizon), on a log
    grid from 1e-3 to 1.2 rad. A microfacet lobe falls as exp(-t^2 / (4 alpha^2))
    (Beckmann D with theta_h ~ t / 2), to exp(-1/2) of its height above the far value at
    t = sqrt(2) alpha; that t / sqrt(2) is the alpha returned, the smallest over the views.
    None if f cos at r is within 5% of its far value at every view (no lobe: Lambertian).
    """
    t = np.concatenate([[0.0], np.geomspace(1e-3, 1.2, 64)])
    found = []
    for degrees in _PROBE_VIEWS:
        theta = np.radians(degrees)
        v = np.array([np.sin(theta), 0.0, np.cos(theta)])
        r = np.array([-np.sin(theta), 0.0, np.cos(theta)])
        l = np.cos(t)[:, None] * r + np.sin(t)[:, None] * np.array([0.0, 1.0, 0.0])
        value = np.mean(source.f_cos(l, np.broadcast_to(v, l.shape)), axis=-1)
        value = np.where(np.isfinite(value), value, 0.0)
        peak, far = value[0], value[-1]
        if not peak > 1.05 * far:
            continue
        below = np.nonzero(value - far < (peak - far) * np.exp(-0.5))[0]
        if below.size:
            found.append(t[below[0]] / np.sqrt(2.0))
    return float(min(found)) if found else None


@lru_cache(maxsize=32)
def _grid_directions(parametrization, resolution: int, lift: bool = False):
    # The grid depends only on the parametrization; every material reuses it.
    l, v = parametrization.grid_directions(resolution, lift=lift)
    l, v = l.reshape(-1, 3), v.reshape(-1, 3)
    l.flags.writeable = False
    v.flags.writeable = False
    return l, v


def sample_matrices(source: BrdfSource, parametrization, resolution: int, targets=("f_cos",)):
    """The sampled BRDF matrices, one per target and colour channel, from one evaluation pass.

    Row i is pi1 texel i, column ``y * n + x`` is pi2 texel (x, y). Targets:
    ``"f_cos"``: f cos(theta_l); ``"f_proxy"``: f times the parametrization's cosine
    proxy (the rebuild multiplies by cos(theta_l) / proxy). Configurations with l or v
    below the horizon take the value at the nearest valid one
    (:meth:`Parametrization.grid_directions`). Non-finite samples become 0 and are counted.

    Returns
    -------
    matrices : dict of ndarray, each (3, resolution, resolution**2)
    nonfinite : int
        How many (sample, channel) values were NaN or inf.
    """
    l, v = _grid_directions(parametrization, resolution, source.zero_on_horizon)
    f = source.f(l, v)
    finite = np.isfinite(f)
    nonfinite = int(np.count_nonzero(~finite))
    f = np.where(finite, f, 0.0)
    out = {}
    for target in targets:
        if target == "f_cos":
            values = f * np.maximum(l[:, 2:3], 0.0)
        elif target == "f_proxy":
            c1, c2 = parametrization.cosine_proxy(resolution)
            values = f * (c1[:, None] * c2[None, :]).reshape(-1, 1)
        else:
            raise ValueError(f"unknown target {target!r}")
        out[target] = np.ascontiguousarray(values.reshape(resolution, -1, 3).transpose(2, 0, 1))
    return out, nonfinite


def sample_matrix(source: BrdfSource, parametrization, resolution: int, target: str = "f_cos"):
    """One target's matrix ``(3, n, n*n)`` and the non-finite count (see :func:`sample_matrices`)."""
    matrices, nonfinite = sample_matrices(source, parametrization, resolution, (target,))
    return matrices[target], nonfinite
