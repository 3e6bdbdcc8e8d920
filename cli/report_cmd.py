"""``atlasgen report``: thin layers over the separable report and the whole-library report."""

from __future__ import annotations

from pathlib import Path

import click

from atlasgen.cli.main import echo_warning, fail_on_errors
from atlasgen.cli.options import HELP_OPTIONS, QUIET, VERBOSE, MaterialProgress, PathArg, refuse_options, verbosity_options
from atlasgen.errors import InputError
from atlasgen.io.output_paths import check_output_folder, refuse_inputs_in_folder
from atlasgen.io.package_data import shipped_library
from atlasgen.materials.material import read_materials
from atlasgen.models.separable import Separable
from atlasgen.reports.library import write_library_report
from atlasgen.reports.report_kind import folder_report_kind
from atlasgen.reports.separable import write_separable_report
from atlasgen.reports.separable_merge import merge_separable_reports

__all__ = ["report", "library", "separable"]


@click.group(context_settings=HELP_OPTIONS)
def report():
    """Measured reports on baked materials."""


def _is_file_name(name: str) -> bool:
    """A NAME that is a material file, not a material's name: ``X.MTLX`` was looked up as a name ("materials: no
    such file or folder") where bake reads the file. Material names hold no dot, so the extension decides."""
    return name.lower().endswith((".toml", ".mtlx"))


@report.command("separable")
@click.argument("names", nargs=-1)
@click.option(
    "-m",
    "--materials",
    "materials_dir",
    type=PathArg(path_type=Path),
    default=Path("materials"),
    show_default=True,
    help="Folder (or TOML file) of materials to pick from.",
)
@click.option("--library", is_flag=True, help="Pick from the material library installed with atlasgen instead of --materials.")
@click.option(
    "--atlas",
    type=PathArg(path_type=Path),
    default=None,
    help="Also measure these materials as stored in this atlas (X.dds with X.json beside it).",
)
@click.option(
    "-o",
    "--output",
    type=PathArg(path_type=Path),
    default=Path("build/report/separable"),
    show_default=True,
    help="Folder for index.html (with its plots), index.md (a text summary) and report.json.",
)
@click.option("--repeats", type=click.IntRange(1, 50), default=5, show_default=True, help="Timing repeats (median).")
@click.option(
    "--merge", is_flag=True, help="Measure nothing: merge earlier reports, the folders given as arguments, into one OUTPUT."
)
@verbosity_options(verbose="Also print the plots written for each material.")
@fail_on_errors
def separable(names, materials_dir, library, atlas, output, repeats, merge, verbosity):
    """Error against K, grid, 8 bits and time for separable MATERIAL names (default: all separable ones).

    NAMES are material names (picked from --materials) or material files (X.toml, or X.mtlx: its every material).
    With --merge they are folders of earlier reports (e.g. one per material), combined
    without measuring again.
    """
    ctx = click.get_current_context()
    if merge:
        # -v lists each study's plots; -q stays (it silences the merged page's path).
        refuse_options(ctx, ("materials_dir", "library", "atlas", "repeats", "--verbose"),
                       "with --merge, which measures nothing (it combines earlier reports)")  # fmt: skip
    elif library:
        refuse_options(ctx, ("materials_dir",), "with --library, which picks from the installed library instead")
    if names and all(_is_file_name(n) for n in names):
        refuse_options(ctx, ("materials_dir", "library"), "when every NAME is a material file: nothing is picked by name")
    check_output_folder(output, "the report folder (-o)", writes=("report.json", "index.html"))
    if merge:
        merged = merge_separable_reports([Path(n) for n in names], output)["html"]
        if verbosity != QUIET:
            click.echo(merged.as_posix())
        return
    if library:
        materials_dir = shipped_library()

    files = [Path(n) for n in names if _is_file_name(n)]
    wanted = [n for n in names if not _is_file_name(n)]
    pool = read_materials([materials_dir]) if (wanted or not files) else []
    chosen = [m for m in pool if not wanted or m.name in wanted]
    missing = sorted(set(wanted) - {m.name for m in chosen})
    if missing:
        raise InputError(f"{materials_dir.as_posix()}: no material named {', '.join(missing)}")
    if not names:  # every separable material of the folder; the others are not asked for
        chosen = [m for m in chosen if isinstance(m.model, Separable)]
        if not chosen:
            raise InputError(f"{materials_dir.as_posix()}: no separable materials to report on; "
                             f'expected materials with type = "{Separable.type_name}"')  # fmt: skip
    if files:
        given = read_materials(files)
        if not given:  # an empty folder named X.toml: the line named nothing
            raise InputError(f"{', '.join(f.as_posix() for f in files)}: no separable materials to report on; "
                             f'expected materials with type = "{Separable.type_name}"')  # fmt: skip
        chosen += given
    inputs = [(Path(m.source), f"the material file of {m.name!r}") for m in chosen]
    if atlas is not None:
        inputs += [(Path(atlas), "the atlas (--atlas)"), (Path(atlas).with_suffix(".json"), "the atlas's manifest")]
    refuse_inputs_in_folder(output, inputs)
    with MaterialProgress("studied", verbosity) as on_material:
        written = write_separable_report(chosen, output, atlas, repeats=repeats, on_material=on_material,
                                         skip_without_terms=not names)  # fmt: skip
    if verbosity == VERBOSE:
        for name, plots in written["plots"].items():
            click.echo(f"  {name}: {', '.join(p.as_posix() for p in plots.values())}", err=True)
    if verbosity != QUIET:
        click.echo(written["html"].as_posix())


def _refuse_absent_reports(ctx: click.Context, validation: Path, separable_dir: Path) -> None:
    """A report folder named on the command line must hold its report: a mistyped --validation wrote a page with
    no validation figures, silently. Left at their defaults, they are used when present."""
    wanted = (("validation", validation, "report.json", "atlasgen validate"),
              ("separable_dir", separable_dir, "index.html", "atlasgen report separable"))  # fmt: skip
    for name, folder, report, writer in wanted:
        option = next(p.opts[-1] for p in ctx.command.params if p.name == name)
        given = ctx.get_parameter_source(name) == click.core.ParameterSource.COMMANDLINE
        if given and not (folder / report).is_file():
            raise InputError(f"{folder.as_posix()}: no {report} in the {option} folder; expected a folder {writer} "
                             f"wrote, or no {option}")  # fmt: skip
    # Any page passed: another library page given as --separable was linked as the factorisation report, exit 0.
    if ctx.get_parameter_source("separable_dir") == click.core.ParameterSource.COMMANDLINE:
        if folder_report_kind(separable_dir) != "separable":
            raise InputError(f"{(separable_dir / 'report.json').as_posix()}: the --separable folder holds no separable "
                             "report; expected a folder atlasgen report separable wrote, or no --separable")  # fmt: skip


@report.command("library")
@click.option(
    "--atlas",
    type=PathArg(path_type=Path),
    default=Path("build/atlas.dds"),
    show_default=True,
    help="Baked atlas (X.dds with X.json and X.timings.json beside it).",
)
@click.option(
    "--validation",
    type=PathArg(path_type=Path),
    default=Path("build/validation"),
    show_default=True,
    help="Folder of `atlasgen validate` (report.json, index.html); left at its default, used when present.",
)
@click.option(
    "--separable",
    "separable_dir",
    type=PathArg(path_type=Path),
    default=Path("build/report/separable"),
    show_default=True,
    help="Folder of `atlasgen report separable`; left at its default, linked when present.",
)
@click.option(
    "-o",
    "--output",
    type=PathArg(path_type=Path),
    default=Path("build/report"),
    show_default=True,
    help="Folder for index.html, slice previews, the cost plots and the Pareto charts (their candidates "
    "cached in OUTPUT/pareto).",
)
@click.option(
    "--no-physical", is_flag=True, help="Skip the Pareto charts against the physical reference (they evaluate Mitsuba BSDFs)."
)
@verbosity_options(
    verbose="Also print which of the validation and separable reports were found, and the validated "
    "materials the atlas does not hold."
)
@fail_on_errors
def library(atlas, validation, separable_dir, output, no_physical, verbosity):
    """One HTML page over the whole library: representation, errors, bake time, slice previews, and Pareto
    charts of run-time cost against error versus the physical reference."""
    check_output_folder(output, "the report folder (-o)", writes=("index.html",))
    _refuse_absent_reports(click.get_current_context(), validation, separable_dir)
    # Figures validated on another bake of a material are not shown as its: one line each, loud even with -q.
    # What is left out as another atlas's (a scene atlas's page over the library's report) is no fault: said with -v.
    notes: list[str] = []
    page = write_library_report(atlas, output, validation, separable_dir, physical=not no_physical,
                                warn=echo_warning, note=notes.append)  # fmt: skip
    if verbosity == VERBOSE:
        inputs = (("validation report", validation / "report.json"), ("separable report", separable_dir / "index.html"))
        for what, path in inputs:
            click.echo(f"  {what}: {path.as_posix()} ({'used' if path.is_file() else 'absent'})", err=True)
        for line in notes:
            click.echo(f"  {line}", err=True)
    if verbosity != QUIET:
        click.echo(page.as_posix())
