"""Benchmark: how far the renderer's environment lighting is from the integral it stands for, per material.

Two parts (issue 20, item 2):

* **CPU breakdown, every shipped material.** ``materials/*.toml`` baked from the repository's bake cache
  (``build/cache``, filled by ``make atlas``), each bound to the ``env-sky`` and ``env-uniform`` validation
  spheres; the g-buffer AOVs from the renderer, then :func:`atlasgen.validate.environment.environment_parts`
  and :func:`~atlasgen.validate.environment.break_down_environment` (SH band limit, split sum, total) on the
  material's pixels. No Mitsuba.
* **Against Mitsuba, the materials with goals.** ``terracotta`` (lambert), ``red-plastic`` and
  ``glazed-ceramic`` (fresnel fits) and ``skin`` (sss, the environment map only) through
  :func:`atlasgen.validate.run.validate_atlas` on ``build/atlas.dds`` (the validation code path: the
  references BSDF- and emitter-sampled on shifted Halton points, two shifts, the noise-floor rule, spp
  capped at :data:`SPP_CAP`). A goal is judged only where the reference's noise floor is
  ``NOISE_FLOOR_MARGIN_DB`` (10 dB) above the PSNR it measures.

Run alone: ``python bench/run.py environment_error``.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCENES = ("env-sky", "env-uniform")
#: The materials issue 20 sets goals for: lambert and the fresnel fits (both scenes), sss (the environment map).
GOAL_MATERIALS = ("terracotta", "red-plastic", "glazed-ceramic", "skin")
#: Which (scene, material) pairs have a goal: the uniform one is the usual model-reference goal.
UNIFORM_GOAL_MATERIALS = ("terracotta", "red-plastic", "glazed-ceramic")
#: Most samples per pixel per seed of a Mitsuba reference here (the validation's own cap is 4096): keeps each
#: reference near a minute on 2 cores. Figures that stop at this cap are labelled with their floor.
SPP_CAP = 1024
#: The CPU breakdown's image size: its texel-sum integral costs ~70 s per material at the scenes' 64x64 on 2 cores,
#: so it is taken on the same sphere at 20x20 (the same geometry, fewer pixels).
CPU_RESOLUTION = (20, 20)


def _db(x) -> str:
    return "inf" if x is None or not math.isfinite(x) else f"{x:.1f}"


def _cpu_breakdown() -> tuple[list[dict], str, float]:
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_materials
    from atlasgen.materials.scene import with_fitted_surfaces
    from atlasgen.models import get_model
    from atlasgen.render.atlas_texture import RenderAtlas
    from atlasgen.render.renderer import Renderer
    from atlasgen.validate.environment import break_down_environment, environment_parts, separable_environment_parts
    from atlasgen.validate.scenes import bind_material, load_validation_scene, resize_scene

    t0 = time.perf_counter()
    files = sorted([*(ROOT / "materials").glob("*.toml"), *(ROOT / "materials").glob("*.mtlx")])
    result = bake_atlas(read_materials(files), cache_dir=ROOT / "build" / "cache")
    atlas = RenderAtlas(result.levels, result.dxgi_format == 29, result.manifest, result.include, "bench bake")
    renderer = Renderer(atlas)
    device = renderer.ctx.name
    scenes = [(n, resize_scene(s, *CPU_RESOLUTION)) for n, s in (load_validation_scene(name) for name in SCENES)]
    rows = []
    for entry in atlas.manifest.materials:
        for scene_name, scene in scenes:
            bound = with_fitted_surfaces(bind_material(scene, entry.name), {e.name: e for e in atlas.manifest.materials})
            row = {"material": entry.name, "type": entry.type, "scene": scene_name}
            aovs = renderer.render(bound, outlines=False, aovs=True).aovs
            data = renderer.environment.data(bound.environment)
            t = time.perf_counter()
            if get_model(entry.type).custom_lighting:
                parts = separable_environment_parts(atlas.levels, atlas.srgb, entry, bound, aovs, data)
                if parts is None:
                    row["note"] = f"{entry.representation or 'not factored'}: the renderer gives it no environment light"
                    rows.append(row)
                    continue
                row["split_sum_only"] = True
            else:
                parts = environment_parts(atlas.levels, atlas.srgb, entry, bound, aovs, data)
            row.update(break_down_environment(parts, bound.settings.exposure))
            row["seconds"] = time.perf_counter() - t
            rows.append(row)
            print(f"bench environment_error: {entry.name} / {scene_name}: total {_db(row['total']['psnr_db'])} dB "
                  f"({row['seconds']:.1f} s)", file=sys.stderr, flush=True)  # fmt: skip
    return rows, device, time.perf_counter() - t0


def _mitsuba() -> tuple[list[dict], float]:
    import atlasgen.validate.run as validation

    atlas = ROOT / "build" / "atlas.dds"
    if not atlas.exists():
        raise FileNotFoundError(f"{atlas.as_posix()}: run `make atlas` first")
    t0 = time.perf_counter()
    cap, validation.MAX_ENVIRONMENT_SPP = validation.MAX_ENVIRONMENT_SPP, SPP_CAP
    try:
        out = validation.validate_atlas(atlas, materials=list(GOAL_MATERIALS), scenes=SCENES,
                                        progress=lambda s: print("bench environment_error:", s, file=sys.stderr, flush=True))  # fmt: skip
    finally:
        validation.MAX_ENVIRONMENT_SPP = cap
    rows = []
    for run in out.runs:
        ref = run.references["model"]
        goal = validation.GOAL_ENVIRONMENT_PSNR_DB if run.scene == "env-sky" else validation.GOAL_PSNR_DB
        if run.scene != "env-sky" and run.material not in UNIFORM_GOAL_MATERIALS:
            goal = None
        psnr, floor = ref.metrics.psnr, ref.noise_floor_db
        converged = floor is not None and floor >= psnr + validation.NOISE_FLOOR_MARGIN_DB
        rows.append({"material": run.material, "scene": run.scene, "psnr_db": psnr, "noise_floor_db": floor, "spp": ref.spp,
                     "capped": ref.spp >= SPP_CAP and not converged, "converged": converged, "goal_db": goal,
                     "seconds": ref.seconds, "description": ref.description})  # fmt: skip
    return rows, time.perf_counter() - t0


def judge(row: dict) -> bool | None:
    """Whether a Mitsuba row meets its goal; None where it has none or cannot say.

    A miss is judged only where the reference's noise floor is far enough above the error it
    measures; a pass always, as the reference's noise only lowers the PSNR measured against it
    (:func:`atlasgen.reports.validation.look_verdict`).
    """
    goal, psnr = row["goal_db"], row["psnr_db"]
    if goal is None or not (row["converged"] or psnr >= goal):
        return None
    return bool(psnr >= goal)


def run() -> dict:
    """Both parts; with ``ATLASGEN_BENCH_ENV_PARTS=cpu`` the CPU breakdown alone, the Mitsuba table kept
    from BENCHMARKS.json and said to be (its references take half an hour; the breakdown two minutes)."""
    cpu_rows, device, cpu_s = _cpu_breakdown()
    data = {"device": device, "cpu_seconds": cpu_s, "cpu_breakdown": cpu_rows, "spp_cap": SPP_CAP}
    if os.environ.get("ATLASGEN_BENCH_ENV_PARTS", "cpu,mitsuba").split(",") == ["cpu"]:
        previous = json.loads((ROOT / "BENCHMARKS.json").read_text())["environment_error"]
        data.update(mitsuba=previous["mitsuba"], mitsuba_seconds=previous["mitsuba_seconds"], spp_cap=previous["spp_cap"],
                    mitsuba_from=previous.get("mitsuba_from") or "the previous run (BENCHMARKS.json), not re-measured")  # fmt: skip
    else:
        data["mitsuba"], data["mitsuba_seconds"] = _mitsuba()
    return {"markdown": markdown(data), "data": data}


def markdown(data: dict) -> str:
    """The section's text from its measured data (``bench/run.py --rewrite`` re-renders it from BENCHMARKS.json)."""
    cpu_rows, device, cpu_s = data["cpu_breakdown"], data["device"], data["cpu_seconds"]
    mi_rows, mi_s, spp_cap = data["mitsuba"], data["mitsuba_seconds"], data["spp_cap"]
    md = [
        "## Environment lighting: error per material",
        "",
        f"Every shipped material (`materials/*.toml`, baked from `build/cache`) on the `env-sky` and `env-uniform` "
        f"validation spheres, at {CPU_RESOLUTION[0]}x{CPU_RESOLUTION[1]} (the texel sum costs ~70 s a material at 64x64), g-buffer from the renderer ({device}); the error of the renderer's two "
        f"approximations against the texel-sum integral of the same decoded slice, computed on the CPU "
        f"(`atlasgen.validate.environment`), on the material's pixels. PSNR on display values (peak 1); "
        f"rel. RMS is linear. A separable material (its f cos is 4D) has the split sum with its own directional "
        f"albedo alone, Lpre(r, alpha) S_sep(N.V), against the texel-sum integral of its rebuilt f cos "
        f"(`separable_environment_parts`): no SH part ('-'). {cpu_s:.0f} s for the whole library, bake included.",
        "",
        "| material | scene | SH band limit (dB) | split sum (dB) | total (dB) | SH rel. RMS | split sum rel. RMS "
        "| total rel. RMS | pixels |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in cpu_rows:
        if "note" in r:
            md.append(f"| {r['material']} | {r['scene']} | - | - | - | - | - | - | {r['note']} |")
            continue
        sh, ss, tot = r["sh_band_limit"], r["split_sum"], r["total"]
        sh_db, sh_rms = (_db(sh["psnr_db"]), f"{sh['linear_relative_rms']:.2e}") if not r.get("split_sum_only") else ("-", "-")
        md.append(f"| {r['material']} | {r['scene']} | {sh_db} | {_db(ss['psnr_db'])} | {_db(tot['psnr_db'])} "
                  f"| {sh_rms} | {ss['linear_relative_rms']:.2e} | {tot['linear_relative_rms']:.2e} "
                  f"| {r['pixels']} |")  # fmt: skip
    md += [
        "",
        f"Against Mitsuba (the model reference lit by the environment alone: the BSDF, and for the sky the emitter "
        f"too, sampled on shifted Halton points, `atlasgen.validate.mitsuba_scene.render_environment_qmc`), through "
        f"`validate_atlas` on `build/atlas.dds`: two shifts from 64 spp each, grown by the noise-floor rule, capped "
        f"here at {spp_cap} spp per shift (the validation's cap is 4096). A miss is judged only where the noise floor "
        f"(the two shifts' PSNR) is 10 dB above the PSNR; a PSNR that meets its goal against a reference short of "
        f"its floor is met as a lower bound ('yes, bound'), since the reference's noise only adds error. "
        f"{mi_s:.0f} s in all" + (f"; these rows are {data['mitsuba_from']}." if data.get("mitsuba_from") else "."),
        "",
        "| material | scene | PSNR (dB) | goal (dB) | met | noise floor (dB) | spp per seed | converged | reference (s) |",
        "|---|---|---:|---:|---|---:|---:|---|---:|",
    ]
    for r in mi_rows:
        spp = f"{r['spp']} (capped)" if r["capped"] else str(r["spp"])
        goal = "-" if r["goal_db"] is None else f"{r['goal_db']:g}"
        verdict = judge(r)
        met = {True: "yes", False: "no", None: "-" if r["goal_db"] is None else "not judged"}[verdict]
        if verdict and not r["converged"]:
            met = "yes, bound"
        md.append(f"| {r['material']} | {r['scene']} | {_db(r['psnr_db'])} | {goal} | {met} "
                  f"| {_db(r['noise_floor_db'])} | {spp} | {'yes' if r['converged'] else 'no'} | {r['seconds']:.1f} |")  # fmt: skip
    conv = [f"{r['material']}/{r['scene']}" for r in mi_rows if r["converged"]]
    notconv = [f"{r['material']}/{r['scene']}" for r in mi_rows if not r["converged"]]
    md += [
        "",
        "Converged (noise floor at least 10 dB above the PSNR): " + (", ".join(conv) or "none") + ". "
        "Not converged (the PSNR is a lower bound set by the reference's noise): " + (", ".join(notconv) or "none") + ".",
        "",
    ]
    return "\n".join(md)


if __name__ == "__main__":
    print(run()["markdown"])
