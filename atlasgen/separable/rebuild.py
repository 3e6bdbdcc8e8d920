"""Rebuild f from separable factors: from float factors, or from an atlas file as a GPU would.

The interpolation is the GPU's: linear filtering between texel centres, clamped
at the edge texels (:mod:`atlasgen.optics.interpolation`), one mip level (level 0). Each factor texture of a term is one
32x32 half of the term's 64x32 slice (g left, h right), so the coordinates below
stay inside the half and never blend across the seam.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from atlasgen.errors import InputError
from atlasgen.io.atlas import Atlas, as_atlas
from atlasgen.optics.interpolation import linear_stencil, sample_slice
from atlasgen.optics.quantize import dequantize_rgba
from atlasgen.separable.factorize import Factors
from atlasgen.separable.parametrization import SYSTEM_ANGLES, angles_of_directions, get_parametrization

__all__ = [
    "sample_factors",
    "evaluate_factors",
    "factors_from_slices",
    "read_separable_factors",
    "evaluate_separable",
    "cached_on_pairs",
]


class _Stencil:
    """Linear (g) and bilinear (h) filtering at N points, as two sparse (N x texels) matrices.

    Filtering is linear in the texels, so one sparse product per factor serves every
    term and channel at once; the error measurement runs it for every candidate grid
    and target, on 100 000 pairs.
    """

    def __init__(self, resolution: int, x1, x2, y2, valid):
        # Here, not at the top: scipy.sparse costs ~0.3 s to import, and the renderer (so every
        # `atlasgen preview`, LUT materials too) imports this module; only separable materials build a stencil.
        from scipy.sparse import csr_matrix

        n = resolution
        self.valid = valid
        count = np.size(valid)
        i0, i1, f = linear_stencil(n, x1)
        x0, xa, fx = linear_stencil(n, x2)
        y0, ya, fy = linear_stencil(n, y2)

        def matrix(indices, weights, columns):
            rows = np.repeat(np.arange(count), len(indices))
            cols = np.stack(indices, axis=1).reshape(-1)
            return csr_matrix((np.stack(weights, axis=1).reshape(-1), (rows, cols)), shape=(count, columns))

        self.g_matrix = matrix((i0, i1), (1.0 - f, f), n)
        self.h_matrix = matrix(
            (y0 * n + x0, y0 * n + xa, ya * n + x0, ya * n + xa),
            ((1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy),
            n * n,
        )

    def apply(self, factors: Factors) -> np.ndarray:
        """g_k(pi1) h_k(pi2) per term and channel at the N points: ``(K, 3, N)``."""
        k, c, n = factors.g.shape
        g = self.g_matrix @ factors.g.reshape(k * c, n).T
        h = self.h_matrix @ factors.h.reshape(k * c, n * n).T
        return (g * h).T.reshape(k, c, -1)


_ANGLE_CACHE: dict = {}
_STENCIL_CACHE: dict = {}
_PAIR_CACHE: dict = {}


def _cached(cache, key, arrays, make):
    # Keyed on the identity of read-only arrays (the fixed error pairs), which every
    # material's error measurement shares; writeable arrays are never cached.
    if any(a.flags.writeable for a in arrays):
        return make()
    hit = cache.get(key)
    if hit is not None and all(x is y for x, y in zip(hit[0], arrays)):
        return hit[1]
    value = make()
    if len(cache) > 32:
        cache.clear()
    cache[key] = (arrays, value)
    return value


def cached_on_pairs(key, arrays, make):
    """``make()``, remembered while ``arrays`` are the same read-only (l, v) pair arrays.

    For per-pair quantities the error measurement needs for every candidate of every
    material (the fixed error pairs); writeable arrays are never cached.
    """
    return _cached(_PAIR_CACHE, (key, *map(id, arrays)), arrays, make)


def _stencil(name: str, resolution: int, n, l, v) -> _Stencil:
    p = get_parametrization(name)
    if n is None:  # local frame: angles depend on the system only, texels on the grid
        z = np.array([0.0, 0.0, 1.0])
        angles = _cached(_ANGLE_CACHE, (p.system, id(l), id(v)), (l, v), lambda: angles_of_directions(p.system, z, l, v))

        def make():
            named = dict(zip(SYSTEM_ANGLES[p.system], angles[0]))
            x1 = p.texel_of(p.single, named[p.single], resolution)
            x2 = p.texel_of(p.pair[0], named[p.pair[0]], resolution)
            y2 = p.texel_of(p.pair[1], named[p.pair[1]], resolution)
            return _Stencil(resolution, *(np.asarray(a).reshape(-1) for a in (x1, x2, y2, angles[1])))

        return _cached(_STENCIL_CACHE, (name, resolution, id(l), id(v)), (l, v), make)
    coords = p.coordinates(n, l, v, resolution)
    return _Stencil(resolution, *(np.asarray(a).reshape(-1) for a in coords))


def sample_factors(factors: Factors, n, l, v):
    """Per-term products g_k(pi1) h_k(pi2) at (n, l, v): ``(K, 3, N)``, and the validity mask.

    ``n = None`` means n = +z (the local frame); read-only (l, v) arrays then have their
    filtering stencils cached, as the fixed error pairs are used for every material.
    """
    stencil = _stencil(factors.parametrization, factors.resolution, n, l, v)
    return stencil.apply(factors), stencil.valid


def evaluate_factors(factors: Factors, n, l, v, cosine: bool = True, clamp: bool = True) -> np.ndarray:
    """f cos(theta_l) (or f, with ``cosine=False``) rebuilt from K terms, shaped ``(..., 3)``.

    With ``factors.target == "f_cos"``: f cos = max(sum_k g_k(pi1) h_k(pi2), 0) where
    n.l > 0 and n.v > 0, else 0 (a BRDF is never negative, so the shader clamps too),
    With ``"f_proxy"``: f cos = max(sum, 0) n.l / proxy, proxy = max(cos(proxy angle),
    1e-3) (:meth:`Parametrization.proxy_at`). Either way f = (f cos) / max(n.l, 1e-4).
    With a ``transmission`` slice, f cos = rgb(N.L, N.V) / pi of it (bilinear, as
    ``atlas_sample`` reads it) where n.l <= 0 < n.v.
    ``n = None`` means n = +z (directions in the local frame).
    """
    local = n is None  # n = +z, the local frame
    if local:
        n = np.array([0.0, 0.0, 1.0])
    shape = np.broadcast_shapes(np.shape(n), np.shape(l), np.shape(v))[:-1]
    if local and np.shape(l) == shape + (3,) and np.shape(v) == shape + (3,):
        products, valid = sample_factors(factors, None, l, v)
    else:
        n, l, v = (np.broadcast_to(np.asarray(a, dtype=np.float64), shape + (3,)) for a in (n, l, v))
        products, valid = sample_factors(factors, n, l, v)
    total = products.sum(axis=0).T  # (N, 3)
    if clamp:
        total = np.maximum(total, 0.0)
    total = np.where(valid[:, None], total, 0.0)
    nl = np.sum(np.asarray(n) * np.asarray(l), axis=-1).reshape(-1)
    if factors.target == "f_proxy":
        proxy = get_parametrization(factors.parametrization).proxy_at(n, l, v).reshape(-1)
        total = total * (np.maximum(nl, 0.0) / proxy)[:, None]
    if factors.transmission is not None:
        nv = np.sum(np.asarray(n) * np.asarray(v), axis=-1).reshape(-1)
        below = (nl <= 0.0) & (nv > 0.0)
        if below.any():
            rgb = sample_slice(factors.transmission, np.clip(nl[below], -1.0, 1.0), np.clip(nv[below], 0.0, 1.0))
            total[below] = rgb / np.pi
    if not cosine:
        total = total / np.maximum(nl, 1e-4)[:, None]
    return total.reshape(shape + (3,))


def factors_from_slices(
    decoded: np.ndarray, scale, bias, parametrization: str, target: str = "f_cos", transmission_scale=None
) -> Factors:
    """Factors from decoded atlas slices ``(K, 32, 64, 4)`` (what a sampler returns, linear).

    ``scale`` and ``bias`` are ``(K, 2, 3)``: per term, per factor (g, h), per channel;
    value = decoded * scale + bias. g is read from row 0 of the left half (every row
    holds the same values), h is the right half. With ``transmission_scale`` = (rgb_scale,
    rgb_bias), ``decoded`` has one slice more, K + 1: a transmission slice, whose linear RGB
    (texel * rgb_scale + rgb_bias) becomes :attr:`Factors.transmission`.
    """
    decoded = np.asarray(decoded, dtype=np.float64)
    scale = np.asarray(scale, dtype=np.float64)
    bias = np.asarray(bias, dtype=np.float64)
    k = scale.shape[0]
    half = decoded.shape[2] // 2
    g = decoded[:k, 0, :half, :3].transpose(0, 2, 1) * scale[:, 0, :, None] + bias[:, 0, :, None]
    h = decoded[:k, :, half:, :3].transpose(0, 3, 1, 2) * scale[:, 1, :, None, None] + bias[:, 1, :, None, None]
    back = None
    if transmission_scale is not None:
        rgb_scale, rgb_bias = transmission_scale
        back = decoded[k, :, :, :3] * rgb_scale + rgb_bias
    return Factors(g, h, parametrization, np.zeros((3, k)), target, back)


def read_separable_factors(atlas_path, material: str) -> Factors:
    """The 8-bit factors of a separable material, decoded from an atlas file and its manifest
    (``atlas_path``: the file, or an :class:`~atlasgen.io.atlas.Atlas` already read).

    Reads ``X.dds`` (or ``X.ktx2``) and ``X.json`` beside it through
    :func:`atlasgen.io.atlas.read_atlas`, which refuses a pair from different bakes; sRGB
    RGB is decoded as the GPU does.

    Raises
    ------
    InputError
        The atlas or manifest is missing, the two do not match, or there is no separable
        material of that name.
    """
    atlas = as_atlas(atlas_path if isinstance(atlas_path, Atlas) else Path(atlas_path))
    manifest_path = atlas.manifest_path
    if atlas.manifest is None:
        raise InputError(f"{manifest_path.as_posix()}: no such file (the manifest beside the atlas); re-run atlasgen bake")
    manifest = atlas.manifest
    entry = manifest.entry_named(material)
    if entry is None or entry.factors is None:
        names = ", ".join(m.name for m in manifest.materials if m.factors is not None) or "none"
        what = f"no material {material!r}" if entry is None else f"material {material!r} is {entry.type!r}, not 'separable'"
        raise InputError(f"{manifest_path.as_posix()}: {what}; separable materials: {names}")
    texels = np.asarray(atlas.image.levels[0])[entry.first_slice : entry.first_slice + entry.slice_count]
    decoded = dequantize_rgba(texels, atlas.srgb)
    factors = entry.factors
    back = factors.transmission  # the last slice, decoded with its slice's (rgb scale, rgb bias)
    pair = None if back is None else (entry.scale[back.slice][0], entry.bias[back.slice][0])
    return factors_from_slices(decoded, factors.factor_scale, factors.factor_bias, factors.parametrization,
                               factors.target, pair)  # fmt: skip


def evaluate_separable(atlas_path, material: str, n, l, v, cosine: bool = False) -> np.ndarray:
    """f (or f cos(theta_l)) of a separable material rebuilt from an atlas, for arrays of unit (n, l, v).

    This is the shader include's computation in float64: anyone can measure the
    atlas's error against their own reference without the bake.

    Examples
    --------
    >>> f = evaluate_separable("build/atlas.dds", "gold", n, l, v)  # doctest: +SKIP
    """
    return evaluate_factors(read_separable_factors(atlas_path, material), n, l, v, cosine=cosine)
