"""``atlasgen report separable``: an HTML page, a Markdown summary and PNG plots of error against terms, grid, bits and time.

Every figure is measured here, by the running code, on the bake's own report sample
(:func:`atlasgen.separable.error.error_sample_for`: the source's lobe-sampled pairs, weighted back to
the uniform measure), so the chosen figures are the manifest's, with their standard errors. matplotlib is imported
lazily (Agg backend), inside :func:`write_separable_report`.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from atlasgen.errors import InputError
from atlasgen.io.atlas import read_atlas
from atlasgen.io.atomic import staged_folder
from atlasgen.io.report_files import rebase_path
from atlasgen.materials.material import check_unique_names
from atlasgen.models import check_manifest_models
from atlasgen.models.separable import Separable
from atlasgen.reports.html import CSS_PX_PER_INCH, Chart, figure_chart, label_points, plot_style, render_page
from atlasgen.reports.report_kind import refuse_another_report
from atlasgen.separable.approximate import MAX_AUTO_TERMS, approximate_brdf, reference_values
from atlasgen.separable.auto import cost_key, read_lighting_cost
from atlasgen.separable.error import ERROR_SEED, error_sample_for, errors_by_terms, measure_errors
from atlasgen.separable.factorize import factorize
from atlasgen.separable.parametrization import PARAMETRIZATIONS, get_parametrization
from atlasgen.separable.rebuild import evaluate_separable
from atlasgen.separable.source import make_source, sample_matrices
from atlasgen.separable.storage import FACTOR_RESOLUTION, encode_factor_slices, factors_to_slices, quantize_factors

__all__ = [
    "MaterialStudy",
    "study_material",
    "format_separable_report",
    "format_separable_html",
    "write_separable_report",
    "RESOLUTIONS",
]

#: Sampling grids of the resolution study (texels per factor axis; the atlas stores 32).
RESOLUTIONS = (8, 12, 16, 24, 32, 48, 64)
#: Terms of the NMF comparison (NMF is not nested, so each K is its own fit).
NMF_TERMS = (1, 2, 4, 8)


@dataclass
class MaterialStudy:
    """Everything the report says about one material, as measured."""

    name: str
    source: str
    chosen: dict
    by_terms: dict  # target -> {"float": [...], "8bit": [...]} (K = 1..8)
    by_parametrization: dict  # name -> [best float rel RMS over targets, K = 1..8]
    by_resolution: list  # [{"resolution", "terms", "relative_rms", "seconds"}]
    nonnegative: dict  # {"nmf": [{terms, relative_rms}], "nd": {...}}
    timings: dict
    atlas: dict | None = None
    pareto: list = field(default_factory=list)
    # Each plot's displayed size and placed labels, by kind ({"width", "height", "labels"}), kept
    # in report.json so that a merge draws the labels over the copied PNGs as this run did.
    charts: dict = field(default_factory=dict)


def _median_time(fn, repeats=5):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def study_material(
    material,
    atlas_path=None,
    resolutions=RESOLUTIONS,
    repeats: int = 5,
    parametrizations=tuple(PARAMETRIZATIONS),
    params: dict | None = None,
    manifest=None,
) -> MaterialStudy:
    """Measure one separable material: the chosen bake, and every comparison the report plots.

    ``params``: the fixed values of the terms its bake stores (:meth:`Separable.stored_terms`, which
    :func:`write_separable_report` resolves first); by default the material's own, which must describe terms.
    ``manifest``: the atlas's, where the caller has read it already (else it is read from ``atlas_path``)."""
    params = material.params if params is None else params
    source = make_source(params, material.source)
    # The bake's two samples (Separable._draft_separable): candidates chosen on the selection sample, every
    # figure measured on the report sample, both lobe-sampled and weighted back to uniform (uniform pairs miss a
    # glossy lobe's peak: docs/separable.md), so the chosen figures are the manifest's.
    pairs = error_sample_for(source, ERROR_SEED)
    reference, _ = reference_values(source, pairs)
    l, v = pairs.pairs
    w = pairs.weight
    name = params["parametrization"]
    p = get_parametrization(name)

    grids = Separable.sampling_grids(params)
    chosen = approximate_brdf(
        source,
        name,
        terms=1 if params["factorization"] == "nd" else params["terms"],
        max_error=params["max_error"],
        method=params["factorization"],
        target=params["target"],
        resolution=FACTOR_RESOLUTION,
        grids=grids,
        report=pairs,
        report_reference=reference,
    )
    full = approximate_brdf(source, name, terms=MAX_AUTO_TERMS, target="auto", reference=reference, pairs=pairs)
    by_terms = {
        t: {
            "float": [e["relative_rms"] for e in full.errors_by_terms[t]],
            "8bit": [e["relative_rms"] for e in full.errors_8bit_by_terms[t]],
            "log_float": [e["log_error"] for e in full.errors_by_terms[t]],
        }
        for t in full.errors_by_terms
    }

    by_param = {}
    for other in parametrizations:
        r = approximate_brdf(
            source, other, terms=MAX_AUTO_TERMS, target="auto", reference=reference, pairs=pairs, measure_8bit=False
        )
        curves = [[e["relative_rms"] for e in errs] for errs in r.errors_by_terms.values()]
        by_param[other] = [float(min(c[k] for c in curves)) for k in range(MAX_AUTO_TERMS)]

    target = chosen.target
    by_res = []
    for res in resolutions:

        def run(res=res):
            mats, _ = sample_matrices(source, p, res, (target,))
            w1, w2 = p.quadrature_weights(res)
            return factorize(mats[target], w1, w2, MAX_AUTO_TERMS, name)

        seconds = _median_time(run, repeats)
        f = run()
        f.target = target
        for e in errors_by_terms(f, reference, l, v, (1, 2, 4, 8), weight=w):
            by_res.append({"resolution": res, "terms": e["terms"], "relative_rms": e["relative_rms"], "seconds": seconds})

    mats, _ = sample_matrices(source, p, FACTOR_RESOLUTION, (target,))
    w1, w2 = p.quadrature_weights(FACTOR_RESOLUTION)
    nmf = []
    for k in NMF_TERMS:
        f = factorize(mats[target], w1, w2, k, name, "nmf")
        f.target = target
        e = errors_by_terms(f, reference, l, v, (k,), weight=w)[0]
        e8 = errors_by_terms(quantize_factors(f), reference, l, v, (k,), weight=w)[0]
        nmf.append({"terms": k, "relative_rms": e["relative_rms"], "relative_rms_8bit": e8["relative_rms"]})
    f = factorize(mats[target], w1, w2, 1, name, "nd")
    f.target = target
    nd = {
        "terms": 1,
        "relative_rms": errors_by_terms(f, reference, l, v, (1,), weight=w)[0]["relative_rms"],
        "relative_rms_8bit": errors_by_terms(quantize_factors(f), reference, l, v, (1,), weight=w)[0]["relative_rms"],
    }

    def stage_times():
        t0 = time.perf_counter()
        mats, _ = sample_matrices(source, p, FACTOR_RESOLUTION, (target,))
        t1 = time.perf_counter()
        f = factorize(mats[target], w1, w2, chosen.terms, name, params["factorization"])
        t2 = time.perf_counter()
        encode_factor_slices(factors_to_slices(f))
        return {"sample_s": t1 - t0, "svd_s": t2 - t1, "quantize_s": time.perf_counter() - t2}

    stage = [stage_times() for _ in range(repeats)]
    timings = {k: float(np.median([s[k] for s in stage])) for k in ("sample_s", "svd_s", "quantize_s")}
    timings["error_s"] = chosen.timings["error_s"]

    atlas = None
    if atlas_path is not None:
        atlas = {"path": Path(atlas_path).as_posix()}
        manifest = read_atlas(atlas_path).manifest if manifest is None else manifest
        entry = manifest.entry_named(material.name)
        if entry is not None and entry.content_hash and material.content_hash and entry.content_hash != material.content_hash:
            # Measured, it compared another bake of the material with this one (672% for another roughness).
            atlas["other_bake"] = True
            atlas["missing"] = (f"{material.name!r} in this atlas is another bake of it (its content hash differs from "
                                "the material file's); re-run atlasgen bake to measure this one")  # fmt: skip
        else:
            try:
                got = evaluate_separable(atlas_path, material.name, np.array([0.0, 0.0, 1.0]), l, v, cosine=True)
                atlas.update(measure_errors(reference, got, w))
            except InputError as exc:
                atlas["missing"] = str(exc)

    # The speed axis is what a frame pays, the lighting pass's cost of K terms (the shipped cost
    # table, measured by `make bench`), not the bake's time, which nobody pays at run time.
    table = read_lighting_cost()
    for r in by_res:
        r["cost"] = table.cost(cost_key("separable", r["terms"]))
    points = sorted({(r["cost"], r["relative_rms"], r["resolution"], r["terms"], r["seconds"]) for r in by_res})
    front, best = [], np.inf
    for cost, err, res, k, seconds in points:
        if err < best:
            front.append({"cost": cost, "seconds": seconds, "relative_rms": err, "resolution": res, "terms": k})
            best = err

    return MaterialStudy(
        name=material.name,
        source=material.source,
        chosen={
            "parametrization": name,
            "target": target,
            "terms": chosen.terms,
            "grid": chosen.grid,
            "factorization": params["factorization"],
            "float": chosen.errors,
            "8bit_srgb": {
                k: v
                for k, v in next(e for e in chosen.errors_8bit_by_terms[target] if e["terms"] == chosen.terms).items()
                if k != "terms"
            },
        },
        by_terms=by_terms,
        by_parametrization=by_param,
        by_resolution=by_res,
        nonnegative={"nmf": nmf, "nd": nd},
        timings=timings,
        atlas=atlas,
        pareto=front,
    )


#: Figure size of every plot in inches (shown at 100 CSS px per inch: two side by side on the page).
_PLOT_SIZE = (5.8, 3.9)


def _plots(study: MaterialStudy, folder: Path, charts: dict | None = None) -> dict:
    """The study's four plots written into ``folder``, ``{kind: path}``; ``charts`` (when given) gets
    each plot's :class:`~atlasgen.reports.html.Chart` (its size and placed labels), by kind."""
    paths = {}
    charts = {} if charts is None else charts
    ks = np.arange(1, MAX_AUTO_TERMS + 1)

    def save(fig, ax, kind: str, xlabel: str, ylabel: str, title: str) -> None:
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.set_title(f"{study.name}: {title}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        paths[kind] = folder / f"{study.name}-{kind}.png"
        charts[kind] = figure_chart(fig)  # the front's labels go over the image, as text
        paths[kind].write_bytes(charts[kind].png)

    with plot_style() as plt:
        fig, ax = plt.subplots(figsize=_PLOT_SIZE)
        for target, curves in study.by_terms.items():
            ax.semilogy(ks, curves["float"], "o-", label=f"SVD {target}, float")
            ax.semilogy(ks, curves["8bit"], "s--", label=f"SVD {target}, 8-bit sRGB")
        ax.semilogy(
            [e["terms"] for e in study.nonnegative["nmf"]],
            [e["relative_rms"] for e in study.nonnegative["nmf"]],
            "^:",
            label="NMF, float",
        )
        ax.semilogy([1], [study.nonnegative["nd"]["relative_rms"]], "kx", markersize=9, label="Kautz-McCool ND, float")
        save(fig, ax, "terms", "terms K (atlas slices)", "relative RMS of f cos", "error against K")

        fig, ax = plt.subplots(figsize=_PLOT_SIZE)
        for k in (1, 2, 4, 8):
            rows = [r for r in study.by_resolution if r["terms"] == k]
            ax.semilogy([r["resolution"] for r in rows], [r["relative_rms"] for r in rows], "o-", label=f"K = {k}")
        ax.axvline(FACTOR_RESOLUTION, color="grey", ls=":", label="stored grid (32)")
        save(
            fig, ax, "resolution", "sampling grid, texels per factor axis", "relative RMS of f cos (float)", "error against grid"
        )

        fig, ax = plt.subplots(figsize=_PLOT_SIZE)
        xs = [r["cost"] for r in study.by_resolution]
        ys = [r["relative_rms"] for r in study.by_resolution]
        ax.loglog(xs, ys, "o", alpha=0.4, label="(grid, K): table below")
        front = [(p["cost"], p["relative_rms"]) for p in study.pareto]
        ax.loglog([x for x, _ in front], [y for _, y in front], "r-o", label="Pareto front")
        label_points(ax, front, [f"{p['resolution']}/K{p['terms']}" for p in study.pareto])
        table = read_lighting_cost()
        save(
            fig,
            ax,
            "pareto",
            f"lighting cost ({table.unit}), {table.device}",
            "relative RMS of f cos (float)",
            "error against run-time cost",
        )

        fig, ax = plt.subplots(figsize=_PLOT_SIZE)
        for name, curve in study.by_parametrization.items():
            ax.semilogy(ks, curve, "o-" if name in ("half_diff", "in_out") else ".:", label=name)
        save(fig, ax, "parametrization", "terms K", "relative RMS (float, best target)", "parametrizations, 32-texel grid")
    return paths


def _pct(x) -> str:
    return f"{100 * x:.2f}%"


def _pct_se(figures: dict, key: str) -> str:
    """``figures[key]`` as a percentage, with its standard error (``key + "_se"``) where it has one."""
    se = figures.get(f"{key}_se")
    return _pct(figures[key]) + ("" if se is None else f" ± {100 * se:.2f}%")


def format_separable_report(studies: list, plots: dict) -> str:
    lines = [
        "# Separable BRDFs: error against terms, grid, bits and time",
        "",
        "Generated by `atlasgen report separable`. Every figure is measured by the running code: relative RMS",
        "and Löw 2012 log error of f cos(theta_l) over the hemisphere, estimated as the bake estimates it (100,000",
        "(l, v) pairs drawn from the source's lobe and weighted back to uniform, fixed seed; ± one standard error),",
        "so the chosen figures are the manifest's; 8-bit figures quantize the factors as an sRGB atlas stores them.",
        "See docs/separable.md.",
        "",
        "| material | parametrization | target | K (factorization) | sampling grid | float rel. RMS | 8-bit rel. RMS | log error | sample + factor + quantize on 32 (ms) | atlas rel. RMS |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s in studies:
        lines.append("| " + " | ".join(str(c) for c in _summary_cells(s)) + " |")
    for s in studies:
        lines += ["", f"## {s.name}", "", f"Source file: `{s.source}`.", ""]
        lines += [
            "### Error against K (float and 8-bit), SVD against NMF and ND",
            "",
            f"![error against K]({plots[s.name]['terms'].name})",
            "",
            "| K | " + " | ".join(f"{t} float | {t} 8-bit" for t in s.by_terms) + " |",
            "|---|" + "---|---|" * len(s.by_terms),
        ]
        for k in range(MAX_AUTO_TERMS):
            lines.append(
                f"| {k + 1} | " + " | ".join(f"{_pct(c['float'][k])} | {_pct(c['8bit'][k])}" for c in s.by_terms.values()) + " |"
            )
        nmf = ", ".join(
            f"K={e['terms']}: {_pct(e['relative_rms'])} float / {_pct(e['relative_rms_8bit'])} 8-bit"
            for e in s.nonnegative["nmf"]
        )
        nd = s.nonnegative["nd"]
        lines += [
            "",
            f"Non-negative alternatives (no bias, full 8-bit range): NMF {nmf}; Kautz-McCool ND (K=1): "
            f"{_pct(nd['relative_rms'])} float / {_pct(nd['relative_rms_8bit'])} 8-bit.",
            "",
        ]
        lines += [
            "### Error against the sampling grid",
            "",
            f"![error against grid]({plots[s.name]['resolution'].name})",
            "",
            "| grid | K=1 | K=2 | K=4 | K=8 | sample + SVD (ms) |",
            "|---|---|---|---|---|---|",
        ]
        for res in sorted({r["resolution"] for r in s.by_resolution}):
            rows = {r["terms"]: r for r in s.by_resolution if r["resolution"] == res}
            lines.append(
                f"| {res} | "
                + " | ".join(_pct(rows[k]["relative_rms"]) for k in (1, 2, 4, 8))
                + f" | {1e3 * rows[1]['seconds']:.1f} |"
            )
        lines += [
            "",
            "### Error against run-time cost (Pareto front)",
            "",
            f"![pareto]({plots[s.name]['pareto'].name})",
            "",
            "Run-time cost: the lighting pass per pixel per light, from atlasgen/data/lighting_cost.json.",
            "",
            "Front: "
            + ", ".join(
                f"grid {p['resolution']} K={p['terms']}: {p['cost']:.3g} ns/pixel/light, {_pct(p['relative_rms'])}"
                for p in s.pareto
            )
            + ".",
            "",
        ]
        lines += [
            "### Parametrizations (same 32-texel grid, same K)",
            "",
            f"![parametrizations]({plots[s.name]['parametrization'].name})",
            "",
            "| parametrization | K=1 | K=2 | K=4 | K=8 |",
            "|---|---|---|---|---|",
        ]
        for name, curve in s.by_parametrization.items():
            lines.append(f"| {name} | " + " | ".join(_pct(curve[k - 1]) for k in (1, 2, 4, 8)) + " |")
        lines += ["", _timings_text(s), ""]
    return "\n".join(lines) + "\n"


def _factorization(s: MaterialStudy) -> str:
    """The factorization of the chosen terms, as the page names it ("NMF"); studies written before it was recorded, SVD."""
    return str(s.chosen.get("factorization") or "svd").upper()


def _summary_cells(s: MaterialStudy) -> list:
    t = s.timings
    missing = "another bake" if (s.atlas or {}).get("other_bake") else "not in atlas"
    atlas = "" if s.atlas is None else (s.atlas.get("missing", "") and missing) or _pct_se(s.atlas, "relative_rms")
    return [
        s.name,
        s.chosen["parametrization"],
        s.chosen["target"],
        # The factorization the bake used: a MaterialX gold's 8-bit figure at K = 6 is its NMF's, in no SVD table.
        f"{s.chosen['terms']} ({_factorization(s)})",
        s.chosen["grid"],
        _pct_se(s.chosen["float"], "relative_rms"),
        _pct_se(s.chosen["8bit_srgb"], "relative_rms"),
        f"{s.chosen['float']['log_error']:.4g}",
        f"{1e3 * (t['sample_s'] + t['svd_s'] + t['quantize_s']):.1f}",
        atlas,
    ]


def _timings_text(s: MaterialStudy) -> str:
    t = s.timings
    return (
        f"Timings (median of repeated runs): sampling {1e3 * t['sample_s']:.1f} ms, "
        f"{_factorization(s)} {1e3 * t['svd_s']:.1f} ms, "
        f"quantization {1e3 * t['quantize_s']:.1f} ms; error measurement {1e3 * t['error_s']:.1f} ms."
    )


def _html_blocks(s: MaterialStudy, plots: dict) -> list[dict]:
    """Per plot of one study: its title, its file, a line of text and the table of its figures."""
    nmf = ", ".join(f"K={e['terms']}: {_pct(e['relative_rms'])} float / {_pct(e['relative_rms_8bit'])} 8-bit"
                    for e in s.nonnegative["nmf"])  # fmt: skip
    nd = s.nonnegative["nd"]
    front = {(p["resolution"], p["terms"]) for p in s.pareto}
    grids = sorted({r["resolution"] for r in s.by_resolution})
    by_grid = {res: {r["terms"]: r for r in s.by_resolution if r["resolution"] == res} for res in grids}
    return [
        {"title": "Error against K (float and 8-bit), SVD against NMF and ND", "plot": plots["terms"].name,
         "text": f"Non-negative alternatives (no bias, full 8-bit range): NMF {nmf}; Kautz-McCool ND (K=1): "
                 f"{_pct(nd['relative_rms'])} float / {_pct(nd['relative_rms_8bit'])} 8-bit.",
         "header": ["K", *(f"{t} {b}" for t in s.by_terms for b in ("float", "8-bit"))],
         "rows": [{"cells": [k + 1, *(v for c in s.by_terms.values() for v in (_pct(c["float"][k]), _pct(c["8bit"][k])))]}
                  for k in range(MAX_AUTO_TERMS)]},
        {"title": "Error against the sampling grid", "plot": plots["resolution"].name, "text": "",
         "header": ["grid", "K=1", "K=2", "K=4", "K=8", "sample + SVD (ms)"],
         "rows": [{"cells": [res, *(_pct(by_grid[res][k]["relative_rms"]) for k in (1, 2, 4, 8)),
                             f"{1e3 * by_grid[res][1]['seconds']:.1f}"]} for res in grids]},
        {"title": "Error against run-time cost (Pareto front)", "plot": plots["pareto"].name,
         "text": "Run-time cost is the lighting pass's time per pixel per light for K terms, from the cost table "
                 "`make bench` measures (atlasgen/data/lighting_cost.json); the grid changes the bake, not the shader. "
                 "The plot labels the front (grid/K); every (grid, K) configuration is listed here, the front in bold.",
         "header": ["grid", "K", "run-time cost (ns/pixel/light)", "bake: sample + SVD (ms)", "float rel. RMS", "on the front"],
         "rows": [{"front": (r["resolution"], r["terms"]) in front,
                   "cells": [r["resolution"], r["terms"], f"{r['cost']:.3g}", f"{1e3 * r['seconds']:.1f}", _pct(r["relative_rms"]),
                             "yes" if (r["resolution"], r["terms"]) in front else ""]}
                  for r in sorted(s.by_resolution, key=lambda r: (r["cost"], r["relative_rms"]))]},
        {"title": "Parametrizations (same 32-texel grid, same K)", "plot": plots["parametrization"].name, "text": "",
         "header": ["parametrization", "K=1", "K=2", "K=4", "K=8"],
         "rows": [{"cells": [name, *(_pct(curve[k - 1]) for k in (1, 2, 4, 8))]} for name, curve in s.by_parametrization.items()]},
    ]  # fmt: skip


def format_separable_html(studies: list, plots: dict, charts: dict | None = None) -> bytes:
    """The report as one HTML page (UTF-8 bytes), the plots beside it: the figures of
    :func:`format_separable_report`, with a table under each plot; ``charts`` (``{name: {kind: Chart}}``,
    from :func:`_plots`) places each plot's point labels over it."""
    pages = []
    for s in studies:
        blocks = _html_blocks(s, plots[s.name])
        for block, kind in zip(blocks, ("terms", "resolution", "pareto", "parametrization")):
            block["chart"] = ((charts or {}).get(s.name) or {}).get(kind) or Chart(b"", *_css_size(_PLOT_SIZE))
        pages.append({"name": s.name, "anchor": "material-" + s.name, "source": s.source, "summary": _summary_cells(s),
                      "blocks": blocks, "timings": _timings_text(s)})  # fmt: skip
    return render_page("separable.html.j2", studies=pages)


def _css_size(size) -> tuple[int, int]:
    return round(size[0] * CSS_PX_PER_INCH), round(size[1] * CSS_PX_PER_INCH)


#: How a bake that stores no separable terms is named.
_STORED = {"lut": "one LUT slice", "analytic": "the closed form"}


def _no_terms_clause(material, kind: str) -> str:
    how = "its budget's choice" if material.params["representation"] == "auto" else "its representation"
    # A MaterialX document has no representation field: its material is named instead.
    field = material.name if material.params["source"] == "materialx" else "representation"
    return (f"{material.source}: field {field!r}: material {material.name!r} bakes as {_STORED.get(kind, kind)} "
            f"({how}), not separable terms: there are none to study")  # fmt: skip


def _refuse_no_terms(refused) -> None:
    """Refuse ``(material, kind)`` pairs whose bake stores no separable terms: their study's "chosen" row would
    report terms the atlas does not hold."""
    if refused:
        clauses = "; ".join(_no_terms_clause(m, kind) for m, kind in refused)
        if all(m.params["source"] == "materialx" for m, _ in refused):
            expected = "the document's materials that bake as terms, named (atlasgen report separable NAME -m DOC.mtlx)"
        else:
            expected = 'representation = "separable", or "auto" where its budget chooses terms'
        raise InputError(f"{clauses}; expected {expected}")


def with_atlas_renamed(message: str, old: str, new: str) -> str:
    """``message`` with the atlas ``old`` and its manifest beside it named as ``new`` and its manifest.

    >>> with_atlas_renamed("a/x.json: no material 'm'", "a/x.dds", "../a/x.dds")
    "../a/x.json: no material 'm'"
    """
    for suffix in (".json", Path(old).suffix):
        message = message.replace(Path(old).with_suffix(suffix).as_posix(), Path(new).with_suffix(suffix).as_posix())
    return message


def rebase_study_paths(study: MaterialStudy, start, folder) -> None:
    """Give ``study``'s material file and atlas, paths from ``start`` (``"."`` where they were typed, a report's folder
    in a merge), from ``folder`` (the report's), as validation gives its atlas: as typed, the same inputs wrote other
    bytes from another working folder."""
    if isinstance(study.source, str):
        study.source = rebase_path(study.source, start, folder)
    atlas = study.atlas
    if isinstance(atlas, dict) and isinstance(atlas.get("path"), str):
        old, atlas["path"] = atlas["path"], rebase_path(atlas["path"], start, folder)
        if isinstance(atlas.get("missing"), str):  # the reader's message names the atlas (or its manifest) as given
            atlas["missing"] = with_atlas_renamed(atlas["missing"], old, atlas["path"])


def write_separable_report(
    materials,
    output,
    atlas_path=None,
    resolutions=RESOLUTIONS,
    repeats: int = 5,
    parametrizations=tuple(PARAMETRIZATIONS),
    on_material=None,
    skip_without_terms: bool = False,
) -> dict:
    """Study each separable material and write ``index.html``, ``index.md``, ``report.json`` and PNG plots into ``output``.

    The files appear all at once (:func:`atlasgen.io.atomic.staged_folder`). Returns the
    written paths. ``on_material(name, done, total)``, when given, is called after each
    material's study. Raises :class:`InputError` when a material is not separable, or its bake stores no terms
    (with ``skip_without_terms``, the whole folder's report, such a material is left out instead), or two share a
    name (their studies would share one set of plots); :class:`OutputError` when the folder cannot be written.
    """
    check_unique_names(list(materials))
    others = [m for m in materials if not isinstance(m.model, Separable)]
    materials = [m for m in materials if isinstance(m.model, Separable)]
    if others:  # named beside separable ones, they were left out without a word
        raise InputError("; ".join(f"{m.source}: field 'type': material {m.name!r} is {m.type!r}, not separable"
                                   for m in others) + f'; expected type = "{Separable.type_name}"')  # fmt: skip
    if not materials:
        raise InputError(f'no separable materials to report on; expected materials with type = "{Separable.type_name}"')
    manifest = None
    if atlas_path is not None:
        # A missing or damaged atlas, or one without its manifest, is refused, not reported as "not in atlas".
        read = read_atlas(atlas_path)
        manifest = read.manifest
        if manifest is None:
            shown = Path(atlas_path).as_posix()
            raise InputError(f"{shown}: no manifest beside the atlas (expected {Path(atlas_path).with_suffix('.json').as_posix()}); "
                             f"re-run atlasgen bake -o {shown}")  # fmt: skip
        # As info and report library do: an entry edited to a parametrization no model has failed deep in the study
        # (an internal error), and one edited to another target or type was measured as it is not stored.
        check_manifest_models(manifest, read.manifest_path.as_posix())
    folder = Path(output)
    refuse_another_report(folder, "separable")  # before the studies' minutes of work
    # The terms each bake stores: an "auto" material's chosen K, grid, factorization and target, where its own
    # values named none (a MaterialX material's study factored gold as K = 3 by SVD, its bake as K = 6 by NMF).
    stored = [m.model.stored_terms(m.params) for m in materials]
    if skip_without_terms:  # every separable material of a folder: those that store no terms are not asked for
        kept = [i for i, (_, values) in enumerate(stored) if values is not None]
        if not kept:
            raise InputError("no material stores separable terms to report on (each bakes as one LUT slice or the closed "
                             'form); expected materials with representation = "separable", or "auto" where its budget '
                             "chooses terms")  # fmt: skip
        materials, stored = [materials[i] for i in kept], [stored[i] for i in kept]
    _refuse_no_terms([(m, kind) for m, (kind, values) in zip(materials, stored) if values is None])
    studies = []
    for done, (m, (_, values)) in enumerate(zip(materials, stored), 1):
        studies.append(study_material(m, atlas_path, resolutions, repeats, parametrizations, params=values,
                                      manifest=manifest))  # fmt: skip
        if on_material is not None:
            on_material(m.name, done, len(materials))
    for s in studies:
        rebase_study_paths(s, ".", folder)
    # Staged, then moved into place: an interrupted run never leaves a half-written
    # report that ``make`` would take as up to date.
    with staged_folder(folder, primary="report.json", whole=True) as staging:
        charts: dict = {s.name: {} for s in studies}
        plots = {s.name: _plots(s, staging, charts[s.name]) for s in studies}
        for s in studies:
            s.charts = {
                kind: {"width": c.width, "height": c.height, "labels": list(c.labels)} for kind, c in charts[s.name].items()
            }
        (staging / "index.md").write_text(format_separable_report(studies, plots))
        (staging / "index.html").write_bytes(format_separable_html(studies, plots, charts))
        (staging / "report.json").write_text(json.dumps([s.__dict__ for s in studies], indent=1, default=float) + "\n")
    plots = {name: {kind: folder / path.name for kind, path in kinds.items()} for name, kinds in plots.items()}
    return {"markdown": folder / "index.md", "html": folder / "index.html", "json": folder / "report.json", "plots": plots}
