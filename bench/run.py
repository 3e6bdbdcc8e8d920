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
SECTIONS = [
    "bake",
    "models",
    "separable",
    "render",
    "preview",
    "cost",
    "physical",
    "verdict",
    "pareto",
    "environment",
    "environment_error",
    "environment_cost",
    "materialx",
]
#: Sections measured elsewhere and brought in with ``--import`` (a lent GPU machine: bench/device_run.sh).
#: A full run keeps them as they were imported; each module words its data with ``markdown(data)``.
IMPORTED = ["render_gpu"]


#: Each section's text in BENCHMARKS.md starts with this marker, so one section can be re-run alone.
_MARK = "<!-- bench section: {} -->"


def _update(names, results, parts) -> int:
    """``bench/run.py NAME...``: replace those sections of BENCHMARKS.md and BENCHMARKS.json (a section
    without a marker yet is appended), keeping every other section as the last full run wrote it."""
    import re

    md_path, json_path = ROOT / "BENCHMARKS.md", ROOT / "BENCHMARKS.json"
    text = md_path.read_text() if md_path.exists() else "# Benchmarks\n"
    data = json.loads(json_path.read_text()) if json_path.exists() else {}
    for name, part in zip(names, parts):
        block = f"{_MARK.format(name)}\n{part}\n"
        pattern = re.compile(re.escape(_MARK.format(name)) + r"\n.*?(?=<!-- bench section: |\Z)", re.S)
        text = pattern.sub(lambda _: block, text) if pattern.search(text) else text.rstrip("\n") + "\n\n" + block
        data[name] = results[name]
    md_path.write_text(text)
    json_path.write_text(json.dumps(data, indent=2) + "\n")
    print(f"bench: updated {', '.join(names)} in BENCHMARKS.md and BENCHMARKS.json", file=sys.stderr)
    return 0 if all("error" not in results[n] for n in names) else 1


def _rewrite(names) -> int:
    """``bench/run.py --rewrite NAME...``: re-render those sections' text from the data BENCHMARKS.json
    holds (for a section whose module has ``markdown(data)``), measuring nothing: a change to how a
    section judges or words its figures lands without re-running an hour of benchmarks."""
    data = json.loads((ROOT / "BENCHMARKS.json").read_text())
    results, parts = {}, []
    for name in names:
        results[name] = data[name]
        parts.append(importlib.import_module(name).markdown(data[name]))
    return _update(names, results, parts)


def _save(path: str, name: str) -> int:
    """``bench/run.py --save FILE NAME``: run one section and write its data to FILE alone, as a lent GPU
    machine does (bench/device_run.sh): that machine's copy of the tree is thrown away, so BENCHMARKS.md is
    left to ``--import`` here."""
    out = importlib.import_module(name).run()
    Path(path).write_text(json.dumps(out["data"], indent=2) + "\n")
    print(out["markdown"])
    print(f"bench: wrote {name}'s data to {path}", file=sys.stderr)
    return 0


def _import(name: str, path: str) -> int:
    """``bench/run.py --import NAME FILE``: section NAME (one of :data:`IMPORTED`) from the data another
    machine measured (``--save``), worded by its module, into BENCHMARKS.md and BENCHMARKS.json."""
    if name not in IMPORTED:
        print(f"bench: {name} is not a section measured elsewhere (one of {', '.join(IMPORTED)})", file=sys.stderr)
        return 2
    data = json.loads(Path(path).read_text())
    return _update([name], {name: data}, [importlib.import_module(name).markdown(data)])


#: Sections run alone only (``make bench-workflow``): a full run leaves them as they were.
ALONE = ["workflow"]
USAGE = (
    "usage: bench/run.py [SECTION...] | --rewrite SECTION... | --save FILE SECTION | --import SECTION FILE\n"
    f"sections: {', '.join(SECTIONS + ALONE)}; measured elsewhere: {', '.join(IMPORTED)}"
)


def _unknown(names) -> list:
    """The names that are no section (an option misspelt, ``--help``): run, they would each be written
    into BENCHMARKS.md as a failed section."""
    return [n for n in names if n not in SECTIONS + ALONE]


def main(argv=None) -> int:
    names = (argv if argv is not None else sys.argv[1:]) or SECTIONS
    sys.path.insert(0, str(ROOT / "bench"))
    if names[0] in ("-h", "--help"):
        print(USAGE)
        return 0
    if names[0] not in ("--rewrite", "--save", "--import") and _unknown(names):
        print(f"bench: no section {', '.join(map(repr, _unknown(names)))}; nothing written\n{USAGE}", file=sys.stderr)
        return 2
    if names[0] == "--rewrite":
        return _rewrite(names[1:])
    if names[0] == "--save" and len(names) == 3:
        return _save(names[1], names[2])
    if names[0] == "--import" and len(names) == 3:
        return _import(names[1], names[2])
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
    if argv is not None or sys.argv[1:]:
        return _update(names, results, parts)
    header = [
        "# Benchmarks",
        "",
        f"Written by `make bench` on {datetime.date.today().isoformat()}: {platform.processor() or platform.machine()}, "
        f"Python {platform.python_version()}. Every figure below is measured by `bench/*.py` in that run.",
        "",
    ]
    # The sections measured elsewhere stay as the last import left them.
    old = json.loads((ROOT / "BENCHMARKS.json").read_text()) if (ROOT / "BENCHMARKS.json").exists() else {}
    for name in IMPORTED:
        if name in old:
            names, results[name] = [*names, name], old[name]
            parts.append(importlib.import_module(name).markdown(old[name]))
    parts = [f"{_MARK.format(name)}\n{part}" for name, part in zip(names, parts)]
    (ROOT / "BENCHMARKS.md").write_text("\n".join(header + parts) + "\n")
    (ROOT / "BENCHMARKS.json").write_text(json.dumps(results, indent=2) + "\n")
    print("bench: wrote BENCHMARKS.md and BENCHMARKS.json", file=sys.stderr)
    return 0 if all("error" not in r for r in results.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
