"""Image metrics on the same display image: RMSE, PSNR and mean FLIP.

Every metric compares ``display_clip(test)`` with ``display_clip(reference)``
(:func:`atlasgen.optics.display.display_clip`), the sRGB image a user looks at, so dark
and bright regions weigh as they are seen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from atlasgen.optics.display import display_clip

__all__ = ["rmse", "psnr", "relative_rms", "flip", "flip_heatmap", "ImageMetrics", "compare_images", "noise_floor",
           "NOISE_FLOOR_MARGIN_DB"]  # fmt: skip

#: A stochastic reference's noise floor must lie this far above the PSNR it measures.
NOISE_FLOOR_MARGIN_DB = 10.0


def rmse(reference, test) -> float:
    """Root-mean-square difference over every pixel and channel."""
    a = np.asarray(reference, dtype=np.float64)
    b = np.asarray(test, dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"image shapes differ: {a.shape} vs {b.shape}")
    return float(np.sqrt(np.mean((a - b) ** 2)))


def psnr(reference, test, peak: float = 1.0) -> float:
    """PSNR = 20 log10(peak / RMSE) in dB; ``inf`` for identical images."""
    e = rmse(reference, test)
    return math.inf if e == 0.0 else 20.0 * math.log10(peak / e)


def relative_rms(reference, test) -> float:
    """Relative L2 error of linear images, sqrt(sum (t - r)^2 / sum r^2); 0 for two black images.

    Pixels no object covers are black in both, so this is the relative RMS over the
    objects, weighted by radiance: the image-space counterpart of the separable
    bake's relative RMS of f cos (docs/separable.md).
    """
    a = np.asarray(reference, dtype=np.float64)
    b = np.asarray(test, dtype=np.float64)
    den = float((a * a).sum())
    num = float(((a - b) ** 2).sum())
    return 0.0 if den == 0.0 and num == 0.0 else (math.inf if den == 0.0 else math.sqrt(num / den))


def flip(reference, test) -> tuple[np.ndarray, float]:
    """LDR FLIP (Andersson et al., "FLIP: A Difference Evaluator for Alternating Images",
    HPG 2020) of two sRGB images in [0, 1]: ``(per-pixel error map (h, w), mean)``.

    Uses NVIDIA's ``flip-evaluator`` package at its default 67 pixels per degree.
    """
    import flip_evaluator

    ref = np.ascontiguousarray(np.clip(reference, 0.0, 1.0), dtype=np.float32)
    tst = np.ascontiguousarray(np.clip(test, 0.0, 1.0), dtype=np.float32)
    error_map, mean, _ = flip_evaluator.evaluate(ref, tst, "LDR", inputsRGB=True, applyMagma=False)
    error_map = np.asarray(error_map, dtype=np.float32)
    if error_map.ndim == 3:
        error_map = error_map[..., 0]
    return error_map, float(mean)


def flip_heatmap(error_map) -> np.ndarray:
    """FLIP's magma colour map of an error map in [0, 1], ``(h, w, 3)`` in [0, 1]."""
    import matplotlib

    cmap = matplotlib.colormaps["magma"]
    return np.asarray(cmap(np.clip(error_map, 0.0, 1.0))[..., :3], dtype=np.float32)


@dataclass
class ImageMetrics:
    """Metrics of a test image against a reference, both shown alike (:func:`display_clip`)."""

    rmse: float
    psnr: float
    flip: float
    linear_rmse: float
    linear_relative_rms: float = math.nan
    flip_map: np.ndarray | None = None

    def as_dict(self) -> dict:
        return {
            "rmse": self.rmse,
            "psnr_db": self.psnr if math.isfinite(self.psnr) else None,
            "flip": self.flip,
            "linear_rmse": self.linear_rmse,
            "linear_relative_rms": self.linear_relative_rms if math.isfinite(self.linear_relative_rms) else None,
        }


def compare_images(reference, test, exposure: float = 1.0, with_flip: bool = True, mask=None) -> ImageMetrics:
    """RMSE and PSNR of the display images (:func:`display_clip`), mean FLIP and its map; linear RMSE and relative RMS.

    ``mask`` (``(h, w)`` bool, True = excluded) leaves pixels out of every figure: FLIP is
    computed on the whole image (it looks at neighbourhoods) and averaged over the kept
    pixels only; the map stays whole.
    """
    keep = (slice(None),) if mask is None else (~np.asarray(mask, dtype=bool),)
    ref_ldr = display_clip(reference, exposure)
    test_ldr = display_clip(test, exposure)
    error_map, mean = flip(ref_ldr, test_ldr) if with_flip else (None, math.nan)
    if error_map is not None and mask is not None:
        mean = float(error_map[keep].mean()) if np.any(keep[0]) else math.nan
    reference, test = np.asarray(reference)[keep], np.asarray(test)[keep]
    return ImageMetrics(rmse(ref_ldr[keep], test_ldr[keep]), psnr(ref_ldr[keep], test_ldr[keep]), mean,
                        rmse(reference, test), relative_rms(reference, test), error_map)  # fmt: skip


def noise_floor(render_a, render_b, exposure: float = 1.0, mask=None) -> float:
    """A stochastic reference's noise floor: the PSNR in dB between two renders with different seeds.

    Compared as :func:`compare_images` compares (display images, ``mask`` excluded). The two
    renders differ by twice one render's noise variance, so one render lies about 3 dB
    closer to the converged image than this figure; an error measured against the reference
    is noise-limited where it comes within :data:`NOISE_FLOOR_MARGIN_DB` of it.
    """
    keep = (slice(None),) if mask is None else (~np.asarray(mask, dtype=bool),)
    return psnr(display_clip(render_a, exposure)[keep], display_clip(render_b, exposure)[keep])
