"""`make bench`: run every benchmark section and write BENCHMARKS.md and BENCHMARKS.json.

Each section lives in its own module with ``run() -> {"markdown": str, "data": dict}``;
a section that fails is reported as failed rather than silently dropped.
"""

from __future__ import annotations

import datetime
import importlib
import json
import platform
import sys
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SECTIONS = ["bake", "models", "separable", "render", "cost", "physical"]


def main(argv=None) -> int:
    names = (argv if argv is not None else sys.argv[1:]) or SECTIONS
    sys.path.insert(0, str(ROOT / "bench"))
    results, parts = {}, []
    for name in names:
        print(f"bench: {name} ...", file=sys.stderr, flush=True)
        try:
            module = importlib.import_module(name)
            out = module.run()
            results[name] = out["data"]
            parts.append(out["markdown"])
        except Exception as exc:  # report, don't hide, a broken section
            results[name] = {"error": repr(exc)}
            parts.append(f"## {name}\n\nFailed: `{exc!r}`\n\n```\n{traceback.format_exc()}```\n")
    header = [
        "# Benchmarks",
        "",
        f"Written by `make bench` on {datetime.date.today().isoformat()}: {platform.processor() or platform.machine()}, "
        f"Python {platform.python_version()}. Every figure below is measured by `bench/*.py` in that run.",
        "",
    ]
    (ROOT / "BENCHMARKS.md").write_text("\n".join(header + parts) + "\n")
    (ROOT / "BENCHMARKS.json").write_text(json.dumps(results, indent=2) + "\n")
    print("bench: wrote BENCHMARKS.md and BENCHMARKS.json", file=sys.stderr)
    return 0 if all("error" not in r for r in results.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
