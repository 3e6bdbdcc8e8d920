"""The GGX-prefiltered environment of the split sum (Karis 2013), level by level.

Karis ("Real Shading in Unreal Engine 4", SIGGRAPH 2013 course, eq. 2 and "Pre-Filtered
Environment Map") splits the specular environment integral into the slice's directional
integral (:func:`atlasgen.optics.environment_tables.slice_specular_table`) times the environment
filtered by the lobe under the assumption n = v = r:

    Lpre(r, alpha) = int L(l) D(r.h) max(r.l, 0) dl / int D(r.h) max(r.l, 0) dl,   h = normalize(r + l)

with D the renderer's GGX distribution (:func:`atlasgen.optics.microfacet.ggx_distribution`).
Level k of ``levels`` holds perceptual roughness k / (levels - 1), alpha = max(roughness^2,
0.002) as the renderer maps gloss (:func:`atlasgen.optics.specular.specular_alpha`), so a
shader reads level (1 - gloss) (levels - 1), linearly between the two nearest levels
(:func:`sample_prefiltered`). Every level is an equirectangular image in Mitsuba's convention
(:mod:`atlasgen.optics.equirect`).
"""

from __future__ import annotations

import math

import numpy as np

from atlasgen.optics.equirect import resample_equirect, sample_equirect, texel_directions, texel_solid_angles
from atlasgen.optics.microfacet import ggx_distribution
from atlasgen.optics.specular import specular_alpha

__all__ = ["PREFILTER_LEVELS", "level_alpha", "level_width", "filter_width", "prefilter_ggx", "sample_prefiltered"]

#: Levels the renderer prefilters: roughness 0, 0.2, ..., 1.
PREFILTER_LEVELS = 6
#: Levels are filtered at least this wide (16x8), then resampled to their mip size when that is
#: smaller: coarser, the rough lobes' cosine fall-off is undersampled by the filter's target texels.
_MIN_FILTER_WIDTH = 16
#: Kernel evaluations per level at most (target rows x source texels); beyond it the source is
#: averaged down (:func:`atlasgen.optics.equirect.resample_equirect`) before filtering.
_LEVEL_BUDGET = 1 << 24
#: Levels 1 and above are filtered from the source averaged down to at most this width: its
#: column spacing, 0.012 radians, is a third of the sharpest filtered lobe's width (alpha = 0.04).
SOURCE_WIDTH = 512
#: Kernel values held at once (target rows x source texels).
_CHUNK = 1 << 21


def level_alpha(level: int, levels: int = PREFILTER_LEVELS) -> float:
    """GGX alpha of ``level``: roughness r = level / (levels - 1), alpha = max(r^2, 0.002) (gloss 1 - r).

    >>> [round(level_alpha(k), 4) for k in range(6)]
    [0.002, 0.04, 0.16, 0.36, 0.64, 1.0]
    """
    return float(specular_alpha(1.0 - level / (levels - 1)))


def level_width(source_width: int, level: int) -> int:
    """Width of ``level`` (its height is half): the source's >> level, a standard mip chain.

    So the levels can be one texture's mip levels (the renderer uploads them as one, and a
    shader picks the level with ``textureSampleLevel``); the source's width must be divisible by
    2^(levels - 1) and leave at least 4x2 (:func:`prefilter_ggx` checks).

    >>> [level_width(256, k) for k in range(6)]
    [256, 128, 64, 32, 16, 8]
    """
    return int(source_width) >> level


def filter_width(source_width: int, level: int, levels: int = PREFILTER_LEVELS) -> int:
    """Width at which ``level`` is filtered before it is resampled to :func:`level_width`: no finer than
    its lobe needs, no narrower than 16 (nor than the level itself).

    A lobe of roughness alpha is about alpha radians wide (D falls to half at tan(theta_h) =
    0.64 alpha, 1.3 alpha between r and l), so a column spacing 2 pi / W of alpha or less (W the
    power of two at or above 2 pi / alpha) resolves it; a wider level is the filtered one
    interpolated bilinearly, which is as good as the filter's own texels. Below 16 wide the filter's
    texels are too coarse for the cosine fall-off, so it runs at 16 and is averaged down.

    >>> [filter_width(256, k) for k in range(6)]
    [256, 128, 64, 32, 16, 16]
    >>> [filter_width(2048, k) for k in range(6)]
    [2048, 256, 64, 32, 16, 16]
    """
    if level == 0:
        return int(source_width)
    alpha = level_alpha(level, levels)
    lobe = 2 ** math.ceil(math.log2(2.0 * math.pi / alpha))
    w = min(int(source_width) >> level, lobe)
    return max(_MIN_FILTER_WIDTH, w + (w % 2))


def _filter_level(source: np.ndarray, height: int, width: int, alpha: float) -> np.ndarray:
    """Lpre at every texel of a ``height`` x ``width`` level from ``source``, whose width is a multiple of ``width``.

    The kernel depends on the target only through its row and, along phi, the difference of
    the two longitudes, so every column's kernel is column 0's rolled by m = W_s / W source
    columns: the sum over source texels is a circular correlation along phi per pair of rows,
    done by FFT. That is the brute-force sum over every source texel, reordered.
    """
    hs, ws, c = source.shape
    m = ws // width
    src_dirs = texel_directions(hs, ws)
    omega = texel_solid_angles(hs, ws)[:, :1]  # (Hs, 1): per row
    spectrum = np.fft.rfft(source, axis=1)  # (Hs, F, C)
    targets = texel_directions(height, width)[:, 0]  # column 0 of every row, (H, 3)
    out = np.empty((height, width, c))
    rows = max(1, _CHUNK // (hs * ws))
    for start in range(0, height, rows):
        mu = np.einsum("tk,hwk->thw", targets[start : start + rows], src_dirs)  # r.l, (t, Hs, Ws)
        # With n = v = r the half vector's cosine depends on r.l alone: r.h = sqrt((1 + r.l) / 2).
        kernel = ggx_distribution(np.sqrt(np.maximum(0.5 * (1.0 + mu), 0.0)), alpha) * np.maximum(mu, 0.0) * omega
        corr = np.fft.irfft(np.einsum("thf,hfc->tfc", np.conj(np.fft.rfft(kernel, axis=-1)), spectrum), n=ws, axis=1)
        out[start : start + rows] = corr[:, ::m] / kernel.sum(axis=(1, 2))[:, None, None]
    return out


def prefilter_ggx(image, levels: int = PREFILTER_LEVELS) -> list[np.ndarray]:
    """Lpre of ``image`` ``(H, W, C)`` at each level's roughness: a list of float32 ``(H_k, W_k, C)`` images.

    Level 0 (roughness 0, alpha = 0.002) is the source itself: its lobe, about 0.003 radians
    (0.15 degrees) between r and l, is narrower than a texel of any usable image (1.4 degrees at
    256 wide), so filtering it would only blur. Level k >= 1 is :func:`level_width` wide (W >> k by
    H >> k, a mip chain: 256x128 down to 8x4 for 6 levels) and holds, at each texel direction r, the
    normalised sum over source texels
    sum_s Omega_s D(r.h_s) max(r.l_s, 0) L_s / sum_s Omega_s D(r.h_s) max(r.l_s, 0)
    (Omega_s: :func:`atlasgen.optics.equirect.texel_solid_angles`), so a constant image stays
    that constant at every level. Levels 1 and above filter the source averaged down to at most
    :data:`SOURCE_WIDTH` wide (the average keeps its integral, so a sun keeps its irradiance), used
    as is when its width is a multiple of the level's and the sum fits ``_LEVEL_BUDGET`` kernel
    evaluations, else averaged further to the widest such multiple. A level is filtered at
    :func:`filter_width` and, where that differs from its mip size, resampled to it
    (:func:`atlasgen.optics.equirect.resample_equirect`: bilinear up, averaged down).
    """
    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 3 or img.shape[0] < 2:
        raise ValueError(f"expected an equirectangular image (H, W, C), got shape {img.shape}")
    if levels < 2:
        raise ValueError(f"expected at least 2 levels, got {levels}")
    w0 = img.shape[1]
    if img.shape[0] * 2 != w0 or img.shape[0] % (1 << (levels - 1)) or (img.shape[0] >> (levels - 1)) < 2:
        raise ValueError(
            f"expected a 2:1 image whose height divides by 2^{levels - 1} and leaves at least 4x2 at the last level"
            f" (a mip chain of {levels} levels), got shape {img.shape}"
        )
    out = [img.astype(np.float32)]
    work = img if w0 <= SOURCE_WIDTH else resample_equirect(img, SOURCE_WIDTH // 2, SOURCE_WIDTH).astype(np.float64)
    hw, ww = work.shape[:2]
    for k in range(1, levels):
        width = filter_width(w0, k, levels)
        height = width // 2
        if ww % width == 0 and height * hw * ww <= _LEVEL_BUDGET:
            source = work
        else:
            m = max(1, ww // width)
            while m > 1 and height * (m * width // 2) * (m * width) > _LEVEL_BUDGET:
                m -= 1
            source = resample_equirect(work, max(2, m * width // 2), m * width).astype(np.float64)
        level = _filter_level(source, height, width, level_alpha(k, levels))
        mip = level_width(w0, k)
        if mip != width:
            level = resample_equirect(level, mip // 2, mip)
        out.append(np.asarray(level, dtype=np.float32))
    return out


def sample_prefiltered(levels, directions, level) -> np.ndarray:
    """Lpre towards ``directions`` ``(..., 3)`` at fractional ``level`` (scalar or ``(...)``): the shader's lookup.

    Each level is sampled bilinearly (:func:`atlasgen.optics.equirect.sample_equirect`), then
    the two levels around ``level`` (clamped to [0, len(levels) - 1]) are blended linearly.
    """
    d = np.asarray(directions, dtype=np.float64)
    lv = np.clip(np.broadcast_to(np.asarray(level, dtype=np.float64), d.shape[:-1]), 0.0, len(levels) - 1)
    k0 = np.minimum(np.floor(lv).astype(np.intp), len(levels) - 2)
    f = (lv - k0)[..., None]
    out = np.zeros(d.shape[:-1] + (np.shape(levels[0])[-1],))
    for k in np.unique(np.concatenate([k0.ravel(), k0.ravel() + 1])):
        weight = np.where((k0 == k)[..., None], 1.0 - f, 0.0) + np.where((k0 + 1 == k)[..., None], f, 0.0)
        if np.any(weight):
            out += weight * sample_equirect(levels[k], d)
    return out
