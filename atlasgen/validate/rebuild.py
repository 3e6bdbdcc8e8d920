"""The atlas path recomputed on the CPU from the renderer's g-buffer.

LUT materials (:func:`rebuild_lut_image`): the renderer's equation with the slice
sampled bilinearly on the CPU, from either the 8-bit slice as baked or the model's
float table at the same texel centres. Against the model reference these split what
the atlas costs into resolution and filtering (float table) and 8-bit quantization
(the difference between the two), and the GPU image against the 8-bit rebuild checks
the renderer itself.

For a separable material the renderer adds, per light, L += E albedo f cos with f cos
rebuilt from the K factor slices by the include's ``separable_f_cos`` (lighting.wgsl).
:func:`rebuild_separable_image` evaluates the same sum in float64 with the public Python
rebuild (:func:`atlasgen.separable.rebuild.evaluate_factors`), at the normals, depths
and albedos the g-buffer holds. It splits the gap between the atlas image and the
source BSDF in two: GPU image against this rebuild (the renderer's sampling and
precision), and this rebuild against the source (the factorization and its 8 bits,
weighted by what the scene shows), which is what the manifest's error claims.
"""

from __future__ import annotations

import time

import numpy as np

from atlasgen.optics.interpolation import sample_slice

__all__ = ["rebuild_separable_image", "rebuild_lut_image", "sample_table", "lut_tables"]


#: The slice as the renderer samples it (bilinear, or nearest for flagged slices).
sample_table = sample_slice


class _TableModel:
    """Stands in for a model: ``evaluate`` samples a table instead of the formula."""

    def __init__(self, table, nearest=False):
        self.table = np.asarray(table, dtype=np.float64)
        self.nearest = nearest

    def evaluate(self, values, n_dot_l, n_dot_v):
        return sample_table(self.table, n_dot_l, n_dot_v, self.nearest)


def lut_tables(atlas_path, entry: dict) -> dict:
    """``{"float": model at texel centres, "8bit": the baked slice decoded}``, both linear ``(H, W, 4)``."""
    from atlasgen.io.atlas import read_atlas
    from atlasgen.models import get_model

    baked = get_model(entry["type"]).bake(entry["params"]).values[0]
    decoded = read_atlas(atlas_path).decode_slice(entry["first_slice"])
    return {"float": baked, "8bit": decoded}


def _pixel_geometry(scene, aovs, mask):
    from atlasgen.render.camera import pixel_rays

    rays = pixel_rays(scene.camera, scene.width, scene.height)[mask]
    depth = np.asarray(aovs["depth"], dtype=np.float64)[mask]
    n = np.asarray(aovs["normal"], dtype=np.float64)[mask]
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    x = np.asarray(scene.camera.position, dtype=np.float64) + rays * depth[:, None]
    v = -rays / np.linalg.norm(rays, axis=1, keepdims=True)
    return x, n, v


def _light_at(light, x):
    """(unit l, irradiance E) of ``light`` at points ``x``."""
    radiant = np.asarray(light.colour, dtype=np.float64) * light.intensity
    if light.type == "point":
        d = np.asarray(light.position, dtype=np.float64) - x
        d2 = np.maximum((d * d).sum(1), 1e-12)
        return d / np.sqrt(d2)[:, None], radiant[None, :] / d2[:, None]
    return np.broadcast_to(-np.asarray(light.direction, dtype=np.float64), x.shape), np.broadcast_to(radiant, x.shape)


def rebuild_lut_image(entry: dict, table: np.ndarray, scene, aovs: dict) -> np.ndarray:
    """The renderer's equation at the g-buffer's pixels with A sampled from ``table`` (mip level 0).

    L = sum over lights of E (albedo * A.rgb / pi + A.a k(s) max(N.H, 0)^s max(N.L, 0))
    (:func:`atlasgen.validate.references.renderer_f_cos` with the table in place of the
    model). The validation scenes lie within the renderer's level-0 distance.
    """
    from atlasgen.validate.references import renderer_f_cos

    ids = np.asarray(aovs["id"]).astype(np.int64)
    mask = ids == entry["first_slice"]
    out = np.zeros((scene.height, scene.width, 3))
    if not mask.any():
        return out.astype(np.float32)
    x, n, v = _pixel_geometry(scene, aovs, mask)
    albedo = np.asarray(aovs["albedo"], dtype=np.float64)[mask]
    gloss = np.asarray(aovs["gloss"], dtype=np.float64)[mask]
    model = _TableModel(table, nearest=bool(entry.get("flags", {}).get("nearest")))
    total = np.zeros((len(x), 3))
    for light in scene.lights:
        l, irradiance = _light_at(light, x)
        h = l + v
        h2 = (h * h).sum(1)
        nh = np.divide((n * h).sum(1), np.sqrt(h2), out=np.zeros_like(h2), where=h2 > 1e-12)
        nl, nv = (n * l).sum(1), (n * v).sum(1)
        for g in np.unique(gloss):
            sel = gloss == g
            f = renderer_f_cos(model, {}, albedo[sel], float(g), nl[sel], nv[sel], nh[sel], lv_degenerate=h2[sel] < 1e-12)
            total[sel] += irradiance[sel] * f
    out[mask] = total
    return out.astype(np.float32)


def rebuild_separable_image(atlas_path, entry: dict, scene, aovs: dict) -> tuple[np.ndarray, float]:
    """``(linear image (h, w, 3), seconds)`` of ``entry``'s pixels, rebuilt on the CPU.

    ``aovs`` are the renderer's g-buffer read-backs (``normal``, ``depth``, ``albedo``,
    ``id``). Pixels of other materials and the background stay 0.
    """
    from atlasgen.separable.rebuild import evaluate_factors, read_separable_factors

    t0 = time.perf_counter()
    first, count = entry["first_slice"], entry["slice_count"]
    ids = np.asarray(aovs["id"]).astype(np.int64)
    mask = (ids >= first) & (ids < first + count)
    out = np.zeros((scene.height, scene.width, 3))
    if not mask.any():
        return out.astype(np.float32), time.perf_counter() - t0
    factors = read_separable_factors(atlas_path, entry["name"])
    x, n, v = _pixel_geometry(scene, aovs, mask)
    albedo = np.asarray(aovs["albedo"], dtype=np.float64)[mask]
    total = np.zeros((len(x), 3))
    for light in scene.lights:
        l, irradiance = _light_at(light, x)
        total += irradiance * albedo * evaluate_factors(factors, n, l, v, cosine=True)
    out[mask] = total
    return out.astype(np.float32), time.perf_counter() - t0
