"""The measured tables of docs/materials.md, written by code: ``python -m atlasgen.reports.measured_docs``.

Each table sits between ``<!-- measured: NAME -->`` and ``<!-- /measured -->``; :func:`write_measured_tables`
replaces what lies between with what :data:`TABLES` measures now, so that no figure there is typed in.
Tests compare each table with a fresh measurement (``tests/reports/test_measured_docs.py``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from atlasgen.materials.material import read_material
from atlasgen.models import get_model

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "materials.md"
#: The golden manifest whose skin fit the skin table quotes (the shipped skin, baked by the golden test).
GOLDEN_MANIFEST = ROOT / "tests" / "resources" / "golden" / "array-srgb.json"
#: The shipped iridescent materials fitted to their physical film (``from = "physical"``).
STYLISED = ("beetle-shell", "iridescent-backlit")
SHIPPED = ROOT / "atlasgen" / "data" / "materials"
_START = "<!-- measured: {} -->"
_END = "<!-- /measured -->"


def skin_fit_table(manifest_path=GOLDEN_MANIFEST) -> list[str]:
    """The skin slice's relative RMS against its volumetric reference, in and out of sample, beside the closed
    form's, as the manifest's ``fit`` records them (``relative_rms``, ``model_relative_rms`` and ``out_of_sample``).

    >>> skin_fit_table()[:2]
    ['| geometry | fitted slice | closed form |', '|---|---|---|']
    """
    manifest = json.loads(Path(manifest_path).read_text(encoding="utf-8"))
    fit = next(m for m in manifest["materials"] if m["name"] == "skin")["fit"]
    out = fit["out_of_sample"]
    rows = [("fitted spheres (in sample)", fit),
            ("validation sphere (out of sample)", out["validation_sphere"]),
            ("flat (out of sample)", out["flat"])]  # fmt: skip
    return ["| geometry | fitted slice | closed form |", "|---|---|---|",
            *(f"| {name} | {s['relative_rms']:.2%} | {s['model_relative_rms']:.2%} |" for name, s in rows)]  # fmt: skip


def stylisation_table(names=STYLISED) -> list[str]:
    """Each shipped iridescent material's model (its closed form in the renderer's equation) and fitted slice
    against the physical film, PSNR with its SE, as ``fit_physical`` records them at gloss 0.5."""
    model = get_model("iridescent")
    lines = ["| material | model's look vs the film | fitted slice vs the film |", "|---|---|---|"]
    for name in names:
        fit = model.fit_physical(read_material(SHIPPED / f"{name}.toml").params, 0.5).extra["fit"]
        lines.append(f"| `{name}` | {fit['model_psnr_db']:.2f} ± {fit['model_psnr_se_db']:.2f} dB | "
                     f"{fit['fit_psnr_db']:.2f} ± {fit['fit_psnr_se_db']:.2f} dB |")  # fmt: skip
    return lines


#: Each measured table of docs/materials.md by its marker's name.
TABLES = {"skin-fit": skin_fit_table, "stylisation": stylisation_table}


def _find_table(text: str, name: str) -> re.Match:
    """Table ``name`` in ``text``: its markers' indent (group 1) and the lines between them (group 2)."""
    match = re.search(rf"^( *){re.escape(_START.format(name))}\n(.*?)^ *{re.escape(_END)}$", text, re.S | re.M)
    if match is None:
        raise ValueError(f"no table {name!r} (its markers {_START.format(name)} ... {_END})")
    return match


def read_measured_table(text: str, name: str) -> list[str]:
    """The lines between table ``name``'s markers, stripped of the list item's indent.

    >>> read_measured_table("a\\n  <!-- measured: t -->\\n  | x |\\n  <!-- /measured -->\\n", "t")
    ['| x |']
    """
    return [line.strip() for line in _find_table(text, name).group(2).splitlines()]


def replace_measured_table(text: str, name: str, lines: list[str]) -> str:
    """``text`` with table ``name``'s lines replaced by ``lines``, at its markers' indent.

    >>> replace_measured_table("  <!-- measured: t -->\\n  | x |\\n  <!-- /measured -->\\n", "t", ["| y |"])
    '  <!-- measured: t -->\\n  | y |\\n  <!-- /measured -->\\n'
    """
    match = _find_table(text, name)
    body = "".join(f"{match.group(1)}{line}\n" for line in lines)
    return text[: match.start(2)] + body + text[match.end(2) :]


def write_measured_tables(doc=DOC, names=None) -> list[str]:
    """Measure each table (all of :data:`TABLES`, or ``names``) and write it into ``doc``; returns the names
    whose text changed."""
    doc = Path(doc)
    text = doc.read_text(encoding="utf-8")
    changed = []
    for name in names or TABLES:
        new = replace_measured_table(text, name, TABLES[name]())
        if new != text:
            changed.append(name)
        text = new
    doc.write_text(text, encoding="utf-8")
    return changed


if __name__ == "__main__":
    for table in write_measured_tables():
        print(f"{DOC.relative_to(ROOT).as_posix()}: table {table!r} rewritten")
