"""The ``atlasgen`` command line: a thin click layer over the library.

Exit codes: :data:`atlasgen.errors.EXIT_CODES` (the table in docs/cli.md). Whatever the
input, a failure is one line on stderr: the library's typed errors and click's usage
errors as ``atlasgen: error: ...``, Ctrl-C as ``atlasgen: interrupted``, and any other
exception (a bug) as ``atlasgen: internal error: ...``; ``--debug`` or
``ATLASGEN_DEBUG=1`` adds the traceback (and Python's warnings, otherwise silent).
"""

from __future__ import annotations

import functools
import importlib
import importlib.util
import json
import math
import os
import signal
import sys
import time
import traceback
import warnings
from pathlib import Path

import click

from atlasgen import __version__
from atlasgen.bake.cache import cache_path
from atlasgen.bake.companions import expected_companions
from atlasgen.bake.outputs import check_bake_outputs
from atlasgen.bake.pipeline import bake_atlas, read_previous_slots, sibling_paths, write_bake
from atlasgen.bake.workers import POOL_AFTER_S, available_cpus, fill_cache
from atlasgen.cli.options import (
    HELP_OPTIONS,
    QUIET,
    VERBOSE,
    MaterialProgress,
    PathArg,
    refuse_options,
    verbosity_options,
)
from atlasgen.errors import (
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_TERMINATED,
    REPORT_BUGS_TO,
    AtlasgenError,
    BakeWarnings,
    OutputError,
    Terminated,
    shorten,
)
from atlasgen.interrupts import end_start_up_interrupts, interrupt_behind
from atlasgen.io.atlas import describe_atlas, summarize_atlas
from atlasgen.io.atomic import lock_timeout, write_file_atomically
from atlasgen.io.depfile import encode_depfile
from atlasgen.io.package_data import shipped_library
from atlasgen.materials.material import read_materials, select_scene_materials
from atlasgen.materials.materialx_document import is_materialx_file
from atlasgen.models import check_manifest_models
from atlasgen.reports.report_kind import folder_report_kind
from atlasgen.start_up import INTERRUPTED_LINE, TERMINATED_LINE

__all__ = ["app", "main", "fail_on_errors", "exit_for", "one_line_message", "FiniteFloatRange"]

#: Seconds after which ``atlasgen bake`` reports each finished material on stderr (a bar on a
#: terminal, else ``baked skin (3/12)`` lines; nothing with -q).
PROGRESS_AFTER_S = 2.0

#: Subcommands that live in their own module, imported only when invoked, so that
#: ``atlasgen --help`` never pays for the renderer's or the reports' imports.
LAZY_COMMANDS = {
    "preview": ("atlasgen.cli.preview_cmd", "preview", "Show materials on a standard ball; --watch re-renders on every save."),
    "render": ("atlasgen.cli.render_cmd", "render", "Render a scene with the bundled deferred renderer."),
    "report": ("atlasgen.cli.report_cmd", "report", "Write reports (separable factorisation, library)."),
    "validate": ("atlasgen.cli.validate_cmd", "validate", "Compare baked materials with Mitsuba 3 references."),
}


class FiniteFloatRange(click.FloatRange):
    """click's FloatRange, less NaN (which every comparison lets through)."""

    def convert(self, value, param, ctx):
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        return number


def _debugging() -> bool:
    """``--debug`` on the command line, or ``ATLASGEN_DEBUG`` set (to anything but 0)."""
    if os.environ.get("ATLASGEN_DEBUG", "").strip() not in ("", "0"):
        return True
    ctx = click.get_current_context(silent=True)
    return bool(ctx is not None and ctx.find_root().params.get("debug"))


def one_line_message(text) -> str:
    """``text`` (an exception, a message) on one line: its non-blank lines joined by ``; ``.

    >>> one_line_message("bad value\n  expected a number\n")
    'bad value; expected a number'
    """
    return "; ".join(part.strip() for part in str(text).splitlines() if part.strip())


def echo_warning(line) -> None:
    """One warning's line on stderr: ``atlasgen: warning: ...``."""
    click.echo(f"atlasgen: warning: {line}", err=True)


def echo_warnings(warnings, printed: set | None = None) -> None:
    """:func:`echo_warning` for each of ``warnings``; with ``printed`` (the lines already shown, updated),
    only those not among them."""
    for warning in warnings:
        if printed is not None:
            if str(warning) in printed:
                continue
            printed.add(str(warning))
        echo_warning(warning)


def exit_for(exc: BaseException):
    """Print the one line for an exception that ended a command, and exit with its status."""
    if isinstance(exc, AtlasgenError):
        click.echo(f"atlasgen: error: {one_line_message(exc)}", err=True)
        sys.exit(exc.exit_code)
    interrupt = interrupt_behind(exc)
    if interrupt is not None:  # the start-up's lines, once the command runs too
        terminated = isinstance(interrupt, Terminated)
        click.echo((TERMINATED_LINE if terminated else INTERRUPTED_LINE).decode(), err=True, nl=False)
        sys.exit(EXIT_TERMINATED if terminated else EXIT_INTERRUPTED)
    if isinstance(exc, click.ClickException):
        ctx = getattr(exc, "ctx", None)
        hint = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
        click.echo(f"atlasgen: error: {one_line_message(exc.format_message())}{hint}", err=True)
        sys.exit(exc.exit_code)
    if _debugging():
        traceback.print_exception(exc)
    detail = one_line_message(exc)
    detail = f"{type(exc).__name__}: {detail[:200]}" if detail else type(exc).__name__
    click.echo(f"atlasgen: internal error ({detail}); this is a bug: please report it to {REPORT_BUGS_TO} "
               "with the traceback that ATLASGEN_DEBUG=1 adds", err=True)  # fmt: skip
    sys.exit(EXIT_INTERNAL)


def _guarded(call):
    """Run ``call()``; any exception but click's own exits goes through :func:`exit_for`."""
    try:
        with warnings.catch_warnings():
            # The library's numerics are checked on their results, not by warnings; a
            # user sees a warning only in the one-line form the commands print.
            if not _debugging():
                warnings.simplefilter("ignore")
            return call()
    except (SystemExit, click.exceptions.Exit, click.Abort):
        raise
    except BaseException as exc:  # noqa: BLE001 - every exception ends in one line
        exit_for(exc)


class LazyGroup(click.Group):
    def make_context(self, info_name, args, parent=None, **extra):
        # The top level's arguments are parsed in here, before invoke's guard: click's own main would catch a
        # Ctrl-C (or SIGTERM) landing here and echo an empty line before the one line.
        return _guarded(lambda: super(LazyGroup, self).make_context(info_name, args, parent, **extra))

    def invoke(self, ctx):
        # The sub-command's arguments are parsed and its module imported in here too.
        return _guarded(lambda: click.Group.invoke(self, ctx))

    def list_commands(self, ctx):
        available = [n for n, (mod, _, _) in LAZY_COMMANDS.items() if importlib.util.find_spec(mod) is not None]
        return sorted(set(super().list_commands(ctx)) | set(available))

    def get_command(self, ctx, name):
        if name in LAZY_COMMANDS:
            module_name, attr, _ = LAZY_COMMANDS[name]
            if importlib.util.find_spec(module_name) is None:
                return None
            return getattr(importlib.import_module(module_name), attr)
        return super().get_command(ctx, name)

    def format_commands(self, ctx, formatter):
        # Short help for lazy commands without importing them.
        rows = []
        for name in self.list_commands(ctx):
            if name in LAZY_COMMANDS:
                rows.append((name, LAZY_COMMANDS[name][2]))
            else:
                cmd = super().get_command(ctx, name)
                rows.append((name, cmd.get_short_help_str(limit=formatter.width)))
        with formatter.section("Commands"):
            formatter.write_dl(rows)


def fail_on_errors(func):
    """Map every exception to a one-line message on stderr and its exit code (:func:`exit_for`)."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        return _guarded(lambda: func(*args, **kwargs))

    return wrapper


@click.group(cls=LazyGroup, invoke_without_command=True, context_settings=HELP_OPTIONS)
@click.version_option(__version__, prog_name="atlasgen")
@click.option("--debug", is_flag=True, help="On an internal error, also print the traceback (as ATLASGEN_DEBUG=1 does).")
@click.pass_context
def app(ctx, debug):
    """atlasgen: bake BRDF materials into a 64x32x256 atlas for fully deferred renderers."""
    if ctx.invoked_subcommand is None:  # bare `atlasgen`: the help, and success
        click.echo(ctx.get_help())
    else:
        # Read where every output is committed, after the work: a bad value failed a validation after its renders.
        lock_timeout()


@app.command()
@click.argument("paths", nargs=-1, type=PathArg(path_type=Path))
@click.option(
    "-o",
    "--output",
    type=PathArg(path_type=Path, file_output=True),
    default=Path("build/atlas.dds"),
    show_default=True,
    help="Atlas to write, X.dds or X.ktx2; X.json (manifest), the includes (X.wgsl, X.glsl, X.hlsl: --include) and X.timings.json go beside it.",
)
@click.option(
    "--layout",
    type=click.Choice(["array", "volume"]),
    default="array",
    show_default=True,
    help="Texture2DArray (a mip chain per material) or Texture3D (mips blend neighbouring materials).",
)
@click.option("--linear", is_flag=True, help="Store RGB linearly (DXGI 28, VK 37) instead of sRGB (DXGI 29, VK 43).")
@click.option("--zstd", is_flag=True, help="Supercompress each mip level with Zstandard (needs -o X.ktx2).")
@click.option(
    "--preview", type=PathArg(path_type=Path, file_output=True), default=None, help="Also write a labelled contact sheet PNG."
)
@click.option("--scene", type=PathArg(path_type=Path), default=None, help="Bake only the materials this scene references.")
@click.option(
    "--ids-from",
    type=PathArg(path_type=Path),
    default=None,
    help="Take slice IDs from this manifest (e.g. the full library's build/atlas.json).",
)
@click.option(
    "--cache",
    "cache_dir",
    type=PathArg(path_type=Path),
    default=None,
    help="Per-material cache folder: unchanged materials are loaded, not re-baked.",
)
@click.option(
    "--include",
    "include_languages",
    default="wgsl,glsl,hlsl",
    show_default=True,
    metavar="LANGS",
    help="Shader includes to write beside the atlas, comma-separated: wgsl, glsl, hlsl.",
)
@click.option("--cache-only", is_flag=True, help="Only fill the cache (with --cache); write no atlas (its options are refused).")
@click.option(
    "--depfile",
    type=PathArg(path_type=Path, file_output=True),
    default=None,
    help="Also write a Make dependency file: the atlas (or --depfile-target) against each material file, the files "
    "MaterialX documents include, and with --cache each cache entry (not with --cache-only, which fills them).",
)
@click.option(
    "--depfile-target",
    type=PathArg(path_type=Path),
    default=None,
    help="The make target --depfile names (as gcc's -MT): default the atlas (-o). --cache-only writes no atlas, so "
    "with --depfile it needs one (a stamp file): the target against each material file and the files it includes.",
)
@click.option(
    "--library", is_flag=True, help="Also bake the material library installed with atlasgen (alone when no PATHS are given)."
)
@click.option("--allow-empty", is_flag=True, help="Allow replacing an atlas that has materials with an empty one.")
@click.option(
    "--flatten",
    "mtlx_flatten",
    type=click.Choice(["default"]),
    default=None,
    help="MaterialX documents: bake an input driven by a texture or node graph at its nodedef default (recorded in the "
    "manifest's params.materialx.flattened) instead of refusing the material. Refused where no input is a MaterialX "
    "document.",
)
@click.option(
    "--strict",
    is_flag=True,
    help="Fail (exit 7, no atlas or side file written; --cache keeps what was baked) when a material warns: its measured error over 20%, a dropped delta lobe, "
    "tolerated non-finite samples.",
)
@click.option(
    "-j",
    "--jobs",
    type=click.IntRange(min=1),
    default=None,
    help=f"Bake up to N materials at once, each in its own process, once baking has run {POOL_AFTER_S:g} s (a quick "
    "bake starts none); the outputs are the same bytes for any N.  [default: one per CPU]",
)
@verbosity_options(verbose="Also print each material's slices and whether it was baked or loaded from the cache.")
@fail_on_errors
def bake(
    paths,
    output,
    layout,
    linear,
    zstd,
    preview,
    scene,
    ids_from,
    cache_dir,
    include_languages,
    cache_only,
    depfile,
    depfile_target,
    library,
    allow_empty,
    mtlx_flatten,
    strict,
    jobs,
    verbosity,
):
    """Bake material definitions (files or folders; default: materials/) into an atlas.

    A file is a TOML material or a MaterialX document (.mtlx), whose every surfacematerial is baked from
    MaterialX's own shader."""
    if cache_only:
        _refuse_atlas_options(click.get_current_context())
    if zstd and output.suffix.lower() != ".ktx2":
        raise click.UsageError(f"--zstd needs a KTX2 output (-o X.ktx2), got -o {output.as_posix()}")
    if cache_only and cache_dir is None:
        raise click.UsageError("--cache-only needs --cache DIR")
    if depfile_target is not None and depfile is None:
        raise click.UsageError("--depfile-target needs --depfile FILE")
    if cache_only and depfile is not None and depfile_target is None:
        raise click.UsageError("--depfile with --cache-only needs --depfile-target: no atlas is written for it to name")
    languages = tuple(dict.fromkeys(lang.strip().lower() for lang in include_languages.split(",") if lang.strip()))
    unknown = [lang for lang in languages if lang not in ("wgsl", "glsl", "hlsl")]
    if unknown:
        raise click.UsageError(f"--include: unknown language {shorten(repr(unknown[0]))}; expected wgsl, glsl or hlsl, "
                               "comma-separated")  # fmt: skip
    sources = list(paths) + ([shipped_library()] if library else [])
    every_material = read_materials(sources or [Path("materials")], materialx_flatten=mtlx_flatten)
    if not any(is_materialx_file(m.source) for m in every_material):
        refuse_options(click.get_current_context(), ("mtlx_flatten",), "without a MaterialX material among the inputs",
                       "a MaterialX document (.mtlx) to flatten, or no --flatten")  # fmt: skip
    materials = select_scene_materials(every_material, scene) if scene is not None else every_material
    # Every output path is checked before anything (the cache included) is written.
    check_bake_outputs(output, materials, preview, depfile, cache_dir, scene, ids_from, allow_empty, cache_only, every_material,
                       depfile_target)  # fmt: skip
    if not cache_only:
        _refuse_a_report_as_manifest(sibling_paths(output)["manifest"])
    jobs = available_cpus() if jobs is None else jobs
    if cache_only:
        # Formatted first, so that a path make cannot read is refused before anything is baked.
        dependencies = encode_depfile(depfile_target, _material_inputs(materials)) if depfile else None
        filled = fill_cache(cache_dir, materials, jobs)
        if dependencies is not None:
            write_file_atomically(depfile, dependencies)
        if verbosity == VERBOSE:
            click.echo(f"cache {cache_dir.as_posix()}: baked {', '.join(filled['baked']) or 'none'}; "
                       f"up to date {', '.join(filled['hits']) or 'none'}", err=True)  # fmt: skip
        if verbosity != QUIET:
            echo_warnings(filled["warnings"])
        return
    extra_files = {}
    if depfile is not None:
        # Formatted before the bake (a path make cannot read is refused first) and written in the same
        # commit as the atlas: a depfile that cannot be written fails the bake before the atlas is replaced.
        inputs = _material_inputs(materials) + ([scene] if scene is not None else [])
        if cache_dir is not None:
            inputs += [cache_path(cache_dir, m) for m in materials]
        extra_files[depfile] = encode_depfile(depfile_target or output, inputs)
    # The atlas's own last IDs keep it stable, but --ids-from's win: a scene atlas takes the library's IDs even
    # where the library moved a material since the scene was last baked.
    previous = read_previous_slots(sibling_paths(output)["manifest"])
    pinned = None if ids_from is None else (ids_from, read_previous_slots(ids_from, missing_ok=False))
    with MaterialProgress("baked", verbosity) as report:
        started, done = time.monotonic(), [0]

        def on_material(name):
            # Quick bakes stay quiet; one that runs past PROGRESS_AFTER_S reports each material from then on.
            done[0] += 1
            if time.monotonic() - started > PROGRESS_AFTER_S:
                report(name, done[0], len(materials))

        result = bake_atlas(materials, layout, linear, previous, progress=on_material, cache_dir=cache_dir, jobs=jobs,
                            pinned_slots=pinned)  # fmt: skip
    if strict and result.material_warnings:
        count = len(result.material_warnings)
        raise BakeWarnings(f"--strict: {count} material warning{'s' * (count != 1)}, no atlas written: "
                           + "; ".join(str(w) for w in result.material_warnings))  # fmt: skip
    write_bake(result, output, preview, zstd, languages, extra_files)
    if verbosity == VERBOSE:
        for line in _describe_materials(result):
            click.echo(line, err=True)
    if verbosity != QUIET:
        # An empty atlas is allowed (a fresh one, or --allow-empty), but a folder or name given by mistake
        # should not pass without a word: the line below names no material count.
        nothing = []
        if not every_material:
            nothing = [f"{', '.join(Path(p).as_posix() for p in sources or ['materials'])}: no material files; "
                       "the atlas holds no materials"]  # fmt: skip
        elif not materials:
            nothing = [f"{Path(scene).as_posix()}: the scene has no objects; the atlas holds no materials"]
        echo_warnings([*nothing, *result.warnings, *result.material_warnings])
        click.echo(result.describe(output, zstd))


def _refuse_a_report_as_manifest(manifest: Path) -> None:
    """Refuse an atlas named report.* in a report's folder: its manifest's name is the report's report.json, which the
    bake read as a damaged manifest (exit 3, advising to delete another command's report)."""
    kind = folder_report_kind(manifest.parent) if manifest.name == "report.json" else None
    if kind is not None:
        raise OutputError(f"{manifest.as_posix()}: the manifest written beside the atlas would replace a {kind} report; "
                          "expected a folder of its own for each command's outputs")  # fmt: skip


#: bake's options that shape only the atlas and its side files, which --cache-only does not write.
_ATLAS_ONLY_OPTIONS = ("output", "layout", "linear", "zstd", "preview", "ids_from", "include_languages", "allow_empty",
                       "strict")  # fmt: skip


def _refuse_atlas_options(ctx) -> None:
    """Refuse an atlas option given with --cache-only, rather than ignore it (--strict's warnings, say, are
    measured on the assembled atlas)."""
    refuse_options(ctx, _ATLAS_ONLY_OPTIONS, "with --cache-only, which writes no atlas (only the cache and --depfile)")


def _material_inputs(materials) -> list:
    """The files a bake of ``materials`` reads: each material's file, then the files MaterialX documents include."""
    return [m.source for m in materials] + [p for m in materials for p in m.includes]


def _describe_materials(result) -> list[str]:
    """One line per baked material: its slices and whether it was baked or loaded from the cache."""
    cached = set(result.timings.get("cache", {}).get("hits", []))
    lines = []
    for entry in result.manifest.materials:
        first, count = entry.first_slice, entry.slice_count
        slices = f"slice {first}" if count == 1 else f"slices {first}-{first + count - 1}"
        how = (
            "loaded from the cache"
            if entry.name in cached
            else f"baked in {result.timings['materials'][entry.name].get('bake_s', 0.0):.3f} s"
        )
        lines.append(f"  {entry.name}: {entry.type}, {slices}, {how}")
    return lines


@app.command()
@click.argument("atlas", type=PathArg(path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True)
@verbosity_options(quiet="Print only the one-line description (text format).",
                   verbose="Also print each material's description and source file (text format).")  # fmt: skip
@fail_on_errors
def info(atlas, fmt, verbosity):
    """Print an atlas's DDS or KTX2 header and a summary of its manifest.

    It says of each include and the separable side-car beside the atlas whether it is of this bake (it records the
    manifest's SHA-256 and holds what a bake of the manifest writes), edited since its bake, of another bake, not
    atlasgen's, or absent: an engine that loads an include of another bake than its atlas reads other slices and
    scales than the include declares. The manifest's entries are checked as render checks them.

    With --format json the output follows the JSON Schema atlasgen/schemas/info.schema.json
    (and the manifest itself atlasgen/schemas/manifest.schema.json).
    """
    if fmt == "json":
        # The JSON is the same whatever they say.
        refuse_options(click.get_current_context(), ("--quiet", "--verbose"), "with --format json, which prints the "
                       "whole summary")  # fmt: skip
        click.echo(json.dumps(summarize_atlas(atlas, expected=_checked_companions), indent=2))
    else:
        click.echo(describe_atlas(atlas, verbose=verbosity == VERBOSE, quiet=verbosity == QUIET, expected=_checked_companions))


def _checked_companions(atlas) -> dict:
    """The manifest's entries checked by their models, as every command that renders from it checks them (info passed
    a type it does not know, or a lambert with a bias, that render refused), then the bytes a bake of it writes."""
    check_manifest_models(atlas.manifest, atlas.manifest_path.as_posix())
    return expected_companions(atlas)


def main(argv=None):
    # Not click's standalone mode, so that what ends the run outside a command (a Ctrl-C
    # while the arguments are parsed, an unknown top-level option) is one line too.
    try:
        # From here a Ctrl-C raises KeyboardInterrupt (and SIGTERM, from the command line, Terminated),
        # so a command's clean-up runs; before it, since the first import of atlasgen.cli, either
        # ended the process with the same line.
        end_start_up_interrupts(command_line=_launched_as_the_command_line())
        status = app.main(args=argv, prog_name="atlasgen", standalone_mode=False)
    except click.Abort as exc:  # click's form of a KeyboardInterrupt
        exit_for(exc.__context__ if isinstance(exc.__context__, KeyboardInterrupt) else exc)
    except (SystemExit, click.exceptions.Exit):
        raise
    except BaseException as exc:  # noqa: BLE001
        exit_for(exc)
    finally:
        # The command has ended (its outputs committed or left, its line printed): a Ctrl-C (or SIGTERM) from here on
        # could only turn its exit into a traceback from Python's shutdown, or a silent death by SIGINT.
        if _launched_as_the_command_line():
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
    sys.exit(status if isinstance(status, int) else 0)


def _launched_as_the_command_line() -> bool:
    """Whether this process is the ``atlasgen`` script or ``python -m atlasgen`` (which call :func:`main`)."""
    launcher = sys.modules.get("__main__")
    spec = getattr(launcher, "__spec__", None)
    return (spec is not None and spec.name in ("atlasgen.__main__", "atlasgen.cli.main")) or (
        Path(getattr(launcher, "__file__", "") or "").name == "atlasgen"
    )


if not _launched_as_the_command_line():
    end_start_up_interrupts()  # imported as a library (tests, notebooks): Ctrl-C as Python has it

if __name__ == "__main__":
    main()
