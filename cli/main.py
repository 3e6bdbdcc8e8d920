"""The ``atlasgen`` command line: a thin click layer over the library.

Exit codes (docs/cli.md): 0 success, 1 internal error, 2 usage error (click),
3 bad input (material, scene, missing path), 4 output cannot be written,
5 a backend is missing (Mitsuba's LLVM variant, a GPU adapter).
"""

from __future__ import annotations

import importlib
import importlib.util
import json
import sys
from pathlib import Path

import click

from atlasgen import __version__
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


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="atlasgen")
def app():
    """atlasgen: bake BRDF materials into a 64x32x256 atlas for fully deferred renderers."""


@app.command()
@click.argument("paths", nargs=-1, type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), default=Path("build/atlas.dds"), show_default=True,
              help="DDS to write; X.json (manifest), X.wgsl (include) and X.timings.json go beside it.")
@click.option("--layout", type=click.Choice(["array", "volume"]), default="array", show_default=True,
              help="Texture2DArray (a mip chain per material) or Texture3D (mips blend neighbouring materials).")
@click.option("--linear", is_flag=True, help="Store RGB linearly (DXGI 28) instead of sRGB (DXGI 29).")
@click.option("--preview", type=click.Path(path_type=Path), default=None, help="Also write a labelled contact sheet PNG.")
@click.option("--scene", type=click.Path(path_type=Path), default=None,
              help="Bake only the materials this scene references.")
@click.option("--ids-from", type=click.Path(path_type=Path), default=None,
              help="Take slice IDs from this manifest (e.g. the full library's build/atlas.json).")
@click.option("--cache", "cache_dir", type=click.Path(path_type=Path), default=None,
              help="Per-material cache folder: unchanged materials are loaded, not re-baked.")
@click.option("--cache-only", is_flag=True, help="Only fill the cache (with --cache); write no atlas.")
@click.option("--depfile", type=click.Path(path_type=Path), default=None,
              help="Also write a Make dependency file: the atlas against each baked material file (and its cache entry).")
@click.option("--allow-empty", is_flag=True, help="Allow replacing an atlas that has materials with an empty one.")
@click.option("-q", "--quiet", is_flag=True, help="Print only errors.")
@fail_on_errors
def bake(paths, output, layout, linear, preview, scene, ids_from, cache_dir, cache_only, depfile, allow_empty, quiet):
    """Bake material definitions (files or folders; default: materials/) into an atlas."""
    from atlasgen.bake.outputs import check_bake_outputs
    from atlasgen.bake.pipeline import bake_atlas, read_previous_slots, sibling_paths, write_bake
    from atlasgen.materials.material import read_materials, select_scene_materials

    if cache_only and cache_dir is None:
        raise click.UsageError("--cache-only needs --cache DIR")
    materials = read_materials(paths or [Path("materials")])
    if scene is not None:
        materials = select_scene_materials(materials, scene)
    # Every output path is checked before anything (the cache included) is written.
    check_bake_outputs(output, materials, preview, depfile, cache_dir, scene, ids_from, allow_empty, cache_only)
    if cache_only:
        from atlasgen.bake.cache import fill_cache

        fill_cache(cache_dir, materials)
        return
    previous = read_previous_slots(ids_from) if ids_from is not None else {}
    previous.update(read_previous_slots(sibling_paths(output)["manifest"]))
    show_bar = not quiet and sys.stderr.isatty()
    if show_bar:
        with click.progressbar(length=len(materials), label="baking", file=sys.stderr) as bar:
            result = bake_atlas(materials, layout, linear, previous, progress=lambda _: bar.update(1), cache_dir=cache_dir)
    else:
        result = bake_atlas(materials, layout, linear, previous, cache_dir=cache_dir)
    extra_files = {}
    if depfile is not None:
        # Written in the same commit as the atlas: a depfile that cannot be written fails
        # the bake before the atlas is replaced.
        from atlasgen.bake.cache import cache_path
        from atlasgen.io.depfile import format_depfile

        inputs = [m.source for m in materials] + ([scene] if scene is not None else [])
        if cache_dir is not None:
            inputs += [cache_path(cache_dir, m) for m in materials]
        extra_files[depfile] = format_depfile(output, inputs).encode()
    write_bake(result, output, preview, extra_files)
    if not quiet:
        for warning in result.warnings:
            click.echo(f"atlasgen: warning: {warning}", err=True)
        click.echo(result.describe(output))


@app.command()
@click.argument("atlas", type=click.Path(path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True)
@fail_on_errors
def info(atlas, fmt):
    """Print an atlas's DDS header and a summary of its manifest."""
    from atlasgen.io.atlas import summarize_atlas

    summary = summarize_atlas(atlas)
    if fmt == "json":
        click.echo(json.dumps(summary, indent=2))
        return
    h = summary["header"]
    click.echo(summary["line"])
    click.echo(f"  format {h['dxgi_format']} ({h['format_name']}), layout {h['layout']}, "
               f"{h['width']}x{h['height']}, {h['layers']} layers, {h['mip_count']} mips")
    m = summary.get("manifest")
    if m is None:
        click.echo("  no manifest beside it")
        return
    click.echo(f"  manifest v{m['format_version']}, encoding {m['encoding']}, {len(m['materials'])} materials, "
               f"{m['slices_used']} slices used")
    for e in m["materials"]:
        click.echo(f"  {e['first_slice']:>3}+{e['slice_count']:<2} {e['name']:<24} {e['type']:<11} "
                   f"scale {e['scale']:<18} qerr max {e['qerr_max']:.4f}")


def main(argv=None):
    app.main(args=argv, prog_name="atlasgen")


if __name__ == "__main__":
    main()
