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
from atlasgen.io.images import PNG_SIGNATURE
from atlasgen.io.json_shape import Count, Fields, Figure, Flag, Items, Nullable, Number, Text, check_shape
from atlasgen.io.report_files import check_merge_output, read_report_json, report_json_paths
from atlasgen.io.text import read_input_bytes
from atlasgen.reports.html import Chart
from atlasgen.reports.report_kind import refuse_another_report
from atlasgen.reports.separable import (
    MaterialStudy,
    format_separable_html,
    format_separable_report,
    rebase_study_paths,
)
from atlasgen.separable.approximate import TARGETS
from atlasgen.separable.factorize import FACTORIZATIONS
from atlasgen.separable.parametrization import PARAMETRIZATIONS

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


#: Measures of error, each a figure, as :func:`atlasgen.separable.error.measure_errors` names them.
_ERRORS = Fields(
    {"relative_rms": Figure()},
    others=Figure(),
    keys=("relative_rms_se", "log_error", "log_error_se", "relative_log_rms", "relative_log_rms_se"),
)
_CURVE = Items(Figure())  # a figure per K = 1, 2, ...
_NONNEGATIVE_ROW = Fields({"terms": Count(), "relative_rms": Figure(), "relative_rms_8bit": Figure()})
_LABEL = Fields({"text": Text(), "left": Number(), "top": Number(), "x": Number(), "y": Number()})
#: One study as :func:`atlasgen.reports.separable.study_material` writes it (its name checked apart), every field: a
#: hand-edited figure is refused where it is, not printed ("-100.00%", "K=one") or blamed on a field read after it.
STUDY_SHAPE = Fields(
    {
        "name": Text(),
        "source": Text(),
        "chosen": Fields(
            {
                "parametrization": Text(tuple(PARAMETRIZATIONS)),
                "target": Text(TARGETS),
                "terms": Count(),
                "grid": Count(),
                "factorization": Text(FACTORIZATIONS),
                "float": _ERRORS,
                "8bit_srgb": _ERRORS,
            }
        ),  # fmt: skip
        "by_terms": Fields(others=Fields({"float": _CURVE, "8bit": _CURVE, "log_float": _CURVE}), keys=TARGETS),
        "by_parametrization": Fields(others=_CURVE, keys=tuple(PARAMETRIZATIONS)),
        "by_resolution": Items(
            Fields({"resolution": Count(), "terms": Count(), "relative_rms": Figure(), "seconds": Figure(), "cost": Figure()}),
            unique=("resolution", "terms"),
        ),  # fmt: skip
        "nonnegative": Fields({"nmf": Items(_NONNEGATIVE_ROW, unique=("terms",)), "nd": _NONNEGATIVE_ROW}),
        "timings": Fields(others=Figure()),
    },
    {
        "atlas": Nullable(
            Fields(
                {"path": Text()},
                {"other_bake": Flag(), "missing": Text()},
                others=Figure(),
                keys=_ERRORS.keys + ("relative_rms",),
            )
        ),  # fmt: skip
        "pareto": Items(
            Fields({"cost": Figure(), "seconds": Figure(), "relative_rms": Figure(), "resolution": Count(), "terms": Count()}),
            unique=("resolution", "terms"),
        ),  # fmt: skip
        "charts": Fields(others=Fields({"width": Count(), "height": Count(), "labels": Items(_LABEL)}), keys=PLOT_KINDS),
    },
)


def _check_chosen(path: Path, where: str, item: dict) -> None:
    """Refuse a study whose fields are not what atlasgen report separable writes (:data:`STUDY_SHAPE`), or whose
    chosen figures are not its own table's."""
    check_shape(path, where, item, STUDY_SHAPE)
    _check_chosen_against_by_terms(path, where, item["chosen"], item["by_terms"])


def _check_chosen_against_by_terms(path: Path, where: str, chosen: dict, by_terms) -> None:
    """Refuse SVD chosen figures that are not the study's own table at the chosen K: the terms are a prefix of one
    factorization, so the chosen row repeats ``by_terms[target]`` at K (an edited ``terms = 7`` printed K = 3's
    figures as K = 7's). An NMF choice (a MaterialX bake's) is in no SVD table, so it is not compared."""
    if chosen["factorization"] != "svd":
        return
    table = by_terms.get(chosen["target"])
    if table is None:
        raise FieldError(path.as_posix(), f"{where}.chosen.target", f"expected a target of the study's by_terms "
                         f"({', '.join(by_terms) or 'none'}), got {chosen['target']!r}")  # fmt: skip
    k = chosen["terms"]
    for part, column in (("float", "float"), ("8bit_srgb", "8bit")):
        errors = table[column]
        if len(errors) < k:  # a fixed K past the K = 1 .. 8 the study measures: nothing to compare
            continue
        got, expected = chosen[part]["relative_rms"], errors[k - 1]
        if not math.isclose(got, expected, rel_tol=1e-6, abs_tol=1e-12):
            raise FieldError(path.as_posix(), f"{where}.chosen.{part}.relative_rms", f"expected {expected:g}, the study's "
                             f"by_terms.{chosen['target']}.{column} at the chosen K = {k}, got {got:g}")  # fmt: skip


#: The most bytes a plot may have: the report's are about 50 kB.
_PLOT_LIMIT = 64 << 20


def _read_plot(png: Path, kind: str, name: str) -> bytes:
    """The bytes of ``name``'s ``kind`` plot, refused unless a regular PNG file: a named pipe hung the merge, /dev/zero
    filled the memory, and an empty file was copied into the merged page as a broken image."""
    what = f"the {kind} plot of {name!r}"
    data = read_input_bytes(png, f"no such file ({what})", limit=(_PLOT_LIMIT, f"{what}, a PNG image"))
    if not data.startswith(PNG_SIGNATURE):
        raise InputError(f"{png.as_posix()}: expected {what}, a PNG image, got {len(data)} bytes of something else")
    return data


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
                files[output / png.name] = _read_plot(png, kind, study.name)
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
