"""The render benchmark on a real GPU: issue 22's lighting-pass figure, measured on a lent GPU machine.

This machine's only adapter is lavapipe, so `make bench` cannot measure it. A session lent a GPU
machine runs ``make device-prepare`` (the wheels, loaders and atlas into ``.device/``), then the
device tool's ``run`` with ``bash bench/device_run.sh`` and ``carry=[".device"]``, which runs
:mod:`render` there and writes its data to ``render-gpu.json``; ``bench/run.py --import render_gpu
FILE`` words it into BENCHMARKS.md (README, "Benchmarks on a lent GPU").
"""

from __future__ import annotations

from render import markdown  # noqa: F401  (the same section, worded from the device's data)


def run() -> dict:
    raise RuntimeError("render_gpu is measured on a lent GPU machine: bench/device_run.sh, then "
                       "bench/run.py --import render_gpu FILE")  # fmt: skip
