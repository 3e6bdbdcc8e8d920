"""One HTML page over the whole material library: representation, errors, bake time, previews."""

from __future__ import annotations

import html
import io
import json
import os
from pathlib import Path

from atlasgen.errors import InputError
from atlasgen.io.manifest import MaterialEntry
from atlasgen.models import get_model

__all__ = ["write_library_report"]


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

    from atlasgen.io.atlas import read_atlas
    from atlasgen.io.atomic import write_file_atomically, write_files_atomically
    from atlasgen.bake.preview import slice_png

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
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 4.5), dpi=100)
        for kind in sorted({p[3] for p in points}):
            sel = [p for p in points if p[3] == kind]
            ax.scatter([p[1] * 1e3 for p in sel], [p[2] for p in sel], label=kind)
            for p in sel:
                ax.annotate(p[0], (p[1] * 1e3, p[2]), fontsize=7, xytext=(3, 3), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("bake time per material (ms)")
        ax.set_ylabel(y_label)
        ax.set_title("Speed against error" + (" (validation, front scene)" if validation is not None else " (level 0)"))
        ax.legend(fontsize=8)
        fig.tight_layout()
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png")
        plt.close(fig)
        plot = "speed-vs-error.png"
        files[out_dir / plot] = buffer.getvalue()
    # Previews and plot first, all-or-nothing; the page that links them replaces the old one last.
    write_files_atomically(files)

    def link(target: Path | None, label: str) -> str:
        if target is None or not Path(target).exists():
            return ""
        rel = os.path.relpath(target, out_dir)
        return f'<a href="{html.escape(rel)}">{html.escape(label)}</a>'

    e = html.escape
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'><title>atlasgen library report</title>",
        "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}"
        "td,th{border:1px solid #ccc;padding:4px 8px;vertical-align:top;font-size:90%}img{image-rendering:pixelated}</style>",
        "</head><body>",
        f"<h1>Material library: {e(Path(atlas_path).as_posix())}</h1>",
        f"<p>{len(rows)} materials, {e(atlas.manifest.encoding)} encoding, {e(atlas.manifest.layout)} layout. "
        "Every figure is read from the bake's manifest and timings, and from validation's report.json.</p>",
    ]
    links = [link(Path(validation_dir) / "index.html" if validation_dir else None, "validation report"),
             link(Path(separable_dir) / "index.md" if separable_dir else None, "separable factorisation report")]
    if any(links):
        parts.append("<p>" + " · ".join(x for x in links if x) + "</p>")
    if plot:
        parts.append(f'<p><img src="{plot}" alt="speed against error"></p>')
    parts.append("<table><tr><th>ID</th><th>material</th><th>type</th><th>representation</th><th>bake (ms)</th>"
                 "<th>quantisation error (max / RMS)</th><th>errors against references</th><th>slices (RGB | A)</th></tr>")
    for entry, previews, bake_s, refs, pages in rows:
        q = entry.quantization_error
        ref_text = "<br>".join(
            f"{e(r['reference'])}: PSNR {_fmt(r['psnr'], '.1f')} dB, FLIP {_fmt(r['flip'], '.4f')}, "
            f"atlas {_fmt(r['speed_ratio'], '.1f')}x faster"
            for r in refs
        ) or "not validated"
        own = [link(Path(validation_dir) / page, "validation page") for page in pages] if validation_dir else []
        if any(own):
            ref_text += "<br>" + " · ".join(x for x in own if x)
        imgs = " ".join(f'<img src="{e(p)}" alt="{e(entry.name)} slice">' for p in previews)
        parts.append(
            f"<tr><td>{entry.first_slice}</td><td>{e(entry.name)}</td><td>{e(entry.type)}</td>"
            f"<td>{e(get_model(entry.type).describe_representation(entry))}</td><td>{_fmt(None if bake_s is None else bake_s * 1e3, '.2f')}</td>"
            f"<td>{q.max:.4f} / {q.rms:.4f}</td><td>{ref_text}</td><td>{imgs}</td></tr>"
        )
    parts.append("</table></body></html>")
    index = out_dir / "index.html"
    write_file_atomically(index, "\n".join(parts).encode())
    return index
