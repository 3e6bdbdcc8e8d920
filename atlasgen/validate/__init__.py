"""``atlasgen validate``: baked materials against Mitsuba 3 reference renders.

One module per concept: :mod:`.backend` (loading Mitsuba's LLVM variant),
:mod:`.mitsuba_scene` (a renderer scene as a Mitsuba scene, and the direct-lighting
integrator without visibility), :mod:`.references` (each model's model and physical
reference, asked through its hooks), :mod:`.rebuild` (the atlas path recomputed on the
CPU with each model's rebuilds), :mod:`.metrics` (RMSE, PSNR, FLIP on the same tone-mapped
image), :mod:`.scenes` (the standard validation scenes) and :mod:`.run` (orchestration);
the report is :mod:`atlasgen.reports.validation`. Nothing here knows a model by name, and
nothing imports Mitsuba, wgpu or matplotlib at import time.
"""

from __future__ import annotations

__all__: list[str] = []
