"""The ``atlasgen`` command line: a thin click layer over the library.

Exit codes (docs/cli.md): 0 success, 1 internal error, 2 usage error (click),
3 bad input (material, scene, missing path), 4 output cannot be written,
5 a backend is missing (Mitsuba's LLVM variant, a GPU adapter), 6 ``validate --strict``:
a validation goal was missed.
"""

from __future__ import annotations

import importlib
import importlib.util
import json
import sys
from pathlib import Path

import click

from atlasgen import __version__
from atlasgen.cli.options import NORMAL, QUIET, VERBOSE, verbosity_options
from atlasgen.errors import AtlasgenError

__all__ = ["app", "main", "fail_on_errors"]

#: Subcommands that live in their own module, imported only when invoked, so that
#: ``atlasgen --help`` never pays for the renderer's or the reports' imports.
LAZY_COMMANDS = {
    "render": ("atlasgen.cli.render_cmd", "render", "Render a scene with the bundled deferred renderer."),
    "report": ("atlasgen.cli.report_cmd", "report", "Write reports (separable factorisation, library)."),
    "validate": ("atlasgen.cli.validate_cmd", "validate", "Compare baked materials with Mitsuba 3 references."),
}


class LazyGroup(click.Group):
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
    """Map library errors to a one-line message on stderr and the error's exit code."""
    import functools

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except AtlasgenError as exc:
            click.echo(f"atlasgen: error: {exc}", err=True)
            sys.exit(exc.exit_code)

    return wrapper


@click.group(cls=LazyGroup, invoke_without_command=True, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="atlasgen")
@click.pass_context
def app(ctx):
    """atlasgen: bake BRDF materials into a 64x32x256 atlas for fully deferred renderers."""
    if ctx.invoked_subcommand is None:  # bare `atlasgen`: the help, and success
        click.echo(ctx.get_help())


@app.command()
@click.argument("paths", nargs=-1, type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), default=Path("build/atlas.dds"), show_default=True,
              help="Atlas to write, X.dds or X.ktx2; X.json (manifest), X.wgsl (include) and X.timings.json go beside it.")
@click.option("--layout", type=click.Choice(["array", "volume"]), default="array", show_default=True,
              help="Texture2DArray (a mip chain per material) or Texture3D (mips blend neighbouring materials).")
@click.option("--linear", is_flag=True, help="Store RGB linearly (DXGI 28, VK 37) instead of sRGB (DXGI 29, VK 43).")
@click.option("--zstd", is_flag=True, help="Supercompress each mip level with Zstandard (needs -o X.ktx2).")
@click.option("--preview", type=click.Path(path_type=Path), default=None, help="Also write a labelled contact sheet PNG.")
@click.option("--scene", type=click.Path(path_type=Path), default=None,
              help="Bake only the materials this scene references.")
@click.option("--ids-from", type=click.Path(path_type=Path), default=None,
              help="Take slice IDs from this manifest (e.g. the full library's build/atlas.json).")
@click.option("--cache", "cache_dir", type=click.Path(path_type=Path), default=None,
              help="Per-material cache folder: unchanged materials are loaded, not re-baked.")
@click.option("--include", "include_languages", default="wgsl,glsl,hlsl", show_default=True, metavar="LANGS",
              help="Shader includes to write beside the atlas, comma-separated: wgsl, glsl, hlsl.")
@click.option("--cache-only", is_flag=True, help="Only fill the cache (with --cache); write no atlas.")
@click.option("--depfile", type=click.Path(path_type=Path), default=None,
              help="Also write a Make dependency file: the atlas against each baked material file (and its cache entry).")
@click.option("--library", is_flag=True,
              help="Also bake the material library installed with atlasgen (alone when no PATHS are given).")
@verbosity_options(verbose="Also print each material's slices and whether it was baked or loaded from the cache.")
@fail_on_errors
def bake(paths, output, layout, linear, zstd, preview, scene, ids_from, cache_dir, include_languages, cache_only, depfile, library,
         verbosity):
    """Bake material definitions (files or folders; default: materials/) into an atlas."""
    from atlasgen.bake.pipeline import bake_atlas, read_previous_slots, sibling_paths, write_bake
    from atlasgen.io.package_data import shipped_library
    from atlasgen.materials.material import read_materials, select_scene_materials

    if zstd and output.suffix.lower() != ".ktx2":
        raise click.UsageError("--zstd needs a KTX2 output (-o X.ktx2)")
    languages = tuple(dict.fromkeys(lang.strip().lower() for lang in include_languages.split(",") if lang.strip()))
    unknown = [lang for lang in languages if lang not in ("wgsl", "glsl", "hlsl")]
    if unknown:
        raise click.UsageError(f"--include: unknown language {unknown[0]!r}; expected wgsl, glsl or hlsl, comma-separated")
    sources = list(paths) + ([shipped_library()] if library else [])
    materials = read_materials(sources or [Path("materials")])
    if scene is not None:
        materials = select_scene_materials(materials, scene)
    if cache_only:
        if cache_dir is None:
            raise click.UsageError("--cache-only needs --cache DIR")
        from atlasgen.bake.cache import fill_cache

        filled = fill_cache(cache_dir, materials)
        if verbosity == VERBOSE:
            click.echo(f"cache {cache_dir.as_posix()}: baked {', '.join(filled['baked']) or 'none'}; "
                       f"up to date {', '.join(filled['hits']) or 'none'}", err=True)  # fmt: skip
        return
    previous = read_previous_slots(ids_from) if ids_from is not None else {}
    previous.update(read_previous_slots(sibling_paths(output)["manifest"]))
    show_bar = verbosity == NORMAL and sys.stderr.isatty()
    if show_bar:
        with click.progressbar(length=len(materials), label="baking", file=sys.stderr) as bar:
            result = bake_atlas(materials, layout, linear, previous, progress=lambda _: bar.update(1), cache_dir=cache_dir)
    else:
        result = bake_atlas(materials, layout, linear, previous, cache_dir=cache_dir)
    write_bake(result, output, preview, zstd, languages)
    if depfile is not None:
        from atlasgen.bake.cache import cache_path
        from atlasgen.io.depfile import write_depfile

        inputs = [m.source for m in materials] + ([scene] if scene is not None else [])
        if cache_dir is not None:
            inputs += [cache_path(cache_dir, m) for m in materials]
        write_depfile(depfile, output, inputs)
    if verbosity == VERBOSE:
        for line in _describe_materials(result):
            click.echo(line, err=True)
    if verbosity != QUIET:
        for warning in result.warnings:
            click.echo(f"atlasgen: warning: {warning}", err=True)
        click.echo(result.describe(output, zstd))


def _describe_materials(result) -> list[str]:
    """One line per baked material: its slices and whether it was baked or loaded from the cache."""
    cached = set(result.timings.get("cache", {}).get("hits", []))
    lines = []
    for entry in result.manifest.materials:
        first, count = entry.first_slice, entry.slice_count
        slices = f"slice {first}" if count == 1 else f"slices {first}-{first + count - 1}"
        how = "loaded from the cache" if entry.name in cached else \
            f"baked in {result.timings['materials'][entry.name].get('bake_s', 0.0):.3f} s"
        lines.append(f"  {entry.name}: {entry.type}, {slices}, {how}")
    return lines


@app.command()
@click.argument("atlas", type=click.Path(path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True)
@verbosity_options(quiet="Print only the one-line description (text format).",
                   verbose="Also print each material's description and source file (text format).")  # fmt: skip
@fail_on_errors
def info(atlas, fmt, verbosity):
    """Print an atlas's DDS or KTX2 header and a summary of its manifest.

    With --format json the output follows the JSON Schema atlasgen/schemas/info.schema.json
    (and the manifest itself atlasgen/schemas/manifest.schema.json).
    """
    from atlasgen.io.atlas import describe_atlas, summarize_atlas

    if fmt == "json":
        click.echo(json.dumps(summarize_atlas(atlas), indent=2))
    else:
        click.echo(describe_atlas(atlas, verbose=verbosity == VERBOSE, quiet=verbosity == QUIET))


def main(argv=None):
    app.main(args=argv, prog_name="atlasgen")


if __name__ == "__main__":
    main()
