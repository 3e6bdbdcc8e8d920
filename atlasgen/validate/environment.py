"""Where the renderer's environment lighting is approximate: its two approximations measured apart, on the CPU.

The renderer shades a table material under an environment of radiance L(l) with (docs/atlas-format.md,
"Environment lighting"; :mod:`atlasgen.optics.environment_tables`)

    approx = albedo / pi * sum_l lambda_l(N.V) sum_m L_lm Y_lm(n)  +  Lpre(r, alpha) S(N.V, alpha),

the SH band limit (l <= 4) for the diffuse term and the split sum (Karis 2013) for the specular one. The
integral both stand for, from the same decoded slice A (what ``atlas_sample`` returns), is

    exact = int_S2 [albedo A.rgb(n.l, N.V) / pi + A.a(n.l, N.V) D(n.h) V (n.l)+] L(l) dl,

taken here by brute force: a sum over every texel of the renderer's environment image
(:data:`atlasgen.render.environment.IMAGE_HEIGHT` rows, the image Mitsuba's ``envmap`` is given), each a
direction weighted by its solid angle sin(theta) dtheta dphi (rows at theta_j = pi j / (H - 1), the
weights scaled to sum to 4 pi, so a uniform environment's integral is exact). Then

    approx - exact = (diffuse_sh - diffuse_exact) + (specular_split_sum - specular_exact),

the SH part and the split-sum part, which sum to the whole CPU error by construction
(:func:`environment_parts`); :func:`break_down_environment` turns each into a PSNR on the material's
pixels with the same display convention as every other figure (:func:`atlasgen.validate.metrics.compare_images`).

A separable material's f cos is 4D and has no A.a: the renderer gives it the split sum with its own
directional albedo, approx = albedo Lpre(r, alpha) S_sep(N.V), against
exact = int_S2 albedo f cos(n, l, v) L(l) dl with f cos rebuilt from its factors as the light loop
evaluates it (:func:`separable_environment_parts`); the whole error is then the split sum's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from atlasgen.io.manifest import MaterialEntry
from atlasgen.optics.environment_tables import (
    diffuse_environment,
    reflect,
    slice_sh_table,
    slice_specular_table,
    specular_environment,
    split_sum_environment,
)
from atlasgen.optics.equirect import texel_directions, texel_solid_angles
from atlasgen.optics.interpolation import sample_slice
from atlasgen.optics.specular import specular_f_cos
from atlasgen.render.environment import EnvironmentData, custom_f_cos, decode_render_slice, separable_albedo_table
from atlasgen.validate.metrics import compare_images, finite_or_none
from atlasgen.validate.rebuild import _pixel_geometry, material_mask

__all__ = ["EnvironmentParts", "environment_parts", "separable_environment_parts", "break_down_environment"]

#: Material pixels integrated at a time (bounds the (pixels x texels) arrays to a few tens of MB).
_CHUNK = 48


@dataclass
class EnvironmentParts:
    """Linear images ``(h, w, 3)`` of one material's pixels (0 elsewhere): each term approximated and exact."""

    diffuse_sh: np.ndarray
    diffuse_exact: np.ndarray
    specular_split_sum: np.ndarray
    specular_exact: np.ndarray
    mask: np.ndarray  # (h, w) True on the material's pixels

    @property
    def approx(self) -> np.ndarray:
        return self.diffuse_sh + self.specular_split_sum

    @property
    def exact(self) -> np.ndarray:
        return self.diffuse_exact + self.specular_exact


def environment_parts(levels, srgb: bool, entry: MaterialEntry, scene, aovs: dict,
                      data: EnvironmentData | None = None) -> EnvironmentParts:  # fmt: skip
    """The renderer's two environment terms at the g-buffer's pixels of ``entry``, approximated and exact.

    ``levels``/``srgb``: the atlas as the renderer holds it (:class:`atlasgen.render.atlas_texture.RenderAtlas`);
    ``aovs``: the g-buffer read-backs (``normal``, ``depth``, ``albedo``, ``gloss``, ``id``); ``data``:
    the scene's prefiltered environment (built from ``scene.environment`` when not given). For a table
    material only (not ``custom_lighting``).
    """
    if data is None:
        data = EnvironmentData.of(scene.environment)
    mask = material_mask(entry, aovs)
    out = {k: np.zeros((scene.height, scene.width, 3)) for k in ("dsh", "dex", "ssum", "sex")}
    if mask.any():
        values = decode_render_slice(levels, srgb, entry, entry.first_slice)
        nearest = entry.flag("nearest")
        _, n, v = _pixel_geometry(scene, aovs, mask)
        albedo = np.asarray(aovs["albedo"], dtype=np.float64)[mask]
        gloss = np.asarray(aovs["gloss"], dtype=np.float64)[mask]
        nv = np.clip(np.sum(n * v, axis=1), 0.0, 1.0)
        out["dsh"][mask] = albedo * diffuse_environment(data.sh, slice_sh_table(values, nearest=nearest), n, nv)
        out["ssum"][mask] = specular_environment(data.levels, slice_specular_table(values, nearest=nearest),
                                                 reflect(v, n), nv, gloss)  # fmt: skip
        dex, sex = _brute_force(values, nearest, data.image, n, v, nv, gloss)
        out["dex"][mask] = albedo * dex
        out["sex"][mask] = sex
    return EnvironmentParts(out["dsh"], out["dex"], out["ssum"], out["sex"], mask)


def separable_environment_parts(levels, srgb: bool, entry: MaterialEntry, scene, aovs: dict,
                                data: EnvironmentData | None = None) -> EnvironmentParts | None:  # fmt: skip
    """A separable material's environment term at its g-buffer pixels, approximated and exact.

    As :func:`environment_parts`, for a ``custom_lighting`` material, with its f cos as the lighting
    pass evaluates it (:func:`atlasgen.render.environment.custom_f_cos`; None if it has none). The
    split sum is the whole approximation, so the diffuse parts are zero; S_sep is the renderer's
    (:func:`atlasgen.render.environment.separable_albedo_table`).
    """
    f_cos = custom_f_cos(levels, srgb, entry)
    if f_cos is None:
        return None
    if data is None:
        data = EnvironmentData.of(scene.environment)
    mask = material_mask(entry, aovs)
    approx, exact = np.zeros((scene.height, scene.width, 3)), np.zeros((scene.height, scene.width, 3))
    if mask.any():
        _, n, v = _pixel_geometry(scene, aovs, mask)
        albedo = np.asarray(aovs["albedo"], dtype=np.float64)[mask]
        gloss = np.asarray(aovs["gloss"], dtype=np.float64)[mask]
        nv = np.clip(np.sum(n * v, axis=1), 0.0, 1.0)
        table = separable_albedo_table(f_cos)
        approx[mask] = albedo * split_sum_environment(data.levels, table, reflect(v, n), nv, gloss)
        h, w = data.image.shape[:2]
        dirs, weights = texel_directions(h, w).reshape(-1, 3), texel_solid_angles(h, w).reshape(-1)
        radiance = np.asarray(data.image, dtype=np.float64).reshape(-1, 3) * weights[:, None]
        sums = np.zeros((len(n), 3))
        for p in range(len(n)):  # one pixel against every texel: (texels, 3) arrays
            sums[p] = np.sum(f_cos(np.broadcast_to(n[p], dirs.shape), dirs, np.broadcast_to(v[p], dirs.shape)) * radiance, axis=0)
        exact[mask] = albedo * sums
    zero = np.zeros_like(approx)
    return EnvironmentParts(zero, zero.copy(), approx, exact, mask)


def _brute_force(values, nearest, image, n, v, nv, gloss):
    """(int A.rgb / pi L dl, int A.a D V (n.l)+ L dl) per pixel, as sums over the image's texels."""
    h, w = image.shape[:2]
    dirs, weights = texel_directions(h, w).reshape(-1, 3), texel_solid_angles(h, w).reshape(-1)
    radiance = np.asarray(image, dtype=np.float64).reshape(-1, 3) * weights[:, None]
    rgb, alpha = values[..., :3], values[..., 3:4]
    diffuse, specular = np.zeros((len(n), 3)), np.zeros((len(n), 3))
    for s in range(0, len(n), _CHUNK):
        nc, vc, nvc = n[s : s + _CHUNK], v[s : s + _CHUNK], nv[s : s + _CHUNK]
        nl = np.clip(nc @ dirs.T, -1.0, 1.0)  # (p, k)
        nvk = np.broadcast_to(nvc[:, None], nl.shape)
        diffuse[s : s + _CHUNK] = np.einsum("pkc,kc->pc", sample_slice(rgb, nl, nvk, nearest=nearest), radiance) / np.pi
        half = dirs[None, :, :] + vc[:, None, :]
        n_dot_h = np.einsum("pkc,pc->pk", half, nc) / np.maximum(np.linalg.norm(half, axis=-1), 1e-12)
        for g in np.unique(gloss[s : s + _CHUNK]):
            rows = gloss[s : s + _CHUNK] == g
            with np.errstate(invalid="ignore"):  # V is infinite at N.L = N.V = 0, where the lobe is masked
                lobe = specular_f_cos(float(g), nl[rows], nvk[rows], n_dot_h[rows])
            lobe = np.nan_to_num(lobe) * sample_slice(alpha, nl[rows], nvk[rows], nearest=nearest)[..., 0]
            specular[s : s + _CHUNK][rows] = lobe @ radiance
    return diffuse, specular


def _psnr_dict(reference, test, exposure, mask) -> dict:
    m = compare_images(reference, test, exposure, with_flip=False, mask=~mask)
    return {"psnr_db": finite_or_none(m.psnr), "linear_relative_rms": m.linear_relative_rms}


def break_down_environment(parts: EnvironmentParts, exposure: float = 1.0) -> dict:
    """The CPU error of the renderer's environment terms on the material's pixels, whole and by part.

    ``total``: approx against exact; ``sh_band_limit``: exact with only the diffuse term approximated
    (exact + (diffuse_sh - diffuse_exact)) against exact; ``split_sum``: the same for the specular term.
    PSNR on display images (:func:`atlasgen.validate.metrics.compare_images`, peak 1 after exposure and
    sRGB encoding, as every figure of the report) and linear relative RMS. The two parts' linear errors
    sum to the total's (:func:`environment_parts`).
    """
    exact, mask = parts.exact, parts.mask
    return {
        "total": _psnr_dict(exact, parts.approx, exposure, mask),
        "sh_band_limit": _psnr_dict(exact, exact + parts.diffuse_sh - parts.diffuse_exact, exposure, mask),
        "split_sum": _psnr_dict(exact, exact + parts.specular_split_sum - parts.specular_exact, exposure, mask),
        "pixels": int(mask.sum()),
    }
