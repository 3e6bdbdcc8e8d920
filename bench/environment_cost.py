"""Benchmark: the lighting pass's cost with and without an environment (issue 20, item 7).

One scene, a floor and three spheres under one point light at 640x360, rendered twice: without an
environment, and with the procedural sky (``environment = "sky"``). The lighting pass alone is timed as
:mod:`bench.render` times it: wall time around ``submit`` of the pass's command buffer and the wait for
it (no GPU timestamps), median of :data:`REPEATS` after :data:`WARMUP` warm-up.

Run alone: ``python bench/run.py environment_cost``.
"""

from __future__ import annotations

import statistics
import time
import tomllib

WIDTH, HEIGHT = 640, 360
WARMUP, REPEATS = 2, 9


def _scene(material: str, environment: str | None):
    from atlasgen.materials.scene import parse_scene

    lines = ([f"environment = {environment}"] if environment else []) + [
        "[camera]", "position = [0, 2, 7]", "target = [0, 0, 0]", "fov = 45",
        "[image]", f"width = {WIDTH}", f"height = {HEIGHT}",
        "[[objects]]", "shape = 'plane'", f"material = '{material}'", "translate = [0, -1, 0]", "scale = 8",
        "[[lights]]", "type = 'point'", "position = [2, 4, 3]", "intensity = 30",
    ]  # fmt: skip
    for x in (-2.2, 0.0, 2.2):
        lines += ["[[objects]]", "shape = 'sphere'", f"material = '{material}'", f"translate = [{x}, 0, 0]", "gloss = 0.6"]
    return parse_scene(tomllib.loads("\n".join(lines)), "bench-environment-cost")


def _time_ms(fn) -> list[float]:
    for _ in range(WARMUP):
        fn()
    times = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1000.0)
    return times


def run() -> dict:
    import os

    from render import load_atlas

    from atlasgen.render.renderer import Renderer

    atlas, source = load_atlas()
    renderer = Renderer(atlas)
    device = renderer.ctx.name
    material = next(m.name for m in atlas.manifest.materials if m.factors is None)
    rows = {}
    for label, env in (("none", None), ("sky", '"sky"'), ("uniform", "[0.6, 0.7, 0.8]")):
        frame = renderer.prepare(_scene(material, env))
        times = _time_ms(lambda: renderer.submit([renderer.encode_lighting(frame)]))
        rows[label] = {"median_ms": statistics.median(times), "min_ms": min(times), "max_ms": max(times), "times_ms": times}
    errors = renderer.ctx.take_errors()
    base = rows["none"]["median_ms"]
    md = [
        "## Environment lighting: cost of the lighting pass",
        "",
        f"{WIDTH}x{HEIGHT}, a floor and three spheres of `{material}` under one point light, with and without an "
        f"environment. The lighting pass alone, wall time around submit and wait (as `bench/render.py`; no GPU "
        f"timestamps), median of {REPEATS} after {WARMUP} warm-up. Atlas: {source}. Device: {device}; load average "
        f"{os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs.",
        "",
        "| environment | median (ms) | fastest (ms) | slowest (ms) | median / none |",
        "|---|---:|---:|---:|---:|",
    ]
    md += [f"| {k} | {r['median_ms']:.2f} | {r['min_ms']:.2f} | {r['max_ms']:.2f} | {r['median_ms'] / base:.2f} |"
           for k, r in rows.items()]  # fmt: skip
    md += ["", f"Device validation errors during the benchmark: {len(errors)}.", ""]
    data = {"device": device, "width": WIDTH, "height": HEIGHT, "warmup": WARMUP, "repeats": REPEATS, "atlas": source,
            "material": material, "rows": rows, "ratio_sky": rows["sky"]["median_ms"] / base,
            "ratio_uniform": rows["uniform"]["median_ms"] / base, "validation_errors": errors}  # fmt: skip
    return {"markdown": "\n".join(md), "data": data}


if __name__ == "__main__":
    print(run()["markdown"])
