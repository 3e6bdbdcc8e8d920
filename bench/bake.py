"""Benchmark: a whole-process `atlasgen bake` of 256 LUT materials, against interpreter start-up."""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RUNS = 7
GOAL_S = 1.0


def make_library(folder: Path, count: int = 256) -> dict:
    """``count`` LUT materials cycled from the shipped library (all LUT types), ids left to the allocator."""
    sources = []
    for path in sorted((ROOT / "materials").glob("*.toml")):
        data = tomllib.loads(path.read_text())
        if data.get("type") != "separable":
            sources.append((path.stem, path.read_text()))
    if not sources:
        sources = [("lambert", 'type = "lambert"\n')]
    types = {}
    for i in range(count):
        stem, text = sources[i % len(sources)]
        lines = [ln for ln in text.splitlines() if not ln.startswith(("id ", "id=", "name ", "name="))]
        (folder / f"m{i:03d}-{stem}.toml").write_text("\n".join(lines) + "\n")
        kind = tomllib.loads(text)["type"]
        types[kind] = types.get(kind, 0) + 1
    return types


def _time(cmd, runs=RUNS) -> list[float]:
    times = []
    env = dict(os.environ)
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
        times.append(time.perf_counter() - t0)
    return times


def run() -> dict:
    exe = Path(sys.executable).with_name("atlasgen")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "lib").mkdir()
        types = make_library(tmp / "lib")
        _time([str(exe), "bake", str(tmp / "lib"), "-o", str(tmp / "warm.dds"), "-q"], runs=1)  # warm the page cache
        bake = _time([str(exe), "bake", str(tmp / "lib"), "-o", str(tmp / "atlas.dds"), "-q"])
        python = _time([sys.executable, "-c", "pass"])
        numpy = _time([sys.executable, "-c", "import numpy"])
    med = statistics.median(bake)
    data = {
        "materials": 256,
        "types": types,
        "runs": RUNS,
        "bake_wall_s": {"median": med, "min": min(bake), "max": max(bake), "all": bake},
        "python_start_s": statistics.median(python),
        "python_numpy_import_s": statistics.median(numpy),
        "goal_s": GOAL_S,
        "meets_goal": med <= GOAL_S,
        "cpu_count": os.cpu_count(),
    }
    md = [
        "## `atlasgen bake`: 256 LUT materials, whole process",
        "",
        f"Materials by type: {', '.join(f'{k} {v}' for k, v in sorted(types.items()))}. "
        f"Median of {RUNS} runs after one warm-up, {os.cpu_count()} cores, interpreter start included.",
        "",
        "| what | median (s) | min (s) | max (s) | ratio to `python -c pass` |",
        "|---|---|---|---|---|",
        f"| `atlasgen bake` (256 materials) | {med:.3f} | {min(bake):.3f} | {max(bake):.3f} | {med / data['python_start_s']:.1f}x |",
        f"| `python -c 'import numpy'` | {data['python_numpy_import_s']:.3f} | | | {data['python_numpy_import_s'] / data['python_start_s']:.1f}x |",
        f"| `python -c pass` (baseline) | {data['python_start_s']:.3f} | | | 1.0x |",
        "",
        f"Goal: at most {GOAL_S:.1f} s. Reached: **{'yes' if data['meets_goal'] else 'no'}** ({med:.3f} s).",
        "",
    ]
    return {"markdown": "\n".join(md), "data": data}
