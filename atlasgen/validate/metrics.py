"""Image metrics on the same display image: RMSE, PSNR and mean FLIP.

Every metric compares ``display_clip(test)`` with ``display_clip(reference)``
(:func:`atlasgen.optics.display.display_clip`), the sRGB image a user looks at, so dark
and bright regions weigh as they are seen. A ``mask`` leaves pixels out (validation leaves
out every pixel that does not show the material: background black in both images would
count as exact), and the metrics say which fraction of the frame they cover (``coverage``).

The display clips: a pixel brighter than 1 after exposure shows as 1 in both images, so its
error is hidden. :func:`compare_images` counts those pixels of the reference
(``clipped_pixels``) and measures the PSNR again at the exposure that keeps the whole
compared reference below clipping (``unclipped_psnr``, :func:`unclipped_exposure`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from atlasgen.optics.display import display_clip

__all__ = ["rmse", "psnr", "relative_rms", "flip", "flip_heatmap", "ImageMetrics", "compare_images", "noise_floor",
           "NOISE_FLOOR_MARGIN_DB", "unclipped_exposure", "clipped_pixels", "region_metrics", "part_metrics", "finite_or_none",
           "not_measured_reason", "NO_PIXELS", "BLACK_REFERENCE"]  # fmt: skip

#: Why a comparison measures nothing (:attr:`ImageMetrics.not_measured`).
NO_PIXELS = "no pixel of the material is compared"
BLACK_REFERENCE = "the reference is black on every compared pixel, unlit or of albedo 0"

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
    #: Fraction of the frame's pixels the figures cover (1 without a mask).
    coverage: float = 1.0
    #: Compared pixels whose reference clips on display (a channel of exposure * L above 1): their error is hidden.
    clipped_pixels: int = 0
    #: The exposure that keeps the compared reference below clipping (:func:`unclipped_exposure`) and the PSNR there.
    unclipped_exposure: float = math.nan
    unclipped_psnr: float = math.nan
    #: Figures over parts of the compared pixels (:func:`region_metrics`), e.g. grazing N.V and the rest.
    regions: dict = field(default_factory=dict)
    #: The PSNR over the whole frame (the background counted), for comparison with earlier figures; None if not measured.
    whole_frame_psnr: float | None = None
    #: Figures over each object showing the material (:func:`part_metrics`), where the comparison splits them.
    parts: dict = field(default_factory=dict)
    #: Why the comparison measures nothing of the material, where it does not (:func:`not_measured_reason`): no
    #: pixel compared, or a reference black on every compared pixel. No goal is met on it: a verdict on it is
    #: "not measured", or a miss where the figures show the atlas differs from the black reference all the same.
    not_measured: str | None = None

    def as_dict(self) -> dict:
        out = {
            # Every figure is a mean over the compared pixels: None, not NaN, where there are none (a frame
            # too small to show the material), which JSON can hold and the pages print as n/a.
            "rmse": finite_or_none(self.rmse),
            "psnr_db": finite_or_none(self.psnr),
            "flip": finite_or_none(self.flip),
            "linear_rmse": finite_or_none(self.linear_rmse),
            "linear_relative_rms": finite_or_none(self.linear_relative_rms),
            "coverage": self.coverage,
            "clipped_pixels": self.clipped_pixels,
            "unclipped_exposure": finite_or_none(self.unclipped_exposure),
            "unclipped_psnr_db": finite_or_none(self.unclipped_psnr),
        }
        if self.regions:
            out["regions"] = self.regions
        if self.whole_frame_psnr is not None:
            out["whole_frame_psnr_db"] = finite_or_none(self.whole_frame_psnr)
        if self.parts:
            out["parts"] = self.parts
        if self.not_measured is not None:
            out["not_measured"] = self.not_measured
        return out


def finite_or_none(x):
    """``x`` where it is a finite number, else ``None``: JSON's null, where a figure of nothing (a mean over no
    pixels) or a perfect match (PSNR of identical images) has no finite value.

    >>> finite_or_none(31.5), finite_or_none(float("inf")), finite_or_none(float("nan")), finite_or_none(None)
    (31.5, None, None, None)
    """
    return x if x is not None and math.isfinite(x) else None


def clipped_pixels(reference, exposure: float = 1.0) -> int:
    """Pixels of ``reference`` ``(n, 3)`` or ``(h, w, 3)`` with a channel above 1 after ``exposure``: the
    display shows them as 1 whatever their value, so a test image brighter still looks exact there.

    >>> clipped_pixels(np.array([[0.5, 0.5, 0.5], [0.2, 1.5, 0.1]]), exposure=1.0)
    1
    """
    x = np.asarray(reference, dtype=np.float64).reshape(-1, 3) * float(exposure)
    return int(np.count_nonzero(np.nan_to_num(x, nan=0.0).max(axis=1) > 1.0))


def unclipped_exposure(reference, exposure: float = 1.0) -> float:
    """The exposure e' = e min(1, 1 / max(e L)) over the pixels given: the scene's exposure ``e``
    where nothing of ``reference`` clips, else the one at which its brightest channel reaches 1.

    >>> unclipped_exposure(np.array([[0.5, 4.0, 0.1]]), exposure=0.2)
    0.2
    >>> unclipped_exposure(np.array([[0.5, 4.0, 0.1]]), exposure=1.0)
    0.25
    """
    x = np.nan_to_num(np.asarray(reference, dtype=np.float64) * float(exposure), nan=0.0, posinf=0.0)
    peak = float(x.max()) if x.size else 0.0
    return float(exposure) if peak <= 1.0 else float(exposure) / peak


def region_metrics(ref_ldr, test_ldr, error_map, regions: dict, frame_pixels: int) -> dict:
    """``{name: {"coverage", "pixels", "psnr_db", "flip"}}`` over each region's pixels (``(h, w)`` bool, True =
    in the region) of two display images and FLIP's map; ``psnr_db`` and ``flip`` are None for an empty region."""
    out = {}
    for name, region in regions.items():
        region = np.asarray(region, dtype=bool)
        n = int(region.sum())
        p = psnr(ref_ldr[region], test_ldr[region]) if n else math.nan
        f = float(error_map[region].mean()) if n and error_map is not None else math.nan
        out[name] = {"coverage": n / frame_pixels if frame_pixels else 0.0, "pixels": n, "psnr_db": finite_or_none(p),
                     "flip": finite_or_none(f)}  # fmt: skip
    return out


def part_metrics(reference, test, ref_ldr, test_ldr, error_map, parts: dict, exposure: float, frame_pixels: int) -> dict:
    """:func:`region_metrics` over each part (``(h, w)`` bool, True = in the part: e.g. the pixels of one
    object), with the reference's ``clipped_pixels`` there and ``unclipped_psnr_db``, the PSNR at the
    exposure that clips none of the part's reference (:func:`unclipped_exposure`): each part is judged
    as the whole comparison is."""
    out = region_metrics(ref_ldr, test_ldr, error_map, parts, frame_pixels)
    for name, part in parts.items():
        part = np.asarray(part, dtype=bool)
        r, t = np.asarray(reference)[part], np.asarray(test)[part]
        e = unclipped_exposure(r, exposure)
        unclipped = psnr(display_clip(r, e), display_clip(t, e)) if r.size else math.nan
        out[name].update(clipped_pixels=clipped_pixels(r, exposure), unclipped_psnr_db=finite_or_none(unclipped))
    return out


def compare_images(reference, test, exposure: float = 1.0, with_flip: bool = True, mask=None, regions=None,
                   parts=None) -> ImageMetrics:  # fmt: skip
    """RMSE and PSNR of the display images (:func:`display_clip`), mean FLIP and its map; linear RMSE and relative RMS;
    the coverage, the reference's clipped pixels and the PSNR at the exposure that clips none of it.

    ``mask`` (``(h, w)`` bool, True = excluded) leaves pixels out of every figure: FLIP is
    computed on the whole image (it looks at neighbourhoods) and averaged over the kept
    pixels only; the map stays whole. ``regions`` (``{name: (h, w) bool}``, True = in the
    region) adds figures over each region's kept pixels (:func:`region_metrics`), ``parts`` (the same
    form) figures over each part's kept pixels with their clipping (:func:`part_metrics`).
    """
    keep_mask = np.ones(np.shape(reference)[:2], dtype=bool) if mask is None else ~np.asarray(mask, dtype=bool)
    keep = (keep_mask,)
    ref_ldr = display_clip(reference, exposure)
    test_ldr = display_clip(test, exposure)
    error_map, mean = flip(ref_ldr, test_ldr) if with_flip else (None, math.nan)
    if error_map is not None and mask is not None:
        mean = float(error_map[keep].mean()) if np.any(keep[0]) else math.nan
    region_figures = {}
    if regions:
        region_figures = region_metrics(ref_ldr, test_ldr, error_map, {k: np.asarray(r, dtype=bool) & keep_mask
                                                                       for k, r in regions.items()}, keep_mask.size)  # fmt: skip
    part_figures = {}
    if parts:
        part_figures = part_metrics(reference, test, ref_ldr, test_ldr, error_map,
                                    {k: np.asarray(r, dtype=bool) & keep_mask for k, r in parts.items()}, exposure,
                                    keep_mask.size)  # fmt: skip
    reference, test = np.asarray(reference)[keep], np.asarray(test)[keep]
    e = unclipped_exposure(reference, exposure)
    unclipped = psnr(display_clip(reference, e), display_clip(test, e)) if reference.size else math.nan
    why = not_measured_reason(reference)
    if why is not None:  # the means of nothing are NaN, and so is an error relative to a black reference
        with np.errstate(invalid="ignore"):
            figures = (math.nan,) * 4 if not reference.size else (rmse(ref_ldr[keep], test_ldr[keep]),
                                                                 psnr(ref_ldr[keep], test_ldr[keep]), mean, rmse(reference, test))  # fmt: skip
        return ImageMetrics(*figures, math.nan, error_map, coverage=float(keep_mask.mean()) if keep_mask.size else 0.0,
                            clipped_pixels=0, unclipped_exposure=e, unclipped_psnr=unclipped, regions=region_figures,
                            parts=part_figures, not_measured=why)  # fmt: skip
    return ImageMetrics(rmse(ref_ldr[keep], test_ldr[keep]), psnr(ref_ldr[keep], test_ldr[keep]), mean,
                        rmse(reference, test), relative_rms(reference, test), error_map,
                        coverage=float(keep_mask.mean()) if keep_mask.size else 0.0,
                        clipped_pixels=clipped_pixels(reference, exposure), unclipped_exposure=e,
                        unclipped_psnr=unclipped, regions=region_figures, parts=part_figures)  # fmt: skip


def not_measured_reason(reference) -> str | None:
    """Why a comparison against ``reference`` (its compared pixels, ``(n, 3)``) measures nothing of the material,
    or ``None``: no pixel (:data:`NO_PIXELS`), or none that is not black (:data:`BLACK_REFERENCE`), where an atlas
    image that is black too would match it perfectly whatever its slices hold.

    >>> not_measured_reason(np.zeros((0, 3))) == NO_PIXELS, not_measured_reason(np.zeros((4, 3))) == BLACK_REFERENCE
    (True, True)
    >>> not_measured_reason(np.array([[0.0, 0.0, 0.0], [0.0, 0.2, 0.0]])) is None
    True
    """
    x = np.asarray(reference)
    if not x.size:
        return NO_PIXELS
    return BLACK_REFERENCE if not np.any(np.nan_to_num(x, nan=0.0) != 0.0) else None


def noise_floor(render_a, render_b, exposure: float = 1.0, mask=None) -> float:
    """A stochastic reference's noise floor: the PSNR in dB between two renders with different seeds.

    Compared as :func:`compare_images` compares (display images, ``mask`` excluded). The two
    renders differ by twice one render's noise variance, so one render lies about 3 dB
    closer to the converged image than this figure; an error measured against the reference
    is noise-limited where it comes within :data:`NOISE_FLOOR_MARGIN_DB` of it.
    """
    keep = (slice(None),) if mask is None else (~np.asarray(mask, dtype=bool),)
    return psnr(display_clip(render_a, exposure)[keep], display_clip(render_b, exposure)[keep])
