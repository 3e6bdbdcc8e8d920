"""A BRDF source (analytic or Mitsuba) and its sampling into the factor matrix."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from atlasgen.separable.analytic import evaluate_analytic
from atlasgen.separable.parametrization import HORIZON_COS
from atlasgen.separable.mitsuba_source import evaluate_mitsuba_f_cos, load_mitsuba_bsdf

__all__ = ["BrdfSource", "make_source", "sample_matrices", "sample_matrix"]


class BrdfSource:
    """One material's BRDF as a function of unit (l, v) in the local frame (n = +z), RGB.

    A source gives either f (``evaluate_f``, analytic models) or f cos(theta_l)
    (``evaluate_f_cos``, Mitsuba's ``BSDF.eval``); the other is derived. Values are
    ``(..., 3)``; non-finite values are passed through, so the caller can count and
    mask them (:func:`sample_matrix`).
    """

    def __init__(self, kind: str, evaluate_f=None, evaluate_f_cos=None, zero_on_horizon: bool = False):
        if (evaluate_f is None) == (evaluate_f_cos is None):
            raise ValueError("give exactly one of evaluate_f, evaluate_f_cos")
        self.kind = kind
        self._f = evaluate_f
        self._f_cos = evaluate_f_cos
        # Mitsuba returns 0 at cos = 0 exactly; the sampling grid then avoids the horizon.
        self.zero_on_horizon = zero_on_horizon

    def _shape(self, l, values):
        return np.asarray(values, dtype=np.float64).reshape(np.shape(l)[:-1] + (3,))

    def f_cos(self, l, v) -> np.ndarray:
        l = np.asarray(l, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
        if self._f_cos is not None:
            return self._shape(l, self._f_cos(l, v))
        return self._shape(l, self._f(l, v)) * np.maximum(l[..., 2], 0.0)[..., None]

    def f(self, l, v) -> np.ndarray:
        """f itself; from f cos it is (f cos) / max(cos theta_l, 1e-4), so keep l above the horizon."""
        l = np.asarray(l, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
        if self._f is not None:
            return self._shape(l, self._f(l, v))

        return self._shape(l, self._f_cos(l, v)) / np.maximum(l[..., 2], HORIZON_COS)[..., None]


def make_source(params: dict, path="<material>") -> BrdfSource:
    """The source a separable material's params describe (Mitsuba loaded lazily)."""
    if params["source"] == "mitsuba":
        bsdf = load_mitsuba_bsdf(params["bsdf"], path)
        return BrdfSource("mitsuba", evaluate_f_cos=lambda l, v: evaluate_mitsuba_f_cos(bsdf, l, v), zero_on_horizon=True)
    snapshot = dict(params)
    return BrdfSource(params["source"], evaluate_f=lambda l, v: evaluate_analytic(snapshot, l, v))


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
