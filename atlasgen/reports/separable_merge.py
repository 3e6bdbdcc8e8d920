"""Merging per-material separable reports into one, without measuring anything again.

``atlasgen report separable`` measures each material for about ten seconds (the
study of :mod:`atlasgen.reports.separable`), so ``make report`` runs it once per
separable material, each into its own folder, and then merges those folders into
the combined ``index.md``, ``report.json`` and plots. A changed material then costs
one study, not one per separable material. The merged Markdown is written by the
report's own formatter from the studies read back from JSON, so a merged report
reads exactly like one written in a single run.
"""

from __future__ import annotations

import json
import math
from dataclasses import MISSING, fields
from pathlib import Path

from atlasgen.contract import NAME_PATTERN
from atlasgen.errors import FieldError, InputError, describe_failure, shorten
from atlasgen.io.atomic import write_files_atomically
from atlasgen.io.field_reads import FieldReads, expected_written
from atlasgen.io.fields import is_number
from atlasgen.io.report_files import check_merge_output, check_number, read_report_json, report_json_paths
from atlasgen.reports.html import Chart
from atlasgen.reports.report_kind import refuse_another_report
from atlasgen.reports.separable import (
    MaterialStudy,
    format_separable_html,
    format_separable_report,
    rebase_study_paths,
)

__all__ = ["PLOT_KINDS", "merge_separable_reports"]

#: The plots :mod:`atlasgen.reports.separable` writes per material, as ``<name>-<kind>.png``.
PLOT_KINDS = ("terms", "resolution", "pareto", "parametrization")


def _read_studies(path: Path) -> list:
    data = read_report_json(path, "separable", "atlasgen report separable")
    known = {f.name for f in fields(MaterialStudy)}
    required = {f.name for f in fields(MaterialStudy) if f.default is MISSING and f.default_factory is MISSING}
    if not isinstance(data, list):
        raise InputError(f"{path.as_posix()}: not a separable report (expected a list of material studies)")
    if not data:
        raise InputError(f"{path.as_posix()}: an empty separable report (expected at least one material study)")
    studies = []
    for index, item in enumerate(data):
        if not isinstance(item, dict) or not required <= set(item) or not set(item) <= known:
            got = ", ".join(sorted(item)) if isinstance(item, dict) else type(item).__name__
            raise InputError(f"{path.as_posix()}: entry {index} is not a material study (expected the fields "
                             f"{', '.join(sorted(required))}; got {got})")  # fmt: skip
        # The name becomes the plots' file names and the merged page's links: "../x" or "a/x" named a file outside the
        # study's folder, and two such studies wrote one plot.
        if not isinstance(item["name"], str) or not NAME_PATTERN.fullmatch(item["name"]):
            raise InputError(f"{path.as_posix()}: entry {index}: expected a material name (a letter then letters, digits, "
                             f"'-' or '_', at most 63), got {shorten(repr(item['name']))}")  # fmt: skip
        _check_chosen(path, f"[{index}]", item)
        studies.append(MaterialStudy(**item))
    return studies


def _check_chosen(path: Path, where: str, item: dict) -> None:
    """Refuse a study whose summary row would print what no study measures: the merged table printed a
    relative RMS of -0.5 as "-50.00%" and ``terms = "three"`` as written (``validate --merge`` refuses both)."""
    chosen = item["chosen"]
    if not isinstance(chosen, dict):
        raise FieldError(path.as_posix(), f"{where}.chosen", f"expected an object, got {type(chosen).__name__}")
    for key in ("terms", "grid"):
        value = chosen.get(key)
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise FieldError(
                path.as_posix(), f"{where}.chosen.{key}", f"expected a whole number >= 1, got {shorten(repr(value))}"
            )
    for part in ("float", "8bit_srgb"):
        figures = chosen.get(part)
        if not isinstance(figures, dict):
            raise FieldError(path.as_posix(), f"{where}.chosen.{part}", f"expected an object, got {shorten(repr(figures))}")
        check_number(path, f"{where}.chosen.{part}.relative_rms", figures.get("relative_rms"), allow_none=False, minimum=0)
    _check_chosen_against_by_terms(path, where, chosen, item.get("by_terms"))
    timings = item["timings"]
    if isinstance(timings, dict):
        for key, value in timings.items():
            check_number(path, f"{where}.timings.{key}", value, minimum=0)
    _check_rows(path, where, item)


def _check_chosen_against_by_terms(path: Path, where: str, chosen: dict, by_terms) -> None:
    """Refuse SVD chosen figures that are not the study's own table at the chosen K: the terms are a prefix of one
    factorization, so the chosen row repeats ``by_terms[target]`` at K (an edited ``terms = 7`` printed K = 3's
    figures as K = 7's). An NMF choice (a MaterialX bake's) is in no SVD table, so it is not compared."""
    if chosen.get("factorization", "svd") != "svd" or not isinstance(by_terms, dict):
        return
    table = by_terms.get(chosen.get("target"))
    if not isinstance(table, dict):
        return
    k = chosen["terms"]
    for part, column in (("float", "float"), ("8bit_srgb", "8bit")):
        errors = table.get(column)
        if not isinstance(errors, list) or len(errors) < k or not is_number(errors[k - 1]):
            continue
        got, expected = chosen[part]["relative_rms"], errors[k - 1]
        if not math.isclose(got, expected, rel_tol=1e-6, abs_tol=1e-12):
            raise FieldError(path.as_posix(), f"{where}.chosen.{part}.relative_rms", f"expected {expected:g}, the study's "
                             f"by_terms.{chosen.get('target')}.{column} at the chosen K = {k}, got {got:g}")  # fmt: skip


#: Per table of a study, its rows' figures (numbers >= 0) and counts (whole numbers >= 1): the page formats some and
#: the merge copies every one, so a hand-edited "x" was merged into its report.json where formatting did not fail.
_ROWS = {"pareto": (("cost", "seconds", "relative_rms"), ("resolution", "terms")),
         "by_resolution": (("relative_rms", "seconds", "cost"), ("resolution", "terms"))}  # fmt: skip


def _check_rows(path: Path, where: str, item: dict) -> None:
    """Refuse a study whose table rows or chart sizes are not what atlasgen report separable writes, naming the field."""
    for table, (figures, counts) in _ROWS.items():
        rows = item.get(table)
        if not isinstance(rows, list) or not all(isinstance(row, dict) for row in rows):
            raise FieldError(path.as_posix(), f"{where}.{table}", f"expected a list of rows, got {shorten(repr(rows))}")
        for i, row in enumerate(rows):
            for key in figures:
                check_number(path, f"{where}.{table}[{i}].{key}", row.get(key), minimum=0)
            for key in counts:
                value = row.get(key)
                if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
                    raise FieldError(path.as_posix(), f"{where}.{table}[{i}].{key}",
                                     f"expected a whole number >= 1, got {shorten(repr(value))}")  # fmt: skip
    charts = item.get("charts") or {}
    if not isinstance(charts, dict):
        raise FieldError(path.as_posix(), f"{where}.charts", f"expected an object of charts, got {shorten(repr(charts))}")
    for kind, chart in charts.items():
        sizes = [chart.get(k) for k in ("width", "height")] if isinstance(chart, dict) else [None]
        if not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in sizes):
            raise FieldError(path.as_posix(), f"{where}.charts.{kind}", "expected a chart's width and height in pixels "
                             f"and its labels, got {shorten(repr(chart))}")  # fmt: skip


def _charts(study: MaterialStudy) -> dict:
    """The study's charts as the HTML page takes them (sizes and labels; the images are its plots)."""
    return {kind: Chart(b"", c["width"], c["height"], tuple(c["labels"])) for kind, c in study.charts.items()}


#: What formatting a study raises where a hand edit changed a field's type or dropped a key beneath its top level.
_MALFORMED = (KeyError, TypeError, AttributeError, ValueError, IndexError)


def _formatted(studies: list, plots: dict) -> tuple[bytes, bytes]:
    """The merged ``index.md`` and ``index.html`` of ``studies``."""
    markdown = format_separable_report(studies, plots).encode()
    return markdown, format_separable_html(studies, plots, {s.name: _charts(s) for s in studies})


def _refuse_malformed(origins: list, plots: dict, exc: Exception) -> None:
    """Raise an InputError naming the first study of ``origins`` (``(study, path, index)``) that cannot be
    formatted alone, and the field its formatting stopped on (:class:`~atlasgen.io.field_reads.FieldReads`): a
    hand-edited field deeper than the study's keys (a figure made a string, a chart without its height), on one
    line; ``exc``, the merge's own failure, where each can."""
    for study, path, index in origins:
        reads = FieldReads()
        try:
            _formatted([reads.track(study, f"[{index}]")], {study.name: plots[study.name]})
        except _MALFORMED as own:
            where = f"entry {index} ({shorten(repr(study.name))})"
            culprit = reads.culprit()
            if culprit is None:
                raise InputError(f"{path.as_posix()}: {where} is not a material study as atlasgen report separable "
                                 f"writes it ({describe_failure(own)})") from None  # fmt: skip
            raise FieldError(
                path.as_posix(), culprit[0], expected_written(culprit[1], own, "atlasgen report separable", where)
            ) from None
    where = ", ".join(dict.fromkeys(path.as_posix() for _, path, _ in origins))
    raise InputError(f"{where} is not a material study as atlasgen report separable writes it "
                     f"({describe_failure(exc)})") from None  # fmt: skip


def merge_separable_reports(sources, output) -> dict:
    """Merge per-material separable reports into one ``index.html``, ``index.md``, ``report.json`` and plots.

    Nothing is measured again: the studies are read from each source's ``report.json``
    and the Markdown is written by the study's own writer, so the merged report reads
    as one written in a single run over the same materials. The plots are copied next
    to the merged ``index.md`` (its links are plain file names).

    Parameters
    ----------
    sources
        Folders written by ``atlasgen report separable -o`` (or their ``report.json``
        files), in the order the merged report lists them.
    output
        Folder for the merged files; nothing else in it is touched, so the sources may
        live inside it.

    Returns
    -------
    dict
        ``{"markdown", "html", "json", "plots"}``: the written paths.

    Raises
    ------
    InputError
        No sources, a missing or malformed ``report.json`` or plot, or one material in
        two sources.
    OutputError
        The merged files cannot be written (nothing is written then).
    """
    output = Path(output)
    paths = report_json_paths(sources, "separable", "atlasgen report separable")
    check_merge_output(paths, output)
    files, seen, plots, origins = {}, {}, {}, []  # origins: (study, its report.json, its entry there)
    for path in paths:
        for index, study in enumerate(_read_studies(path)):
            if study.name in seen:
                raise InputError(f"{path.as_posix()}: material {study.name!r} is also in {seen[study.name].as_posix()}")
            seen[study.name] = path
            rebase_study_paths(study, path.parent, output)
            plots[study.name] = {}
            for kind in PLOT_KINDS:
                png = path.parent / f"{study.name}-{kind}.png"
                try:
                    files[output / png.name] = png.read_bytes()
                except OSError as exc:
                    raise InputError(
                        f"{png.as_posix()}: cannot read the {kind} plot of {study.name!r} ({exc.strerror})"
                    ) from None
                plots[study.name][kind] = output / png.name
            origins.append((study, path, index))
    studies = [study for study, _, _ in origins]
    try:
        files[output / "index.md"], files[output / "index.html"] = _formatted(studies, plots)
    except _MALFORMED as exc:  # a study edited by hand: found one by one only now, so a good merge formats once
        _refuse_malformed(origins, plots, exc)
    # The same serialisation as a single run's report.json.
    files[output / "report.json"] = (json.dumps([s.__dict__ for s in studies], indent=1, default=float) + "\n").encode()
    # The set a single run's report names (report.json): a merge into a folder that holds one replaces
    # that set under its lock, rather than writing the same paths as a second set under another.
    refuse_another_report(output, "separable")
    write_files_atomically(files, primary=output / "report.json", whole=True)
    return {"markdown": output / "index.md", "html": output / "index.html", "json": output / "report.json", "plots": plots}
