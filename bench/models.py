"""Benchmark: one slice's ``model.bake()`` per LUT model, for the shipped library and each model's defaults."""

from __future__ import annotations

import statistics
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RUNS = 50


def _cases():
    from atlasgen.io.fields import validate_params
    from atlasgen.materials.material import read_materials
    from atlasgen.models import get_model, model_types

    # The table models: the renderer samples their slice (the others shade with their own code).
    lut_models = [t for t in model_types() if not get_model(t).custom_lighting]
    cases = [(m.name, m.type, m.model, m.params) for m in read_materials([ROOT / "materials"]) if m.type in lut_models]
    for type_name in lut_models:
        model = get_model(type_name)
        # A model whose defaults are no material (bsdf needs its Mitsuba BSDF table; its bake is a
        # Mitsuba fit, not a closed form) has no defaults case.
        if any(p.kind == "table" and p.default is None for p in model.params):
            continue
        cases.append((f"({type_name} defaults)", type_name, model, validate_params(model.params, {}, "defaults")))
    return cases


def run() -> dict:
    rows, data = [], {}
    for name, type_name, model, params in _cases():
        model.bake(params)  # first call fills the models' caches (quadrature rules, spectral grids)
        times = []
        for _ in range(RUNS):
            t0 = time.perf_counter()
            model.bake(params)
            times.append(time.perf_counter() - t0)
        med = statistics.median(times)
        data[name] = {"type": type_name, "median_s": med, "min_s": min(times), "max_s": max(times)}
        rows.append(f"| {name} | {type_name} | {med * 1e3:.2f} | {min(times) * 1e3:.2f} | {max(times) * 1e3:.2f} |")
    worst = max(v["median_s"] for v in data.values())
    md = [
        "## `model.bake()`: one 64x32 slice per LUT material, in process",
        "",
        f"Median of {RUNS} calls after one warm-up call; the shipped library, then each model with its defaults.",
        "",
        "| material | model | median (ms) | min (ms) | max (ms) |",
        "|---|---|---|---|---|",
        *rows,
        "",
        f"Slowest median: {worst * 1e3:.2f} ms, so 256 such slices take at most {256 * worst:.2f} s of model time.",
        "",
    ]
    return {"markdown": "\n".join(md), "data": {"runs": RUNS, "materials": data}}


if __name__ == "__main__":
    print(run()["markdown"])
