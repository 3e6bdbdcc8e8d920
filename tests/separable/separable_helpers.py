"""Helpers shared by the separable-BRDF tests (``from tests.separable.separable_helpers import ...``)."""

from __future__ import annotations

import numpy as np

from atlasgen.separable.source import BrdfSource, make_source

ANALYTIC_DEFAULTS = dict(
    alpha=0.2,
    fresnel="schlick",
    f0=(0.04, 0.04, 0.04),
    ior=1.5,
    specular=(1.0, 1.0, 1.0),
    diffuse=(0.0, 0.0, 0.0),
    exponent=100.0,
)


def analytic(source="ggx", **overrides) -> BrdfSource:
    """An analytic source with the separable model's defaults."""
    return make_source({**ANALYTIC_DEFAULTS, "source": source, **overrides})


def random_frames(count: int, seed: int = 7):
    """Random unit normals with l, v mostly in n's hemisphere (some below the horizon)."""
    rng = np.random.default_rng(seed)

    def unit(k):
        d = rng.normal(size=(k, 3))
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    n = unit(count)
    l = unit(count)
    v = unit(count)
    l = np.where((np.sum(n * l, 1) < 0)[:, None] & (rng.random((count, 1)) < 0.8), -l, l)
    v = np.where((np.sum(n * v, 1) < 0)[:, None] & (rng.random((count, 1)) < 0.8), -v, v)
    return n, l, v
