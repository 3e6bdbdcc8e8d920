"""One HTML page over the whole material library: representation, errors, run-time cost against error, bake time, previews."""

from __future__ import annotations

import os
from pathlib import Path

from atlasgen.bake.preview import slice_png
from atlasgen.errors import FieldError, InputError, OutputError
from atlasgen.io.atlas import read_atlas
from atlasgen.io.atomic import write_files_atomically
from atlasgen.io.fields import counted
from atlasgen.io.manifest import AnalyticRepresentation, LutRepresentation, MaterialEntry, SeparableRepresentation
from atlasgen.io.report_files import check_number, read_json_file
from atlasgen.io.text import special_file_kind
from atlasgen.models import check_manifest_models, check_manifest_params, get_model
from atlasgen.reports.comparisons import manifest_pairs
from atlasgen.reports.html import (
    CSS_PX_PER_INCH,
    Chart,
    figure_chart,
    label_points,
    legend_beside,
    pareto_front,
    plot_style,
    render_page,
    series_style,
)
from atlasgen.reports.pareto import (
    MAX_JOBS,
    baked_candidate,
    cache_files,
    front_flags,
    library_candidates,
    plot_library,
    plot_material,
)
from atlasgen.reports.report_kind import folder_report_kind
from atlasgen.reports.validation import check_result_figures
from atlasgen.separable.auto import cost_key, read_lighting_cost
from atlasgen.validate.identity import atlas_identity, identity_problem

__all__ = ["write_library_report"]

#: The library's cost/error plot: its file and its size in inches (shown at 100 CSS px per inch).
_PLOT = "cost-vs-error.png"
_PLOT_SIZE = (7.0, 4.5)
_SMALL_PLOT_SIZE = (3.6, 2.8)
#: The Pareto charts against the physical reference: the library's, and one per material under ``pareto/``.
_PARETO_PLOT = "pareto.png"
_PARETO_DIR = "pareto"
_PARETO_SIZE = (7.5, 5.0)
_PARETO_SMALL_SIZE = (5.0, 3.6)


def _cost_key(entry: MaterialEntry, terms=None) -> str:
    """The run-time cost table's key of ``entry``'s representation (with ``terms`` for a K)."""
    rep = entry.representation
    if isinstance(rep, AnalyticRepresentation):
        return cost_key("analytic", rep.distribution)
    if entry.factors is not None:
        return cost_key("separable", terms if terms is not None else (entry.factors.terms or entry.factors.term_slices))
    return cost_key("lut")


def _runtime_candidates(entry: MaterialEntry, table) -> list[dict]:
    """What ``entry`` could be drawn as, each ``{"representation", "cost", "error", "measure", "chosen"}``:
    the ``auto`` choice's candidates as recorded, each factorization its own (in the measure of the
    material's error budget, which is not the manifest's); a separable material's K = 1..8 at its grid
    and target (estimated 8-bit relative RMS of f cos); else the one representation baked, its
    error the manifest's (quantisation RMS for a LUT, 0 for a closed form)."""
    rep = entry.representation
    # A LUT chosen by ``representation = "auto"`` records the choice beside its LUT representation.
    auto = getattr(rep, "auto", None)
    if auto:
        # An SVD and an NMF candidate share a K: each is named by its factorization, and only the one baked is chosen.
        # A representation = "lut" bake records no cost: the table's.
        baked = entry.factors.factorization if entry.factors is not None else None
        return [{"representation": c["representation"] + (f" ({c['factorization']})" if c.get("factorization") else ""),
                 "cost": c["cost"] if "cost" in c else table.costs.get(c["representation"]), "error": c["error"], "measure": c.get("error_kind") or auto.get("error_measure"),
                 "chosen": c["representation"] == auto["chosen"] and c.get("factorization") in (None, baked)}
                for c in auto["candidates"]]  # fmt: skip
    if isinstance(rep, SeparableRepresentation):
        curve = next((c.get("relative_rms_by_terms") for c in rep.candidates
                      if c.get("grid") == rep.sampling_grid and c.get("target") == rep.target), None)  # fmt: skip
        if curve:
            return [{"representation": _cost_key(entry, k + 1), "cost": table.costs.get(_cost_key(entry, k + 1)),
                     "error": e, "measure": "estimated relative RMS of f cos, 8-bit", "chosen": k + 1 == rep.terms}
                    for k, e in enumerate(curve)]  # fmt: skip
    if isinstance(rep, AnalyticRepresentation):
        error, measure = 0.0, "0: a closed form evaluated in the shader"
    elif entry.factors is not None and entry.factors.errors_8bit is not None:
        error, measure = entry.factors.errors_8bit.relative_rms, "estimated relative RMS of f cos, 8-bit"
    else:
        error, measure = entry.quantization_error.rms, "quantisation RMS"
    chosen = _cost_key(entry)
    return [{"representation": chosen, "cost": table.costs.get(chosen), "error": error, "measure": measure, "chosen": True}]


def _refuse_file_as_folder(folder, role: str, command: str) -> None:
    """Refuse ``folder`` (a report's ``role``) where it is a file, a pipe or a device: the folder ``command -o`` wrote
    is wanted."""
    if folder is not None and Path(folder).exists() and not Path(folder).is_dir():
        kind = special_file_kind(folder) or "a file"
        raise InputError(f"{Path(folder).as_posix()}: {role} is {kind}; expected the folder {command} -o wrote")


def _refuse_another_report(folder, kind: str, role: str, command: str) -> None:
    """Refuse ``folder`` (a report's ``role``) where its ``report.json`` is another command's report: a validation
    folder given as --separable was linked from the page as the separable factorisation report, without a word."""
    found = folder_report_kind(folder) if folder is not None else None
    if found is not None and found != kind:
        path = (Path(folder) / "report.json").as_posix()
        raise InputError(f"{path}: {role} holds a {found} report; expected the folder {command} -o wrote")


def _read_validation(folder) -> dict | None:
    """``folder/report.json`` of atlasgen validate, or None where the folder has none (a library not validated yet).

    Only its results are read, so only they are checked (their figures must be numbers); a folder that is a
    file, a report that is no JSON object (``null`` read as none) or has no results is refused, naming it."""
    if folder is None:
        return None
    folder = Path(folder)
    _refuse_file_as_folder(folder, "the validation report (--validation)", "atlasgen validate")
    path = folder / "report.json"
    if not path.exists():
        return None
    validation = read_json_file(path)
    if not isinstance(validation, dict):
        got = "null" if validation is None else type(validation).__name__
        raise FieldError(path.as_posix(), None, f"expected a validation report (a JSON object), got {got}")
    if "results" not in validation:
        raise FieldError(path.as_posix(), "results", "missing; expected the list of results atlasgen validate writes")
    check_result_figures(path, validation["results"])
    return validation


def _bake_seconds(timings, path, name: str) -> float | None:
    """``materials.<name>.bake_s`` of a bake's timings file: a finite number, or None where absent."""
    if not isinstance(timings, dict):
        got = "null" if timings is None else type(timings).__name__
        raise FieldError(Path(path).as_posix(), None, f"expected a bake's timings (a JSON object), got {got}")
    materials = timings.get("materials", {})
    if not isinstance(materials, dict):
        raise FieldError(Path(path).as_posix(), "materials", f"expected an object of per-material timings, got {materials!r}")
    entry = materials.get(name, {})
    if not isinstance(entry, dict):
        raise FieldError(Path(path).as_posix(), f"materials.{name}", f"expected an object of timings, got {entry!r}")
    return check_number(path, f"materials.{name}.bake_s", entry.get("bake_s"), minimum=0.0)


def _check_identity(validation: dict | None, atlas, report_path: Path, warn, note) -> tuple[dict | None, dict]:
    """The validation report with only the results measured on the materials of ``atlas`` as they are now, and
    ``{material: note}`` for each material whose results were not (:mod:`atlasgen.validate.identity`).

    A material whose recorded identity differs was validated on another bake of it: its results are dropped, and
    its note says so. A report that records none (written before atlasgen recorded it) cannot be checked: its
    results stay, marked unverified. ``warn`` gets one line per material dropped and one for an unverifiable report.
    Results of materials the atlas does not hold are left out (nothing on the page is theirs), as a scene atlas leaves
    out most of the library's report; ``note`` gets one line naming them, which the command prints with ``-v``.
    """
    if validation is None:
        return None, {}
    shown = report_path.as_posix()
    kept, notes, unverified, absent = [], {}, [], []
    current = {e.name: atlas_identity(atlas, e) for e in atlas.manifest.materials}
    for row in validation.get("results", []):
        name = row.get("material")
        if name not in current:
            if name not in absent:
                absent.append(name)
            continue
        if not isinstance(row.get("atlas_identity"), dict):
            kept.append(row)
            if name not in unverified:
                unverified.append(name)
                notes[name] = ("unverified", f"{shown} records no identity of the atlas it validated (written by an older "
                               "atlasgen), so these figures may be of another bake of it; re-run atlasgen validate")  # fmt: skip
            continue
        why = identity_problem(row["atlas_identity"], current[name])
        if why is None:
            kept.append(row)
        elif name not in notes:
            notes[name] = ("stale", f"not validated on this atlas: {shown} measured another bake of it, and {why}; "
                               "re-run atlasgen validate")  # fmt: skip
            warn(f"{shown}: the validation figures of {name!r} were measured on another bake of it than "
                 f"{atlas.manifest_path.as_posix()}'s ({why}); not shown: re-run atlasgen validate")  # fmt: skip
    if unverified:
        warn(f"{shown}: records no identity of the atlas it validated (written by an older atlasgen), so the figures of "
             f"{', '.join(unverified)} cannot be checked against {atlas.manifest_path.as_posix()}; shown as unverified: "
             "re-run atlasgen validate")  # fmt: skip
    if absent:
        note(f"{shown}: left out the figures of {counted(len(absent), 'material')} {atlas.manifest_path.as_posix()} does "
             f"not hold: {', '.join(map(str, absent))}")  # fmt: skip
    return {**validation, "results": kept}, notes


def _validation_rows(validation: dict | None, name: str) -> list[dict]:
    """Per-reference metrics of one material from validate's report.json, whatever refs it has."""
    rows = []
    for result in (validation or {}).get("results", []):
        if result.get("material") == name:
            for kind, ref in result.get("references", {}).items():
                rows.append(
                    {
                        "reference": f"{result.get('scene', '?')}/{kind}",
                        "psnr": ref.get("psnr_db"),
                        "flip": ref.get("flip"),
                        "speed_ratio": ref.get("speed_ratio"),
                        "linear_rmse": ref.get("linear_rmse"),
                    }
                )
    return rows


def _validation_pages(validation: dict | None, name: str) -> list[str]:
    """The per-material validation pages of one material (``page`` of a merged report), in
    report order, relative to the validation folder."""
    pages = [r["page"] for r in (validation or {}).get("results", []) if r.get("material") == name and r.get("page")]
    return list(dict.fromkeys(pages))


def _fmt(x, spec=".3g"):
    return "–" if x is None else format(x, spec)


def _oracle_error(entry: MaterialEntry) -> str:
    """A MaterialX material's error against the oracle: relative RMS of f cos ± its SE, 8-bit, on the
    report sample (independent of the fit's): the atlas's measured factors, else the bake's estimate."""
    rep = entry.representation
    if isinstance(rep, LutRepresentation):
        auto = rep.auto or {}
        chosen = next((c for c in auto.get("candidates", []) if c.get("representation") == auto.get("chosen")), {})
        return f"{rep.reconstruction_error:.4f} ± {_fmt(chosen.get('error_se'), '.4f')} (one LUT slice)"
    factors = entry.factors
    if factors is not None and factors.errors_8bit is not None:
        e = factors.errors_8bit
        return f"{e.relative_rms:.4f} ± {_fmt(e.relative_rms_se, '.4f')} (K = {factors.terms or factors.term_slices}, measured on the atlas)"
    if isinstance(rep, SeparableRepresentation):
        return f"{rep.estimated_error_8bit:.4f} ± {_fmt(rep.estimated_error_8bit_se, '.4f')} (K = {rep.terms}, estimated)"
    return "–"


def _materialx_rows(entries, validation: dict | None, validation_dir, out_dir: Path) -> list[dict]:
    """One row per material imported from a MaterialX document: its document and name in it, its
    surface model, the representation chosen, its error against the oracle ± SE, what the table
    could not hold or was flattened, and per validation scene the atlas image beside the oracle's."""
    rows = []
    for entry in entries:
        spec = entry.params.get("materialx") if entry.params.get("source") == "materialx" else None
        if not isinstance(spec, dict):
            continue
        images = []
        for result in (validation or {}).get("results", []):
            model = result.get("references", {}).get("model", {})
            if result.get("material") != entry.name or not model.get("images"):
                continue
            pair = [Path(validation_dir) / result["atlas_image"], Path(validation_dir) / model["images"]["reference"]]
            if all(p.exists() for p in pair):
                images.append({"scene": result.get("scene"), "atlas": os.path.relpath(pair[0], out_dir),
                               "oracle": os.path.relpath(pair[1], out_dir), "psnr": _fmt(model.get("psnr_db"), ".1f")})  # fmt: skip
        rows.append({
            "name": entry.name, "document": spec.get("document"), "material": spec.get("material"),
            "category": spec.get("category"), "representation": get_model(entry.type).describe_representation(entry),
            "error": _oracle_error(entry), "not_in_table": list(spec.get("not_in_table") or []),
            "flattened": get_model(entry.type).flattened_inputs(entry.params),
            "images": images,
        })  # fmt: skip
    return rows


def _physical_section(entries, out_dir: Path, files: dict, jobs: int, warn=None):
    """The Pareto charts against the physical reference (:mod:`atlasgen.reports.pareto`): the library's
    chart, one per material with a projectable reference, every candidate in a table, and one line
    for each material without such a reference. Adds the charts and the candidate cache to ``files``."""
    cache = out_dir / _PARETO_DIR
    results = library_candidates(entries, cache, jobs, warn)
    files.update(cache_files(results, cache))
    chosen = {e.name: baked_candidate(e, results[e.name]) for e in entries}
    materials, without = [], []
    for entry in entries:
        result = results[entry.name]
        if not result.get("candidates"):
            without.append({"name": entry.name, "reason": result.get("reason", "no physical reference")})
            continue
        src = f"{_PARETO_DIR}/{entry.name}.png"
        drawn = plot_material(entry.name, result, chosen[entry.name], _PARETO_SMALL_SIZE)
        files[out_dir / src] = drawn.png
        chart = {"src": src, "chart": drawn}
        front = front_flags(result["candidates"])
        materials.append({
            "name": entry.name, "chart": chart, "reference": result["reference"], "gloss": f"{result['gloss']:g}",
            "sphere": bool(result.get("sphere")), "skipped": result.get("skipped", []),
            "candidates": [{"representation": c["representation"], "cost": _fmt(c["cost"], ".3g"), "error": _fmt(c["error"], ".4g"),
                            "error_se": _fmt(c.get("error_se"), ".2g"), "front": on_front,
                            "chosen": c["representation"] == chosen[entry.name]}
                           for c, on_front in zip(result["candidates"], front)],
        })  # fmt: skip
    plot = None
    if materials:
        files[out_dir / _PARETO_PLOT] = plot_library({m["name"]: results[m["name"]] for m in materials}, chosen, _PARETO_SIZE)
        plot = {
            "src": _PARETO_PLOT,
            "chart": Chart(b"", round(_PARETO_SIZE[0] * CSS_PX_PER_INCH), round(_PARETO_SIZE[1] * CSS_PX_PER_INCH)),
        }
    first = next((results[m["name"]] for m in materials), None)
    sample = None if first is None else {"estimator": first["estimator"], "pairs": first["pairs"], "seed": first["seed"]}
    return {
        "plot": plot,
        "materials": materials,
        "without": without,
        "sample": sample,
    }


def write_library_report(
    atlas_path,
    out_dir,
    validation_dir=None,
    separable_dir=None,
    physical: bool = True,
    jobs: int = MAX_JOBS,
    warn=None,
    note=None,
) -> Path:
    """Write ``out_dir/index.html`` (+ slice previews and a speed-against-error plot).

    Every figure on the page is read from files the toolchain measured: the manifest
    (errors, representation), the timings file (bake time), and, when present,
    ``validation_dir/report.json`` (errors against Mitsuba references; a merged report
    also links each material's own validation page). Only figures measured on the materials of this
    atlas as they are are shown as validated: a material validated on another bake of it reads "not
    validated", and the figures of a report that records no identity are marked unverified (each
    said on one line to ``warn``, where given; what is left out as not this atlas's is said to ``note``). With ``physical``, the Pareto charts of
    run-time cost against error versus the physical reference (:mod:`atlasgen.reports.pareto`),
    their candidates cached under ``out_dir/pareto`` and computed in up to ``jobs`` processes.
    Every file is replaced atomically.

    Raises
    ------
    OutputError
        ``out_dir`` is the validation or separable report's own folder, or inside it: its pages are theirs.
    """
    for folder, role in ((validation_dir, "the validation report (--validation)"),
                         (separable_dir, "the separable report (--separable)")):  # fmt: skip
        if folder is None:
            continue
        theirs, ours = Path(os.path.realpath(folder)), Path(os.path.realpath(out_dir))
        if ours == theirs:
            raise OutputError(f"{Path(out_dir).as_posix()}: the report folder (-o) is {role}'s folder, whose index.html "
                              "it would overwrite; expected a folder of its own")  # fmt: skip
        # Inside it (a material's page folder of a validation copied as plain files), the page replaced one of theirs.
        if theirs in ours.parents:
            raise OutputError(f"{Path(out_dir).as_posix()}: the report folder (-o) is inside {role}'s folder, whose pages "
                              "it could overwrite; expected a folder of its own")  # fmt: skip
    # A file given as the separable report's folder was linked from the page as one, where --validation's is refused.
    _refuse_file_as_folder(separable_dir, "the separable report (--separable)", "atlasgen report separable")
    _refuse_another_report(separable_dir, "separable", "the separable report (--separable)", "atlasgen report separable")
    atlas = read_atlas(atlas_path)
    if atlas.manifest is None:
        raise InputError(f"{Path(atlas_path).as_posix()}: no manifest beside the atlas; run atlasgen bake first")
    check_manifest_models(atlas.manifest, atlas.manifest_path.as_posix())
    if physical:  # the Pareto charts rebuild each material's reference from its params
        check_manifest_params(atlas.manifest, atlas.manifest_path.as_posix())
    timings_path = Path(atlas_path).with_suffix("").as_posix() + ".timings.json"
    # No file: no bake times (an atlas baked before they were kept). A file of null or [] was read as none, every
    # material's bake time shown as '–' without a word.
    timings = read_json_file(timings_path) if Path(timings_path).exists() else {}
    validation = _read_validation(validation_dir)
    validation, validation_notes = _check_identity(validation, atlas, Path(validation_dir or ".") / "report.json",
                                                   warn or (lambda line: None), note or (lambda line: None))  # fmt: skip
    out_dir = Path(out_dir)

    rows, files = [], {}
    table = read_lighting_cost()
    srgb = atlas.manifest.srgb
    chosen_points = []
    for entry in atlas.manifest.materials:
        name = entry.name
        previews = []
        for k, s in enumerate(entry.slices):
            rel = f"slices/{name}-{k}.png"
            files[out_dir / rel] = slice_png(atlas.image.levels[0], s, srgb, zoom=2)
            previews.append(rel)
        bake_s = _bake_seconds(timings, timings_path, name)
        refs = _validation_rows(validation, name)
        candidates = [c for c in _runtime_candidates(entry, table) if c["cost"] is not None]
        chart = None
        if candidates:
            src = f"cost/{name}.png"
            drawn = _plot_cost_error({name: candidates}, table, _SMALL_PLOT_SIZE, name)
            files[out_dir / src] = drawn.png
            chart = {"src": src, "chart": drawn}
            chosen_points += [(name, c) for c in candidates if c["chosen"]]
        rows.append((entry, previews, bake_s, refs, _validation_pages(validation, name), candidates, chart))

    physical_section = _physical_section(atlas.manifest.materials, out_dir, files, jobs, warn) if physical else None
    materialx = _materialx_rows(atlas.manifest.materials, validation, validation_dir, out_dir)
    plot = None
    if chosen_points:
        drawn = _plot_cost_error({n: [c] for n, c in chosen_points}, table, _PLOT_SIZE,
                                 "Library: run-time cost against error", label_all=True)  # fmt: skip
        files[out_dir / _PLOT] = drawn.png
        plot = {"src": _PLOT, "chart": drawn}

    def rel(target) -> str | None:
        return os.path.relpath(target, out_dir) if target is not None and Path(target).exists() else None

    links = [{"href": href, "label": label} for href, label in (
        (rel(Path(validation_dir) / "index.html") if validation_dir else None, "validation report"),
        (rel(Path(separable_dir) / "index.html") if separable_dir else None, "separable factorisation report"),
    ) if href]  # fmt: skip
    page_rows = []
    for entry, previews, bake_s, refs, pages, candidates, chart in rows:
        q = entry.quantization_error
        own = [rel(Path(validation_dir) / page) for page in pages] if validation_dir else []
        page_rows.append({
            "first_slice": entry.first_slice, "name": entry.name, "type": entry.type,
            "representation": get_model(entry.type).describe_representation(entry),
            "bake_s": _fmt(bake_s, ".3g"), "quantisation": (f"{q.max:.4f}", f"{q.rms:.4f}"),
            "refs": [{"reference": r["reference"], "psnr": _fmt(r["psnr"], ".1f"), "flip": _fmt(r["flip"], ".4f"),
                      "speed": _fmt(r["speed_ratio"], ".1f") + "x"} for r in refs],
            "pages": [p for p in own if p], "previews": previews, "chart": chart,
            "validation_note": validation_notes.get(entry.name),
            "runtime": [{"representation": c["representation"], "cost": _fmt(c["cost"], ".3g"), "error": _fmt(c["error"], ".3g"),
                         "chosen": c["chosen"]} for c in candidates],
            "runtime_measures": list(dict.fromkeys(c["measure"] for c in candidates if c["measure"])),
        })  # fmt: skip
    pairs = [
        p
        for entry, *_ in rows
        for p in manifest_pairs(entry.name, None if entry.fit is None else entry.fit.to_json(), validation)
    ]
    index = out_dir / "index.html"
    files[index] = render_page(
        "library.html.j2",
        # From the page, as its links are: the path as typed made the page differ by the folder it was run from.
        atlas=Path(os.path.relpath(atlas_path, out_dir)).as_posix(),
        encoding=atlas.manifest.encoding,
        layout=atlas.manifest.layout,
        links=links,
        plot=plot,
        rows=page_rows,
        pairs=pairs,
        physical=physical_section,
        materialx=materialx,
        cost_device=table.device,
        cost_unit=table.unit,
    )
    # Previews, plots and the page that links them, as one set; the page is the primary (make's target).
    write_files_atomically(files, primary=index, whole=True)
    return index


def _plot_cost_error(series: dict, table, size, title: str, label_all: bool = False) -> Chart:
    """Run-time cost (the shipped cost table, :func:`atlasgen.separable.auto.read_lighting_cost`)
    against error, one marker per candidate; the chosen representation is filled, the Pareto
    front (nothing both cheaper and closer) labelled where there is room, the chosen one first."""
    floor = 1e-6  # a closed form's error is 0: drawn on the axis's floor
    with plot_style() as plt:
        from matplotlib import ticker

        fig, ax = plt.subplots(figsize=size)
        points = []
        for i, (name, candidates) in enumerate(series.items()):
            xs = [c["cost"] for c in candidates]
            ys = [max(c["error"], floor) for c in candidates]
            if label_all:  # one point a material, told apart by its colour and marker in the legend
                ax.scatter(xs, ys, label=name, **series_style(i))
            else:
                ax.scatter(xs, ys, facecolors=["C0" if c["chosen"] else "none" for c in candidates], edgecolors="C0")
            points += [(x, y, name if label_all else c["representation"], c["chosen"]) for x, y, c in zip(xs, ys, candidates)]
        front = [points[i] for i in pareto_front([(p[0], p[1]) for p in points])]
        # The chosen representation's label first: where the front is crowded, later labels give way.
        front.sort(key=lambda p: not p[3])
        label_points(ax, [(p[0], p[1]) for p in front], [p[2] for p in front])
        ax.set_xscale("log")
        ax.set_yscale("log")
        # Costs span less than a decade or two: label 1, 2, 5 x 10^k plainly, not every minor tick in powers of ten.
        ax.xaxis.set_major_locator(ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_major_formatter(ticker.FormatStrFormatter("%g"))
        ax.xaxis.set_minor_formatter(ticker.NullFormatter())
        small = size[0] < 5.0  # a table cell's chart: axis titles short enough to fit it
        ax.set_xlabel(f"lighting cost ({table.unit})")
        ax.set_ylabel("error (rel. RMS)" if small else "error (rel. RMS of f cos; LUT: quantisation RMS)")
        # The device's name is long: on its own line of the title, where it wraps no axis.
        ax.set_title(title if small else f"{title}\non {table.device}", fontsize="medium")
        if label_all:
            # Beside the axes, every material named: inside them a legend hid the points, and over 12 there was none.
            across, down = legend_beside(ax)
            fig.set_size_inches(size[0] + across, max(size[1], down))
        return figure_chart(fig)
