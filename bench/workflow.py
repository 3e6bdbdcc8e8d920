"""Benchmark: the developer's loop as a newcomer meets it: the fast subset, the whole suite, the demo.

Not part of a plain ``make bench`` (it takes a quarter of an hour): ``make bench-workflow`` runs
it. Each command runs from the repository root as the README gives it, timed on the wall and by
the CPU its process tree used (``getrusage(RUSAGE_CHILDREN)``: user and system, every thread and
child process). The demo runs after ``make clean`` (the set-up's virtual environment is kept,
so the figure is the README's "after make setup"). The figures go to BENCHMARKS.md/json and to
the README's "Timings" table, between its ``<!-- workflow timings -->`` markers: no timing in
the README is typed in. The machine is shared: a load average is recorded before each command.
"""

from __future__ import annotations

import datetime
import os
import re
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: The issue's goals (issue 19), in seconds of wall time on the 2-core machine.
GOALS = {"fast": 30.0, "suite": 300.0, "demo": 120.0}
FAST_RUNS = 3
_README_MARK = re.compile(r"(<!-- workflow timings -->\n).*?(<!-- /workflow timings -->)", re.S)


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _timed(command: str) -> dict:
    load = os.getloadavg()[0]
    cpu0, t0 = _children_cpu(), time.perf_counter()
    done = subprocess.run(command, shell=True, cwd=ROOT, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    if done.returncode != 0:
        # pytest's short summary names the failing tests; keep them, since the run is not repeatable.
        lines = (done.stdout + done.stderr).strip().splitlines()
        failed = [line for line in lines if line.startswith(("FAILED ", "ERROR "))]
        raise RuntimeError(f"{command!r} exited {done.returncode}: " + "; ".join(failed or lines[-1:]))
    passed = re.search(r"(\d+) passed", done.stdout)
    return {
        "command": command,
        "wall_s": wall,
        "cpu_s": cpu,
        "load_before": load,
        "tests": int(passed.group(1)) if passed else None,
    }


def _minutes(seconds: float) -> str:
    """Seconds as the table gives them, rounded once (179.6 s is 3 min 0 s, never 2 min 60 s).

    >>> _minutes(179.6), _minutes(59.94), _minutes(312.2)
    ('3 min 0 s', '59.9 s', '5 min 12 s')
    """
    if seconds < 60:
        return f"{seconds:.1f} s"
    whole = round(seconds)
    return f"{whole // 60} min {whole % 60} s"


def run() -> dict:
    fast_runs = [_timed("make test PYTEST_ARGS='-m \"not slow\"'") for _ in range(FAST_RUNS)]
    fast = dict(fast_runs[0], wall_s=statistics.median(r["wall_s"] for r in fast_runs),
                cpu_s=statistics.median(r["cpu_s"] for r in fast_runs), runs=FAST_RUNS)  # fmt: skip
    suite = _timed("make test")
    _timed("make clean")
    demo = _timed("make demo")
    when = datetime.date.today().isoformat()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    data = {"fast": fast, "fast_runs": fast_runs, "suite": suite, "demo": demo, "goals_s": GOALS, "date": when, "commit": commit}
    return {"markdown": markdown(data), "data": data}


def markdown(data: dict) -> str:
    """The section's text from its data (``bench/run.py --rewrite workflow``), and the README's table with it."""
    goals = data["goals_s"]
    rows = [("`make test PYTEST_ARGS='-m \"not slow\"'`", data["fast"], "fast", f"median of {data['fast']['runs']}"),
            ("`make test`", data["suite"], "suite", "one run"),
            ("`make demo` after `make clean`", data["demo"], "demo", "one run")]  # fmt: skip
    table = ["| command | tests | wall | CPU (user + sys, all processes) | goal | met | runs | load before |",
             "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for label, r, goal, runs in rows:
        table.append(f"| {label} | {r['tests'] or ''} | {_minutes(r['wall_s'])} | {_minutes(r['cpu_s'])} | "
                     f"{_minutes(goals[goal])} | {'yes' if r['wall_s'] <= goals[goal] else '**no**'} | {runs} | {r['load_before']:.2f} |")  # fmt: skip
    text = "\n".join([f"Measured by `make bench-workflow` (`bench/workflow.py`) on {data['date']} at {data['commit']}, "
                      f"{os.cpu_count()} cores:", "", *table]) + "\n"  # fmt: skip
    readme = ROOT / "README.md"
    if _README_MARK.search(readme.read_text()):
        readme.write_text(_README_MARK.sub(lambda m: m.group(1) + text + m.group(2), readme.read_text()))
    return "## Developer workflow: fast subset, whole suite, demo\n\n" + text


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT / "bench"))
    print(run()["markdown"])
