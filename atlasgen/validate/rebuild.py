"""The atlas path recomputed on the CPU from the renderer's g-buffer.

Each model supplies CPU twins of its lighting (:meth:`atlasgen.models.base.Model.radiance_rebuilds`):
the radiance one light adds at given normals, light and view directions, albedos and
glosses, from the atlas's 8-bit texels (what the GPU samples) and, where the model can,
from its own float data sampled the same way. :func:`rebuild_image` sums them over the
scene's lights at the pixels the g-buffer holds (normals, depths, albedos, glosses).

For a table model that splits what the atlas costs against the model reference into
resolution and filtering (the float table), 8-bit quantization (the difference between
the two) and the renderer's own precision (the GPU image against the 8-bit rebuild). For
a separable material the 8-bit rebuild is the include's ``separable_f_cos`` in float64:
the GPU image against it checks the renderer's sampling and precision, and it against the
source BSDF measures the factorization and its 8 bits, weighted by what the scene shows.
"""

from __future__ import annotations

import time

import numpy as np

from atlasgen.io.manifest import MaterialEntry
from atlasgen.models.base import RadianceRebuild
from atlasgen.optics.falloff import DISTANCE_SQUARED_FLOOR, range_window, spot_factor
from atlasgen.render.camera import pixel_rays

__all__ = ["rebuild_images", "rebuild_image", "material_mask", "n_dot_v_image"]


def material_mask(entry: MaterialEntry, aovs: dict) -> np.ndarray:
    """``(h, w)`` bool: the pixels whose g-buffer ID is one of ``entry``'s slices."""
    ids = np.asarray(aovs["id"]).astype(np.int64)
    return (ids >= entry.first_slice) & (ids < entry.first_slice + entry.slice_count)


def _pixel_geometry(scene, aovs, mask):
    rays = pixel_rays(scene.camera, scene.width, scene.height)[mask]
    depth = np.asarray(aovs["depth"], dtype=np.float64)[mask]
    n = np.asarray(aovs["normal"], dtype=np.float64)[mask]
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    x = np.asarray(scene.camera.position, dtype=np.float64) + rays * depth[:, None]
    v = -rays / np.linalg.norm(rays, axis=1, keepdims=True)
    return x, n, v


def n_dot_v_image(scene, aovs: dict, mask) -> np.ndarray:
    """``(h, w)``: N.V at each pixel of ``mask`` (True = wanted), from the g-buffer's normal and the
    direction to the camera through the pixel; NaN elsewhere. N.V < 0 (a normal facing away, as a
    back face shows it) stays negative."""
    mask = np.asarray(mask, dtype=bool)
    out = np.full(mask.shape, np.nan)
    if mask.any():
        _, n, v = _pixel_geometry(scene, aovs, mask)
        out[mask] = (n * v).sum(axis=1)
    return out


def _light_at(light, x):
    """(unit l, irradiance E) of ``light`` at points ``x``."""
    radiant = np.asarray(light.colour, dtype=np.float64) * light.intensity
    if light.type in ("point", "spot"):
        d = np.asarray(light.position, dtype=np.float64) - x
        d2 = np.maximum((d * d).sum(1), DISTANCE_SQUARED_FLOOR)
        l = d / np.sqrt(d2)[:, None]
        scale = range_window(np.sqrt(d2), light.range)
        if light.type == "spot":
            scale = scale * spot_factor(
                -(l @ np.asarray(light.direction, dtype=np.float64)), light.inner_angle, light.outer_angle
            )
        return l, radiant[None, :] * (scale / d2)[:, None]
    return np.broadcast_to(-np.asarray(light.direction, dtype=np.float64), x.shape), np.broadcast_to(radiant, x.shape)


def rebuild_image(rebuild: RadianceRebuild, entry: MaterialEntry, scene, aovs: dict) -> np.ndarray:
    """Linear image ``(h, w, 3)`` of ``entry``'s pixels: sum over the scene's lights of ``rebuild.radiance``.

    ``rebuild`` is one of the model's
    :meth:`~atlasgen.models.base.Model.radiance_rebuilds`; ``aovs`` are the renderer's
    g-buffer read-backs (``normal``, ``depth``, ``albedo``, ``gloss``, ``id``). Pixels of
    other materials and the background stay 0. The validation scenes lie within the
    renderer's level-0 distance, which is what the rebuilds sample.
    """
    mask = material_mask(entry, aovs)
    out = np.zeros((scene.height, scene.width, 3))
    if not mask.any():
        return out.astype(np.float32)
    x, n, v = _pixel_geometry(scene, aovs, mask)
    albedo = np.asarray(aovs["albedo"], dtype=np.float64)[mask]
    gloss = np.asarray(aovs["gloss"], dtype=np.float64)[mask]
    total = np.zeros((len(x), 3))
    for light in scene.lights:
        l, irradiance = _light_at(light, x)
        total += rebuild.radiance(n, l, v, albedo, gloss, irradiance)
    out[mask] = total
    return out.astype(np.float32)


def rebuild_images(model, entry: MaterialEntry, atlas, scene, aovs: dict, float_slices=None) -> dict:
    """``{name: (image, seconds, description)}`` for each of the model's rebuilds (``"8bit"``,
    and ``"float"`` where it has one); the seconds include decoding the atlas (``atlas``: an
    :class:`~atlasgen.io.atlas.Atlas` already read, or its path) and, without ``float_slices``
    (the bake cache's), computing the float table."""
    t0 = time.perf_counter()
    rebuilds = model.radiance_rebuilds(entry, atlas, float_slices)
    setup = (time.perf_counter() - t0) / max(len(rebuilds), 1)
    images = {}
    for name, rebuild in rebuilds.items():
        t0 = time.perf_counter()
        image = rebuild_image(rebuild, entry, scene, aovs)
        images[name] = (image, setup + time.perf_counter() - t0, rebuild.description)
    return images
