"""Benchmark: what environment lighting computes on the CPU, per environment and per material."""

from __future__ import annotations

import statistics
import time

import numpy as np

RUNS = 7
#: The prefilter's goal for a 256x128 source (issue 20).
PREFILTER_GOAL_S = 1.0


def _time(fn, runs=RUNS):
    fn()  # warm-up: quadrature caches, FFT plans
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), min(times), max(times)


def run() -> dict:
    from atlasgen.contract import HEIGHT, WIDTH, texel_grid
    from atlasgen.optics.environment_tables import slice_sh_table, slice_specular_table
    from atlasgen.optics.prefilter import prefilter_ggx
    from atlasgen.optics.sky import sky_image
    from atlasgen.optics.spherical_harmonics import project_equirect

    nl, _ = texel_grid()
    slice_ = np.zeros((HEIGHT, WIDTH, 4))
    slice_[..., :3] = np.maximum(nl, 0.0)[..., None]
    slice_[..., 3] = 0.04 + 0.96 * (1.0 - np.abs(nl)) ** 5
    sky = {(h, 2 * h): sky_image(h, 2 * h) for h in (128, 512)}
    cases = [
        ("`prefilter_ggx`, 256x128 sky, 6 levels", lambda: prefilter_ggx(sky[(128, 256)]), RUNS),
        ("`prefilter_ggx`, 1024x512 sky, 6 levels", lambda: prefilter_ggx(sky[(512, 1024)]), 3),
        ("`project_equirect`, 256x128 sky, l <= 4", lambda: project_equirect(sky[(128, 256)]), RUNS),
        ("`sky_image`, 256x128", lambda: sky_image(128, 256), RUNS),
        ("`slice_sh_table`, one slice", lambda: slice_sh_table(slice_), RUNS),
        ("`slice_specular_table`, one slice, 16 glosses", lambda: slice_specular_table(slice_), RUNS),
    ]
    rows, data = [], {}
    for name, fn, runs in cases:
        med, lo, hi = _time(fn, runs)
        data[name] = {"median_s": med, "min_s": lo, "max_s": hi, "runs": runs}
        rows.append(f"| {name} | {med * 1e3:.1f} | {lo * 1e3:.1f} | {hi * 1e3:.1f} |")
    prefilter = data[cases[0][0]]["median_s"]
    md = [
        "## Environment lighting: CPU side, in process",
        "",
        f"Median of {RUNS} calls (3 for the 1024x512 prefilter) after one warm-up call, 2 cores.",
        "",
        "| what | median (ms) | min (ms) | max (ms) |",
        "|---|---|---|---|",
        *rows,
        "",
        f"Goal: the 256x128 prefilter in at most {PREFILTER_GOAL_S:g} s. Reached: **{'yes' if prefilter <= PREFILTER_GOAL_S else 'no'}** "
        f"({prefilter:.3f} s).",
        "",
    ]
    return {"markdown": "\n".join(md), "data": {"cases": data, "goal_s": PREFILTER_GOAL_S, "prefilter_s": prefilter}}


if __name__ == "__main__":
    print(run()["markdown"])
