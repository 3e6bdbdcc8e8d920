"""One HTML page over the whole material library: representation, errors, bake time, previews."""

from __future__ import annotations

import json
import os
from pathlib import Path

from atlasgen.errors import InputError
from atlasgen.io.manifest import MaterialEntry
from atlasgen.models import get_model
from atlasgen.reports.html import plot_width, render_page
from atlasgen.io.atlas import read_atlas
from atlasgen.io.atomic import write_file_atomically, write_files_atomically
from atlasgen.bake.preview import slice_png
from atlasgen.reports.html import figure_png, label_points, pareto_front, plot_style

__all__ = ["write_library_report"]

#: The speed/error plot: its file and its size in inches (shown at 100 CSS px per inch).
_PLOT = "speed-vs-error.png"
_PLOT_SIZE = (7.0, 4.5)


def _read_json(path):
    path = Path(path)
    if not path.exists():
        return None
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except ValueError as exc:
        raise InputError(f"{path.as_posix()}: malformed JSON ({exc})") from None


def _validation_rows(validation: dict | None, name: str) -> list[dict]:
    """Per-reference metrics of one material from validate's report.json, whatever refs it has."""
    rows = []
    for result in (validation or {}).get("results", []):
        if result.get("material") == name:
            for kind, ref in result.get("references", {}).items():
                rows.append({"reference": f"{result.get('scene', '?')}/{kind}", "psnr": ref.get("psnr_db"),
                             "flip": ref.get("flip"), "speed_ratio": ref.get("speed_ratio"),
                             "linear_rmse": ref.get("linear_rmse")})
    return rows


def _validation_pages(validation: dict | None, name: str) -> list[str]:
    """The per-material validation pages of one material (``page`` of a merged report), in
    report order, relative to the validation folder."""
    pages = [r["page"] for r in (validation or {}).get("results", []) if r.get("material") == name and r.get("page")]
    return list(dict.fromkeys(pages))


def _plotted_error(entry: MaterialEntry, refs: list[dict], validated: bool):
    """One error per material on one scale: validation's linear RMSE against the model
    reference when there is a validation run, else the manifest's quantisation RMS."""
    if validated:
        front = [r for r in refs if r["reference"] == "front/model" and r.get("linear_rmse") is not None]
        return max(front[0]["linear_rmse"], 1e-7) if front else None
    return max(entry.quantization_error.rms, 1e-7)


def _fmt(x, spec=".3g"):
    return "–" if x is None else format(x, spec)


def write_library_report(atlas_path, out_dir, validation_dir=None, separable_dir=None) -> Path:
    """Write ``out_dir/index.html`` (+ slice previews and a speed-against-error plot).

    Every figure on the page is read from files the toolchain measured: the manifest
    (errors, representation), the timings file (bake time), and, when present,
    ``validation_dir/report.json`` (errors against Mitsuba references; a merged report
    also links each material's own validation page). Every file is replaced atomically.
    """


    atlas = read_atlas(atlas_path)
    if atlas.manifest is None:
        raise InputError(f"{Path(atlas_path).as_posix()}: no manifest beside the atlas; run atlasgen bake first")
    timings = _read_json(Path(atlas_path).with_suffix("").as_posix() + ".timings.json") or {}
    validation = _read_json(Path(validation_dir) / "report.json") if validation_dir else None
    out_dir = Path(out_dir)

    rows, points, files = [], [], {}
    srgb = atlas.manifest.srgb
    for entry in atlas.manifest.materials:
        name = entry.name
        previews = []
        for k, s in enumerate(entry.slices):
            rel = f"slices/{name}-{k}.png"
            files[out_dir / rel] = slice_png(atlas.image.levels[0], s, srgb, zoom=2)
            previews.append(rel)
        bake_s = (timings.get("materials", {}).get(name) or {}).get("bake_s")
        refs = _validation_rows(validation, name)
        rows.append((entry, previews, bake_s, refs, _validation_pages(validation, name)))
        if bake_s is not None:
            points.append((name, bake_s, _plotted_error(entry, refs, validation is not None), entry.type))

    y_label = ("linear RMSE vs model reference" if validation is not None else "RMS quantisation error, linear")
    points = [p for p in points if p[2] is not None]
    plot = None
    if points:
        files[out_dir / _PLOT] = _plot_speed_error(points, y_label, validation is not None)
        plot = {"src": _PLOT, "width": plot_width(_PLOT_SIZE[0])}
    # Previews and plot first, all-or-nothing; the page that links them replaces the old one last.
    write_files_atomically(files)

    def rel(target) -> str | None:
        return os.path.relpath(target, out_dir) if target is not None and Path(target).exists() else None

    links = [{"href": href, "label": label} for href, label in (
        (rel(Path(validation_dir) / "index.html") if validation_dir else None, "validation report"),
        (rel(Path(separable_dir) / "index.html") if separable_dir else None, "separable factorisation report"),
    ) if href]  # fmt: skip
    page_rows = []
    for entry, previews, bake_s, refs, pages in rows:
        q = entry.quantization_error
        own = [rel(Path(validation_dir) / page) for page in pages] if validation_dir else []
        page_rows.append({
            "first_slice": entry.first_slice, "name": entry.name, "type": entry.type,
            "representation": get_model(entry.type).describe_representation(entry),
            "bake_ms": _fmt(None if bake_s is None else bake_s * 1e3, ".2f"), "quantisation": f"{q.max:.4f} / {q.rms:.4f}",
            "refs": [{"reference": r["reference"], "psnr": _fmt(r["psnr"], ".1f"), "flip": _fmt(r["flip"], ".4f"),
                      "speed": _fmt(r["speed_ratio"], ".1f") + "x"} for r in refs],
            "pages": [p for p in own if p], "previews": previews,
        })  # fmt: skip
    index = out_dir / "index.html"
    write_file_atomically(index, render_page(
        "library.html.j2", atlas=Path(atlas_path).as_posix(), encoding=atlas.manifest.encoding,
        layout=atlas.manifest.layout, links=links, plot=plot, rows=page_rows))
    return index


def _plot_speed_error(points, y_label: str, validated: bool) -> bytes:
    """Bake time against error, one point per material ``(name, seconds, error, type)``; the
    Pareto front (no material both faster and closer) is labelled, the table lists all."""
    with plot_style() as plt:
        fig, ax = plt.subplots(figsize=_PLOT_SIZE)
        for kind in sorted({p[3] for p in points}):
            sel = [p for p in points if p[3] == kind]
            ax.scatter([p[1] * 1e3 for p in sel], [p[2] for p in sel], label=kind)
        front = [points[i] for i in pareto_front([(p[1], p[2]) for p in points])]
        label_points(ax, [(p[1] * 1e3, p[2]) for p in front], [p[0] for p in front])
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("bake time per material (ms)")
        ax.set_ylabel(y_label)
        ax.set_title("Speed against error" + (" (validation, front scene)" if validated else " (level 0)")
                     + "; labelled: the Pareto front")
        ax.legend()
        return figure_png(fig)
