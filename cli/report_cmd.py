"""``atlasgen report``: thin layers over the separable report and the whole-library report."""

from __future__ import annotations

from pathlib import Path

import click

from atlasgen.cli.main import fail_on_errors

__all__ = ["report", "library", "separable"]


@click.group()
def report():
    """Measured reports on baked materials."""


@report.command("separable")
@click.argument("names", nargs=-1)
@click.option("-m", "--materials", "materials_dir", type=click.Path(path_type=Path), default=Path("materials"),
              show_default=True, help="Folder (or TOML file) of materials to pick from.")
@click.option("--atlas", type=click.Path(path_type=Path), default=None,
              help="Also measure these materials as stored in this atlas (X.dds with X.json beside it).")
@click.option("-o", "--output", type=click.Path(path_type=Path), default=Path("build/report/separable"), show_default=True,
              help="Folder for index.md, report.json and the PNG plots.")
@click.option("--repeats", type=click.IntRange(1, 50), default=5, show_default=True, help="Timing repeats (median).")
@click.option("--merge", is_flag=True,
              help="Measure nothing: merge earlier reports, the folders given as arguments, into one OUTPUT.")
@fail_on_errors
def separable(names, materials_dir, atlas, output, repeats, merge):
    """Error against K, grid, 8 bits and time for separable MATERIAL names (default: all separable ones).

    NAMES are material names (picked from --materials) or material files (X.toml).
    With --merge they are folders of earlier reports (e.g. one per material), combined
    without measuring again.
    """
    from atlasgen.errors import InputError
    from atlasgen.materials.material import read_materials
    from atlasgen.reports.separable_merge import merge_separable_reports
    from atlasgen.reports.separable import write_separable_report

    if merge:
        click.echo(merge_separable_reports([Path(n) for n in names], output)["markdown"].as_posix())
        return

    files = [Path(n) for n in names if n.endswith(".toml")]
    wanted = [n for n in names if not n.endswith(".toml")]
    pool = read_materials([materials_dir]) if (wanted or not files) else []
    chosen = [m for m in pool if not wanted or m.name in wanted]
    missing = sorted(set(wanted) - {m.name for m in chosen})
    if missing:
        raise InputError(f"{materials_dir.as_posix()}: no material named {', '.join(missing)}")
    if files:
        chosen += read_materials(files)
    written = write_separable_report(chosen, output, atlas, repeats=repeats)
    click.echo(written["markdown"].as_posix())


@report.command("library")
@click.option("--atlas", type=click.Path(path_type=Path), default=Path("build/atlas.dds"), show_default=True,
              help="Baked atlas (X.dds with X.json and X.timings.json beside it).")
@click.option("--validation", type=click.Path(path_type=Path), default=Path("build/validation"), show_default=True,
              help="Folder of `atlasgen validate` (report.json, index.html), used when present.")
@click.option("--separable", "separable_dir", type=click.Path(path_type=Path), default=Path("build/report/separable"),
              show_default=True, help="Folder of `atlasgen report separable`, linked when present.")
@click.option("-o", "--output", type=click.Path(path_type=Path), default=Path("build/report"), show_default=True,
              help="Folder for index.html, slice previews and the speed-against-error plot.")
@fail_on_errors
def library(atlas, validation, separable_dir, output):
    """One HTML page over the whole library: representation, errors, bake time, slice previews."""
    from atlasgen.reports.library import write_library_report

    click.echo(write_library_report(atlas, output, validation, separable_dir).as_posix())
