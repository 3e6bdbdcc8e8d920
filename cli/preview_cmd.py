"""``atlasgen preview``: a thin click layer over :mod:`atlasgen.preview`."""

from __future__ import annotations

from pathlib import Path

import click

from atlasgen.cli.main import echo_warnings, fail_on_errors, one_line_message
from atlasgen.cli.options import HELP_OPTIONS, MAX_SPP, QUIET, VERBOSE, PathArg, refuse_options, verbosity_options
from atlasgen.errors import Terminated
from atlasgen.preview.previewer import DEFAULT_CACHE_DIR, Previewer, check_preview_output, default_output
from atlasgen.preview.reference import reference_lines
from atlasgen.preview.watch import describe_label, describe_update, picture_kept, watch_preview

__all__ = ["preview"]


def _steps(timings: dict) -> str:
    return ", ".join(f"{name} {seconds:.3f} s" for name, seconds in timings.items())


@click.command("preview", context_settings=HELP_OPTIONS)
@click.argument("paths", nargs=-1, required=True, type=PathArg(path_type=Path))
@click.option("-o", "--output", type=PathArg(path_type=Path, file_output=True), default=None,
              help="PNG to write.  [default: build/preview/NAME.png, NAME the material file's stem or the folder's "
                   "name; build/preview/contact-sheet.png for several]")  # fmt: skip
@click.option("--cache", "cache_dir", type=PathArg(path_type=Path), metavar="DIRECTORY", default=DEFAULT_CACHE_DIR,
              show_default=True, help="Per-material bake cache, the one make fills: unchanged materials are loaded, "
                                      "not baked again.")  # fmt: skip
@click.option("--no-cache", is_flag=True, help="Bake every material, and store nothing.")
@click.option("--watch", is_flag=True,
              help="Keep running: re-bake and re-render on every save of a material file (or a file it names), "
                   "printing one line per update; Ctrl-C ends it (exit 0).")  # fmt: skip
@click.option("--reference", is_flag=True,
              help="Also render each material's Mitsuba physical reference of the same scene and show it beside the "
                   "picture, labelled with its spp, noise floor and the picture's PSNR against it on the material's "
                   "pixels (needs Mitsuba).")  # fmt: skip
@click.option(
    "--reference-spp",
    "max_spp",
    type=click.IntRange(4, MAX_SPP),
    default=256,
    show_default=True,
    help="The most samples per pixel (per seed) a reference is refined to.",
)
@verbosity_options(quiet="Print only errors.", verbose="Also print how long each step took.")
@fail_on_errors
def preview(paths, output, cache_dir, no_cache, watch, reference, max_spp, verbosity):
    """Show material files (or folders of them) on a standard ball and sphere, in a labelled PNG.

    The materials are baked alone, from the bake cache, and rendered with the deferred renderer
    on a floor with a key and a rim light (atlasgen/preview/scene.py). Each picture is labelled
    with the material's name and type, its representation (LUT slice, fitted slice, separable
    with K terms, analytic) and the error its manifest entry gives. Several materials, or a
    folder, give a contact sheet: one bake, one labelled picture per material.

    With --watch the GPU device and the compiled pipelines stay warm: every save re-bakes what
    changed and rewrites the PNG (atomically, so a viewer never sees half of it). Editors that
    save by renaming a new file over the old one are followed (the folder is watched). A bad
    edit prints its one-line error and keeps the last good picture. A separable material's
    picture comes first, labelled "error: measuring ..."; its error figure (the one a full bake
    writes) follows on a second line and in the PNG's label.

    With --reference each picture has the material's Mitsuba physical reference of the same
    scene beside it, rendered at the preview's resolution with seeds 0 and 1 (their PSNR is its
    noise floor), from 4 samples per pixel doubling until the floor is 10 dB above the picture's
    PSNR against it, or --reference-spp. A material without one says so. With --watch the
    reference renders in the background: the picture comes first, and each refinement rewrites
    the PNG.

    Exit codes as every command's; a bad material file gives its one line (3) and leaves the PNG as
    it was. A material the atlas holds badly is shown with the line `atlasgen bake` warns with.
    """
    ctx = click.get_current_context()
    if not reference:
        refuse_options(ctx, ("max_spp",), "without --reference, which renders the references it refines",
                       "--reference with it")  # fmt: skip
    if no_cache:
        refuse_options(ctx, ("cache_dir",), "with --no-cache, which reads and stores no cache")
    output = output or default_output(paths)
    cache = None if no_cache else cache_dir
    if watch:
        _watch(paths, output, cache, verbosity, reference, max_spp)
        return
    shown = Previewer(cache).write(paths, output, reference=reference, max_spp=max_spp)
    if verbosity != QUIET:
        _warn(shown.bake, set())
        click.echo(f"wrote {output.as_posix()} ({', '.join(shown.names)}) in {shown.seconds:.2f} s")
    if verbosity == VERBOSE:
        click.echo(f"  {_steps(shown.timings)}", err=True)


def _warn(result, printed: set) -> None:
    """The bake's warnings, as ``atlasgen bake`` prints them: a material the atlas holds badly (its measured
    error over the threshold, texels lost to 8 bits, ...) is never shown without its line. ``printed``: the
    warnings already printed for this picture (a watch's draft picture, then its measured labels)."""
    if result is not None:
        echo_warnings([*result.warnings, *result.material_warnings], printed)


def _watch(paths, output, cache, verbosity, reference=False, max_spp=None) -> None:
    printed: set = set()

    def report(update) -> None:
        printed.clear()
        if update.error is not None:
            click.echo(f"atlasgen: error: {one_line_message(update.error)} ({picture_kept(output)}; watching)", err=True)
        elif verbosity != QUIET:
            _warn(update.preview.bake, printed)
            click.echo(describe_update(update, output, steps=verbosity == VERBOSE))

    def labelled(preview, error) -> None:
        if error is not None:
            click.echo(f"atlasgen: error: {one_line_message(error)} (the picture stands without its error figures; watching)",
                       err=True)  # fmt: skip
        elif verbosity != QUIET:
            _warn(preview.bake, printed)  # the drafts' warnings, measured only now
            click.echo(describe_label(preview))

    def refined(name, shot) -> None:
        if name is None:
            click.echo(f"atlasgen: error: {one_line_message(shot)} (no reference; watching)", err=True)
        elif verbosity == VERBOSE:
            click.echo(f"reference {name}: {', '.join(reference_lines(shot)[1:])} ({shot.seconds:.1f} s)")

    check_preview_output(output, paths, cache)  # before the line that says the watch has begun
    if verbosity != QUIET:
        click.echo(f"watching {', '.join(Path(p).as_posix() for p in paths)} (Ctrl-C to stop)", err=True)
    try:
        watch_preview(paths, output, cache, on_update=report, reference=reference, max_spp=max_spp, on_reference=refined,
                      on_label=labelled)  # fmt: skip
    except KeyboardInterrupt as exc:
        # SIGTERM (a CI job's time-out, an IDE's stop) is not how a watch is ended by its user: it exits 143
        # with its one line, as every command does (Terminated is a KeyboardInterrupt, for the clean-ups).
        if isinstance(exc, Terminated):
            raise
        # Ctrl-C is how a watch ends: a success; the PNG was replaced whole or not at all.
        if verbosity != QUIET:
            click.echo("stopped watching", err=True)
