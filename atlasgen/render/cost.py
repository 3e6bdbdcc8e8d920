"""Run-time cost of a material: the lighting pass's time per pixel per light, measured in the renderer.

The material covers the whole frame (a camera looking down onto a large plane), ``lights``
point lights shine on it, and only the opaque lighting pass is timed, submitted and waited
for, after ``warmup`` runs (shader compilation and first-touch costs excluded). The figure
is the median over ``repeats`` runs divided by pixels x lights, in nanoseconds, on the
device named with it. A representation's shader decides the cost, not its data: a LUT
slice costs the same point-sampled or supersampled.
"""

from __future__ import annotations

import math
import statistics
import time
import tomllib
from dataclasses import dataclass

import numpy as np

from atlasgen.errors import BackendError
from atlasgen.materials.scene import parse_scene

__all__ = ["LightingCost", "measure_lighting_cost", "time_runs", "cost_per_pixel_per_light", "coverage_scene",
           "relative_costs"]  # fmt: skip


@dataclass(frozen=True)
class LightingCost:
    """One measurement: ``ns_per_pixel_per_light`` = median seconds * 1e9 / (pixels * lights)."""

    material: str
    device: str
    ns_per_pixel_per_light: float
    median_s: float
    runs_s: tuple
    pixels: int
    lights: int

    def to_json(self) -> dict:
        return {"material": self.material, "device": self.device, "ns_per_pixel_per_light": self.ns_per_pixel_per_light,
                "median_s": self.median_s, "runs_s": list(self.runs_s), "pixels": self.pixels, "lights": self.lights}  # fmt: skip


def time_runs(fn, repeats: int, warmup: int = 1, timer=time.perf_counter) -> list[float]:
    """Seconds of each of ``repeats`` calls of ``fn`` after ``warmup`` untimed calls, by ``timer``."""
    for _ in range(warmup):
        fn()
    out = []
    for _ in range(repeats):
        t0 = timer()
        fn()
        out.append(timer() - t0)
    return out


def cost_per_pixel_per_light(runs_s, pixels: int, lights: int) -> float:
    """Median of ``runs_s`` (seconds) in nanoseconds per pixel per light."""
    if pixels <= 0 or lights <= 0 or not runs_s:
        raise ValueError("expected runs, pixels > 0 and lights > 0")
    return statistics.median(runs_s) * 1e9 / (pixels * lights)


def coverage_scene(material: str, width: int = 256, height: int = 256, lights: int = 8):
    """A scene whose every pixel shows ``material``: a plane seen from above at 45 degrees
    (the view's rays span 25 to 65 degrees downwards), ``lights`` point lights on a ring above."""
    lines = ["[camera]", "position = [0, 2, 2]", "target = [0, 0, 0]", "fov = 40",
             "[image]", f"width = {width}", f"height = {height}",
             "[[objects]]", "shape = 'plane'", f"material = '{material}'", "scale = 100", "gloss = 0.6"]  # fmt: skip
    for i in range(lights):
        a = 2 * math.pi * i / lights
        lines += ["[[lights]]", "type = 'point'", f"position = [{2 * math.cos(a):.4f}, 1.5, {2 * math.sin(a):.4f}]",
                  f"intensity = {8.0 / lights:.6f}"]  # fmt: skip
    return parse_scene(tomllib.loads("\n".join(lines)), "cost-scene")


def measure_lighting_cost(renderer, material: str, width: int = 256, height: int = 256, lights: int = 8,
                          repeats: int = 9, warmup: int = 2, timer=time.perf_counter) -> LightingCost:  # fmt: skip
    """The lighting pass's cost for ``material`` of ``renderer``'s atlas (:class:`~atlasgen.render.renderer.Renderer`).

    Every pixel is covered (checked on the g-buffer's IDs), so the figure is the shader's own
    per-pixel, per-light cost on ``renderer``'s device plus the pass's fixed cost shared out.
    Compare figures from one run only: a loaded CPU slows a software rasteriser.
    """

    scene = coverage_scene(material, width, height, lights)
    frame = renderer.prepare(scene)
    renderer.submit(renderer.encode_frame(frame, outlines=False))
    ids = renderer.read_aovs(frame)["id"]
    slot = renderer.atlas.manifest.entry_named(material).first_slice
    if not np.all(ids == slot):
        raise BackendError(f"cost scene: material {material!r} covers {np.mean(ids == slot):.1%} of the frame, not all")
    runs = time_runs(lambda: renderer.submit([renderer.encode_lighting(frame)]), repeats, warmup, timer)
    pixels = width * height
    return LightingCost(material, renderer.ctx.name, cost_per_pixel_per_light(runs, pixels, lights),
                        statistics.median(runs), tuple(runs), pixels, lights)  # fmt: skip


def relative_costs(costs: dict, baseline: str) -> dict:
    """Each ``costs[key]`` (ns per pixel per light) divided by ``costs[baseline]`` from the same run."""
    base = costs[baseline]
    return {key: value / base for key, value in costs.items()}
