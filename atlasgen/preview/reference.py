"""``atlasgen preview --reference``: the material's Mitsuba physical reference of the preview scene itself.

The reference is validation's (:func:`atlasgen.validate.run.render_physical`): the same scene
(camera, lights, the procedural sky), the material's ``physical_reference`` on its objects, the
floor its own model reference (a diffuse BSDF), rendered at the preview's resolution through
the pixel centres. It is always rendered stochastically, with seeds 0 and 1, because the
environment is integrated by sampling even where the material's own reference is
deterministic; the PSNR between the seeds is its noise floor
(:func:`atlasgen.validate.metrics.noise_floor`). The atlas picture's error is the PSNR against
the mean of the seeds on the material's pixels only (the g-buffer's material-ID AOV,
:func:`atlasgen.validate.rebuild.material_mask`), as validation measures.

The samples double from :data:`START_SPP` (each pass continues the last: none is rendered
twice) until the floor lies :data:`~atlasgen.validate.metrics.NOISE_FLOOR_MARGIN_DB` above the
error or :data:`MAX_SPP` is reached; :func:`refine_reference` yields after every pass, so that
a watch can show each one.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np

from atlasgen.io.manifest import MaterialEntry
from atlasgen.materials.scene import Scene, with_fitted_surfaces
from atlasgen.validate.backend import load_mitsuba
from atlasgen.validate.metrics import NOISE_FLOOR_MARGIN_DB
from atlasgen.validate.rebuild import material_mask
from atlasgen.validate.references import physical_reference
from atlasgen.validate.run import (
    add_physical_samples,
    mean_of_seeds,
    measure_physical,
    register_references_for_variant,
    render_physical,
)

__all__ = ["START_SPP", "MAX_SPP", "ReferenceShot", "load_reference_mitsuba", "refine_reference", "reference_lines"]

#: Samples per pixel (per seed) of the first pass: a picture within seconds.
START_SPP = 4
#: The most samples per pixel (per seed) a reference is refined to.
MAX_SPP = 256
#: Mitsuba renders one scene at a time: a refinement started by a new edit waits for the old one's pass.
MITSUBA_LOCK = threading.Lock()


@dataclass
class ReferenceShot:
    """The physical reference of one material at one stage of its refinement."""

    name: str
    #: ``(h, w, 3)`` linear radiance, the mean of the two seeds; None without a physical reference.
    image: np.ndarray | None
    description: str = ""
    spp: int = 0
    floor_db: float | None = None
    psnr_db: float | None = None
    seconds: float = 0.0
    #: Whether refinement is over (converged, at the cap, or nothing to render).
    final: bool = True

    @property
    def converged(self) -> bool:
        """Whether the floor clears the error by the margin (the error is not the reference's noise)."""
        if self.floor_db is None or self.psnr_db is None:
            return False
        return not math.isfinite(self.psnr_db) or self.floor_db >= self.psnr_db + NOISE_FLOOR_MARGIN_DB


def reference_lines(shot: ReferenceShot | None) -> list[str]:
    """The reference picture's label: its spp and noise floor, and the atlas picture's PSNR against it;
    ``shot`` None while the first pass renders.

    >>> reference_lines(ReferenceShot("clay", None))
    ['clay: no physical reference', 'no reference image']
    >>> reference_lines(ReferenceShot("clay", np.zeros((1, 1, 3)), "diffuse", 16, 41.25, 30.5, 2.0, False))[1:]
    ['16 spp, noise floor 41.2 dB (refining)', 'atlas vs reference: PSNR 30.5 dB on the material']
    """
    if shot is None:
        return ["physical reference", "reference: rendering"]
    if shot.image is None:
        return [f"{shot.name}: no physical reference", "no reference image"]
    state = "" if shot.final and shot.converged else (" (refining)" if not shot.final else " (at the cap)")
    floor = "n/a" if shot.floor_db is None else f"{shot.floor_db:.1f} dB"
    psnr = "n/a" if shot.psnr_db is None else ("inf" if not math.isfinite(shot.psnr_db) else f"{shot.psnr_db:.1f}")
    return [f"physical reference: {shot.description}", f"{shot.spp} spp, noise floor {floor}{state}",
            f"atlas vs reference: PSNR {psnr} dB on the material"]  # fmt: skip


def load_reference_mitsuba():
    """Mitsuba's ``llvm_ad_rgb`` variant with atlasgen's plugins registered (raises BackendError without it)."""
    mi = load_mitsuba("llvm_ad_rgb")
    register_references_for_variant(mi)
    return mi


def refine_reference(
    mi,
    scene: Scene,
    entry: MaterialEntry,
    manifest,
    atlas_image: np.ndarray,
    aovs: dict,
    start_spp: int = START_SPP,
    max_spp: int = MAX_SPP,
    stop: threading.Event | None = None,
) -> Iterator[ReferenceShot]:
    """Yield ``entry``'s physical reference of ``scene`` after each pass: ``start_spp`` samples per pixel
    and seed, then twice as many, until the floor is 10 dB above the atlas picture's error, ``max_spp``,
    or ``stop`` is set. A material without a physical reference yields one shot with no image.

    ``atlas_image`` and ``aovs`` are the atlas picture of ``scene`` and its g-buffer read-backs; the
    objects showing a fitted material are shaded as validation shades them
    (:func:`~atlasgen.materials.scene.with_fitted_surfaces`).
    """
    physical = physical_reference(entry)
    if physical is None:
        yield ReferenceShot(entry.name, None)
        return
    physical = replace(physical, stochastic=True)
    scene = with_fitted_surfaces(scene, {e.name: e for e in manifest.materials})
    not_material = ~material_mask(entry, aovs)
    exposure = scene.settings.exposure
    stop = stop or threading.Event()
    ref = None
    while not stop.is_set():
        with MITSUBA_LOCK:
            if stop.is_set():
                return
            if ref is None:
                ref = render_physical(mi, scene, entry, physical, manifest, start_spp, 1)
            else:
                add_physical_samples(mi, scene, entry, physical, manifest, ref, min(ref.spp, max_spp - ref.spp), 1)
        measure_physical(ref, atlas_image, exposure, not_material)
        shot = ReferenceShot(entry.name, mean_of_seeds(ref), physical.description, ref.spp, ref.noise_floor_db,
                             ref.metrics.psnr, ref.seconds)  # fmt: skip
        shot.final = shot.converged or ref.spp >= max_spp
        yield shot
        if shot.final:
            return
