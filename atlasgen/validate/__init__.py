"""``atlasgen validate``: baked materials against Mitsuba 3 reference renders.

One module per concept: :mod:`.backend` (loading Mitsuba's LLVM variant),
:mod:`.mitsuba_scene` (a renderer scene as a Mitsuba scene, and the direct-lighting
integrator without visibility), :mod:`.references` (model and physical reference
BSDFs), :mod:`.metrics` (RMSE, PSNR, FLIP on the same tone-mapped image),
:mod:`.scenes` (the standard validation scenes), :mod:`.report` (HTML, JSON, plot)
and :mod:`.run` (orchestration). Nothing here imports Mitsuba, wgpu or matplotlib at
import time.
"""

from __future__ import annotations

__all__: list[str] = []
