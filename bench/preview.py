"""Benchmark of ``atlasgen preview``: save-to-PNG latency in watch mode, and the whole process.

Watch mode: a material file in a fresh folder, watched by :func:`atlasgen.preview.watch.watch_preview`
with a fresh bake cache (so every save is a real bake); each save renames an edited copy over the
file, as vim and most IDEs save, and its latency runs from just before the rename to the moment the
watch reports the PNG in place. The figure is the median of ``SAVES`` saves after ``WARMUP``.
Each update's own timings say where the time went (read, bake, upload, render with any shader
compile, label, PNG encode, write); the rest of the latency is the watch noticing the save
(watchfiles waits ``STEP_MS`` for quiet). A picture drawn from a draft bake (a separable material:
its label's error figure still to measure) is followed by the full label; its latency is timed
from the same instant to the watch's ``on_label``, and the next save waits for it.

Whole process: ``atlasgen preview MATERIAL -o OUT -v`` as a subprocess, the median of ``RUNS`` runs
after one that fills the bake cache, from process start to exit; ``-v`` prints the steps' times.

Beside each wall time, the CPU time it took (user + system, every thread: the watch, the bake and
lavapipe's; a subprocess's from its rusage), which other processes on a shared machine disturb less,
and the ratio of each median to the one the last run wrote in BENCHMARKS.json.

Run alone: ``python bench/run.py preview`` (updates this section of BENCHMARKS.md and .json).
"""

from __future__ import annotations

import json
import os
import queue
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SAVES, WARMUP, RUNS = 10, 1, 5
#: Goals on lavapipe on the 2-core development machine (issue 20).
GOALS_S = {"lut": 0.3, "separable": 1.0, "process": 3.0}


#: Part of every edited value, new in each run: Mesa keeps compiled shaders on disk, and an edit an
#: earlier run made already would find its shader there. An artist's new value finds none.
NONCE = time.time_ns() % 999_983 * 1e-9


def _terracotta_peak(i: int) -> str:
    # The largest channel moves: the slice's scale, so the bake's include (the renderer reads it from a buffer).
    return f'type = "lambert"\ndescription = "terracotta, edited"\ncolour = [{0.76 - 0.01 * (i + 1) - NONCE:.9f}, 0.39, 0.25]\n'


def _terracotta_same_peak(i: int) -> str:
    # Another green: the same scale, the same include; only the texels change.
    return f'type = "lambert"\ndescription = "terracotta, edited"\ncolour = [0.76, {0.39 - 0.01 * (i + 1) - NONCE:.9f}, 0.25]\n'


def _red_plastic(i: int) -> str:
    text = (ROOT / "materials" / "red-plastic.toml").read_text()
    return text.replace('colour = "#b3161b"', f"colour = [{0.45 - 0.01 * (i + 1) - NONCE:.9f}, 0.008, 0.011]")


def _gold(i: int) -> str:
    text = (ROOT / "materials" / "separable-gold.toml").read_text()
    return text.replace("alpha = 0.2,", f"alpha = {0.2 + 0.002 * (i + 1) + NONCE:.9f},")


#: (key, material file, kind for the goal, what each save edits, how)
CASES = (
    ("terracotta", "terracotta", "lut", "colour, a new largest channel (a new slice scale)", _terracotta_peak),
    ("terracotta-same-peak", "terracotta", "lut", "colour, the same largest channel (texels only)", _terracotta_same_peak),
    ("red-plastic", "red-plastic", None, "colour of a slice fitted to Mitsuba's roughplastic (the fit runs)", _red_plastic),
    ("separable-gold", "separable-gold", "separable", "roughness alpha of the factored Mitsuba BSDF", _gold),
)


def rename_over(path: Path, text: str) -> None:
    temporary = path.with_name(f".{path.name}.swp")
    temporary.write_text(text)
    os.replace(temporary, path)


def measure_saves(stem: str, edit) -> dict:
    """``SAVES`` timed saves of an edited ``materials/<stem>.toml`` under a running watch."""
    from atlasgen.preview.previewer import Previewer
    from atlasgen.preview.watch import watch_preview

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        path = tmp / "materials" / f"{stem}.toml"
        path.parent.mkdir()
        shutil.copy(ROOT / "materials" / f"{stem}.toml", path)
        updates: queue.Queue = queue.Queue()
        labels: queue.Queue = queue.Queue()
        stop = threading.Event()
        previewer = Previewer(tmp / "cache")

        def got(update) -> None:  # whether the picture was a draft's, before the watch completes it
            updates.put((update, bool(update.preview is not None and update.preview.pending)))

        def labelled(preview, error) -> None:
            labels.put((time.perf_counter(), time.process_time(), error, sum(preview.label_timings.values())))

        watcher = threading.Thread(target=watch_preview, args=([path], tmp / "preview.png"),
                                   kwargs={"stop": stop, "on_update": got, "on_label": labelled, "previewer": previewer},
                                   daemon=True)  # fmt: skip
        watcher.start()
        first, drafted = updates.get(timeout=600)
        if first.error is not None:
            raise RuntimeError(f"{stem}: first picture failed: {first.error}")
        if drafted:
            labels.get(timeout=600)
        latencies, cpus, steps, compiled, label_latencies, label_cpus, label_work = [], [], [], 0, [], [], []
        for i in range(WARMUP + SAVES):
            time.sleep(0.3)  # the watch idle again, as between an artist's saves
            t0, c0 = time.perf_counter(), time.process_time()
            rename_over(path, edit(i))
            update, drafted = updates.get(timeout=600)
            latency, cpu = time.perf_counter() - t0, time.process_time() - c0
            if update.error is not None:
                raise RuntimeError(f"{stem}: save {i} failed: {update.error}")
            if drafted:
                t_label, c_label, error, work = labels.get(timeout=600)
                if error is not None:
                    raise RuntimeError(f"{stem}: save {i}: the label's figures failed: {error}")
            if i >= WARMUP:
                latencies.append(latency)
                cpus.append(cpu)
                steps.append(update.timings)
                compiled += update.preview.compiled
                if drafted:
                    label_latencies.append(t_label - t0)
                    label_cpus.append(c_label - c0)
                    label_work.append(work)
        stop.set()
        watcher.join(30)
    names = [k for k in steps[0] if k != "total"]
    step_medians = {k: statistics.median(s[k] for s in steps) for k in names}
    work = statistics.median(s["total"] for s in steps)
    return {
        "median_s": statistics.median(latencies),
        "min_s": min(latencies),
        "max_s": max(latencies),
        "all_s": latencies,
        "cpu_median_s": statistics.median(cpus),
        "steps_median_s": step_medians,
        "update_median_s": work,
        "noticing_median_s": statistics.median(lat - s["total"] for lat, s in zip(latencies, steps)),
        "compiled_saves": compiled,
        "first_picture_s": first.timings["total"],
        # Saves whose picture came from a draft: the full label's latency and CPU from the same instant.
        "drafted_saves": len(label_latencies),
        **(
            {
                "label_median_s": statistics.median(label_latencies),
                "label_cpu_median_s": statistics.median(label_cpus),
                "label_work_median_s": statistics.median(label_work),
            }
            if label_latencies
            else {}
        ),  # fmt: skip
    }


def measure_process(stem: str) -> dict:
    """Whole-process ``atlasgen preview`` of ``materials/<stem>.toml``, warm bake cache."""
    exe = Path(sys.executable).with_name("atlasgen")
    with tempfile.TemporaryDirectory() as tmp:
        material = str(ROOT / "materials" / f"{stem}.toml")
        cmd = [str(exe), "preview", material, "-o", f"{tmp}/out.png", "--cache", f"{tmp}/cache", "-v"]
        subprocess.run(cmd, check=True, capture_output=True)  # fills the cache and writes the ball's file
        walls, cpus, steps = [], [], []
        for _ in range(RUNS):
            t0, r0 = time.perf_counter(), resource.getrusage(resource.RUSAGE_CHILDREN)
            done = subprocess.run(cmd, check=True, capture_output=True, text=True)
            walls.append(time.perf_counter() - t0)
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpus.append(r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
            steps.append({k: float(v) for k, v in re.findall(r"(\w+) ([0-9.]+) s", done.stderr)})
        imports = []
        for _ in range(RUNS):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-c", "import atlasgen.cli.preview_cmd"], check=True)
            imports.append(time.perf_counter() - t0)
    step_medians = {k: statistics.median(s[k] for s in steps) for k in steps[0]}
    return {"median_s": statistics.median(walls), "min_s": min(walls), "max_s": max(walls), "all_s": walls,
            "cpu_median_s": statistics.median(cpus),
            "steps_median_s": step_medians, "start_and_imports_median_s": statistics.median(imports)}  # fmt: skip


def _steps(medians: dict) -> str:
    return ", ".join(f"{k} {v:.3f}" for k, v in medians.items())


def _last_run() -> dict:
    """The ``preview`` section BENCHMARKS.json holds (the figures this run is compared with), {} without one."""
    try:
        data = json.loads((ROOT / "BENCHMARKS.json").read_text()).get("preview", {})
    except (OSError, ValueError):
        return {}
    return data if "saves" in data else {}


def _ratio(new: float, old: dict | None) -> str:
    return f"{new / old['median_s']:.2f}x" if old and old.get("median_s") else "-"


def _median(entry: dict | None) -> str:
    return f"{entry['median_s']:.3f}" if entry and "median_s" in entry else "-"


def _cpu(entry: dict | None) -> str:
    return f"{entry['cpu_median_s']:.3f}" if entry and "cpu_median_s" in entry else "-"


def run() -> dict:
    from atlasgen.render.device import get_device

    last = _last_run()
    load, cpus = os.getloadavg()[0], os.cpu_count()
    device = get_device().name
    saves = {}
    for key, stem, kind, what, edit in CASES:
        print(f"bench preview: {key} ...", file=sys.stderr, flush=True)
        saves[key] = {"material": stem, "kind": kind, "edit": what, **measure_saves(stem, edit)}
        print(f"bench preview: {key}: median {saves[key]['median_s']:.3f} s", file=sys.stderr, flush=True)
    print("bench preview: whole process ...", file=sys.stderr, flush=True)
    process = measure_process("terracotta")
    goals = {
        "lut": saves["terracotta"]["median_s"] <= GOALS_S["lut"],
        "separable": saves["separable-gold"]["median_s"] <= GOALS_S["separable"],
        "process": process["median_s"] <= GOALS_S["process"],
    }
    md = [
        "## `atlasgen preview`: save-to-PNG latency in watch mode, and the whole process",
        "",
        f"Watch mode: each save renames an edited copy over the material file (as vim saves); latency from "
        f"just before the rename to the PNG in place, median of {SAVES} saves after {WARMUP}, fresh bake cache "
        f"(every save bakes). 640x400 per picture plus its label. Device: {device}; load average {load:.2f} on "
        f"{cpus} CPUs when the section started. CPU: the process's user + system seconds over the same span "
        f"(every thread: the watch, the bake, lavapipe's); last run: this median over the one BENCHMARKS.json held.",
        "",
        "| material | each save edits | median (s) | CPU median (s) | last run (s) | ratio | fastest | slowest | goal "
        "| where an update's time goes (median s) | noticing the save (s) | shader compiled |",
        "|---|---|---:|---:|---:|---:|---:|---:|---|---|---:|---:|",
    ]
    old_saves = last.get("saves", {})
    for key, s in saves.items():
        old = old_saves.get(key)
        goal = f"<= {GOALS_S[s['kind']]} s: {'met' if s['median_s'] <= GOALS_S[s['kind']] else 'not met'}" if s["kind"] else "-"
        md.append(f"| {s['material']} | {s['edit']} | {s['median_s']:.3f} | {_cpu(s)} | "
                  f"{_median(old)} | {_ratio(s['median_s'], old)} | {s['min_s']:.3f} "
                  f"| {s['max_s']:.3f} | {goal} | {_steps(s['steps_median_s'])} | {s['noticing_median_s']:.3f} "
                  f"| {s['compiled_saves']}/{SAVES} |")  # fmt: skip
    lut, same = saves["terracotta"], saves["terracotta-same-peak"]
    compile_s = lut["steps_median_s"]["render"] - same["steps_median_s"]["render"]
    missed = [s for s in saves.values() if s["kind"] and s["median_s"] > GOALS_S[s["kind"]]]
    if missed:
        md += ["", "Where the time goes where a goal is missed: " + "; ".join(
            f"{s['material']} ({s['edit']}): " + ", ".join(
                f"{k} {v:.3f} s" for k, v in sorted(s["steps_median_s"].items(), key=lambda kv: -kv[1])[:2])
            for s in missed) + "."]  # fmt: skip
    drafted = [s for s in saves.values() if s.get("drafted_saves")]
    if drafted:
        md += ["", "Pictures drawn from a draft bake (the SVD and the choice of K; the label's error figure measured "
               "after the PNG is written, then the PNG rewritten with it): " + "; ".join(
                   f"{s['material']}, {s['drafted_saves']}/{SAVES} saves: the full label in place a median "
                   f"{s['label_median_s']:.3f} s after the save (CPU {s['label_cpu_median_s']:.3f} s), measuring it "
                   f"{s['label_work_median_s']:.3f} s" for s in drafted) + "."]  # fmt: skip
    md += ["", f"A new slice scale costs {compile_s:.3f} s more render than new texels alone (the two terracotta "
           f"rows): the renderer reads scales and factor tables from storage buffers, and compiled its lighting "
           f"shader on {sum(s['compiled_saves'] for s in saves.values())} of {len(saves) * SAVES} saves."]  # fmt: skip
    p, load_after, old_p = process, os.getloadavg()[0], last.get("process")
    last_text = f"; last run {old_p['median_s']:.2f} s, ratio {_ratio(p['median_s'], old_p)}" if old_p else ""
    md += [
        "",
        f"Whole process, `atlasgen preview materials/terracotta.toml -v` with a warm bake cache: median "
        f"{p['median_s']:.2f} s of {RUNS} (fastest {p['min_s']:.2f}, slowest {p['max_s']:.2f}; CPU median "
        f"{p['cpu_median_s']:.2f} s{last_text})",
    ]
    md[-1] += (f"; goal <= {GOALS_S['process']} s: {'met' if goals['process'] else 'not met'}. Its steps (median s): "
               f"{_steps(p['steps_median_s'])}; Python's start with the command's imports alone: "
               f"{p['start_and_imports_median_s']:.2f} s. Load average {load_after:.2f} when the section ended: other "
               "processes on the machine move the wall times by as much as 2x between runs, the CPU times less.")  # fmt: skip
    md.append("")
    return {"markdown": "\n".join(md),
            "data": {"device": device, "load_average": load, "load_average_after": load_after, "cpus": cpus, "saves": saves, "process": process,
                     "lighting_compile_s": compile_s, "goals_s": GOALS_S, "goals_met": goals,
                     "last_run": {"saves": {k: v.get("median_s") for k, v in old_saves.items()},
                                  "process": (old_p or {}).get("median_s")}}}  # fmt: skip


if __name__ == "__main__":
    print(run()["markdown"])
