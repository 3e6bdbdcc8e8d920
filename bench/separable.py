"""Benchmark section: separable BRDFs (issue 3) against their goals, measured here.

Goals: GGX with Schlick F0 = 0.04 at alpha in {0.05, 0.1, 0.2, 0.5}: relative RMS of
f cos at most 5% with K = 2 and at most 2% with K = 4 in float, the 8-bit atlas adding
at most 1 percentage point; sampling + SVD + quantization of one material at most 0.2 s.
"""

from __future__ import annotations

import statistics
import time

ALPHAS = (0.05, 0.1, 0.2, 0.5)
GOALS = {2: 0.05, 4: 0.02}
EIGHT_BIT_GOAL = 0.01
TIME_GOAL_S = 0.2
REPEATS = 9


def _bake_factors(alpha: float, terms: int, tmp):
    """The separable factors (:class:`atlasgen.io.manifest.SeparableFactors`) of one material
    baked by the real pipeline (sRGB atlas)."""
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_material

    path = tmp / f"ggx-{int(alpha * 1000)}-{terms}.toml"
    path.write_text(
        f'type = "separable"\nsource = "ggx"\nalpha = {alpha}\nfresnel = "schlick"\nf0 = [0.04, 0.04, 0.04]\nterms = {terms}\n'
    )
    return bake_atlas([read_material(path)]).manifest.materials[0].factors


def _stage_times(alpha: float, terms: int = 4, grids=None) -> list[dict]:
    """Sampling, SVD and quantization of one material, REPEATS times, on one grid or the bake's grids."""
    from atlasgen.separable.approximate import approximate_brdf
    from atlasgen.separable.source import make_source
    from atlasgen.separable.storage import encode_factor_slices, factors_to_slices

    params = dict(
        source="ggx",
        alpha=alpha,
        fresnel="schlick",
        f0=(0.04,) * 3,
        ior=1.5,
        specular=(1.0,) * 3,
        diffuse=(0.0,) * 3,
        exponent=100.0,
    )
    out = []
    approximate_brdf(make_source(params), terms=terms, grids=grids)  # warm-up: caches of grid and weights
    for _ in range(REPEATS):
        result = approximate_brdf(make_source(params), terms=terms, grids=grids)
        t0 = time.perf_counter()
        encode_factor_slices(factors_to_slices(result.factors))
        t = dict(result.timings, quantize_s=time.perf_counter() - t0)
        t["factorize_s"] = t["sample_s"] + t["svd_s"] + t["quantize_s"]
        out.append(t)
    return out


def run() -> dict:
    import tempfile
    from pathlib import Path

    rows, data = (
        [],
        {"alphas": {}, "goals": {"relative_rms": GOALS, "eight_bit_extra": EIGHT_BIT_GOAL, "factorize_s": TIME_GOAL_S}},
    )
    met_all = True
    with tempfile.TemporaryDirectory() as tmp:
        for alpha in ALPHAS:
            data["alphas"][alpha] = {}
            for terms, goal in GOALS.items():
                f = _bake_factors(alpha, terms, Path(tmp))
                flt = f.errors.float_error.relative_rms
                bit = f.errors_8bit.relative_rms
                ok = flt <= goal and bit - flt <= EIGHT_BIT_GOAL
                met_all &= ok
                data["alphas"][alpha][terms] = {
                    "float": flt,
                    "8bit": bit,
                    "target": f.target,
                    "log_error_float": f.errors.float_error.log_error,
                    "met": ok,
                }
                rows.append(
                    f"| {alpha} | {terms} | {100 * flt:.2f}% | <= {100 * goal:.0f}% | {100 * bit:.2f}% | "
                    f"{100 * (bit - flt):+.2f} pp | {f.target} | {'yes' if ok else '**no**'} |"
                )
    stages = _stage_times(0.2)
    med = {k: statistics.median(s[k] for s in stages) for k in ("sample_s", "svd_s", "quantize_s", "factorize_s", "error_s")}
    data["timing"] = {
        "material": "ggx alpha 0.2, K = 4, target auto",
        "repeats": REPEATS,
        "median": med,
        "min_factorize_s": min(s["factorize_s"] for s in stages),
        "max_factorize_s": max(s["factorize_s"] for s in stages),
    }
    time_ok = med["factorize_s"] <= TIME_GOAL_S
    from atlasgen.separable.approximate import GRID_RESOLUTIONS

    chosen = _stage_times(0.2, grids=GRID_RESOLUTIONS)
    med_grids = {k: statistics.median(s[k] for s in chosen) for k in ("factorize_s", "error_s")}
    data["timing_grid_choice"] = {
        "grids": list(GRID_RESOLUTIONS),
        "median": med_grids,
        "ratio_to_one_grid": {k: med_grids[k] / med[k] for k in med_grids},
    }
    lines = [
        "## Separable BRDFs (Kautz-McCool SVD)",
        "",
        "GGX with Schlick F0 = 0.04, half/difference parametrization, 32x32 texels per factor, sRGB atlas. Errors: relative",
        "RMS of f cos(theta_l) as the manifest reports it: importance-sampled around the reflection lobe (the defensive",
        "GGX mixture of docs/separable.md, on a sample independent of the one that chose K), for the float factors and",
        "for the 8-bit atlas read back as a GPU samples it. Each row is a real `bake_atlas` of that material.",
        "",
        "| alpha | K | float | goal (float) | 8-bit | 8-bit extra (goal <= +1 pp) | target | met |",
        "|---|---|---|---|---|---|---|---|",
        *rows,
        "",
        f"Time for one material (GGX alpha 0.2, K = 4), median of {REPEATS} runs after a warm-up: sampling "
        f"{1e3 * med['sample_s']:.1f} ms + SVD {1e3 * med['svd_s']:.1f} ms + quantization {1e3 * med['quantize_s']:.1f} ms = "
        f"**{1e3 * med['factorize_s']:.1f} ms** (min {1e3 * data['timing']['min_factorize_s']:.1f}, max "
        f"{1e3 * data['timing']['max_factorize_s']:.1f}); goal <= {1e3 * TIME_GOAL_S:.0f} ms: "
        f"{'**yes**' if time_ok else '**no**'}. Measuring the error of every K and target (not part of the goal) took "
        f"{1e3 * med['error_s']:.0f} ms more. That is one 32-texel grid; a bake with an error budget may try "
        f"the grids {', '.join(map(str, GRID_RESOLUTIONS))} (here all of them): sampling + SVD + quantization "
        f"{1e3 * med_grids['factorize_s']:.1f} ms ({med_grids['factorize_s'] / med['factorize_s']:.1f}x one grid), "
        f"error measurement {1e3 * med_grids['error_s']:.0f} ms ({med_grids['error_s'] / med['error_s']:.1f}x), "
        f"medians of {REPEATS} runs in the same process.",
        "",
        f"All error goals met: {'**yes**' if met_all else '**no**'}.",
        "",
    ]
    data["all_error_goals_met"] = met_all
    data["time_goal_met"] = time_ok
    return {"markdown": "\n".join(lines), "data": data}


if __name__ == "__main__":
    print(run()["markdown"])
