"""``atlasgen render``: a thin click layer over :mod:`atlasgen.render`."""

from __future__ import annotations

from pathlib import Path

import click

from atlasgen.cli.main import FiniteFloatRange, echo_warnings, fail_on_errors
from atlasgen.cli.options import HELP_OPTIONS, QUIET, VERBOSE, PathArg, refuse_options, verbosity_options
from atlasgen.io.fields import counted
from atlasgen.materials.scene import read_scene
from atlasgen.render import render_scene

__all__ = ["render"]

AOVS = ("normal", "depth", "id", "albedo")


@click.command("render", context_settings=HELP_OPTIONS)
@click.argument("scene", type=PathArg(path_type=Path))
@click.option("--atlas", type=PathArg(path_type=Path), metavar="FILE", default=Path("build/atlas.dds"),
              show_default=True, help="Baked atlas; its manifest X.json and include X.wgsl must sit beside it.")  # fmt: skip
@click.option("-o", "--output", type=PathArg(path_type=Path, file_output=True), required=True,
              help="EXR to write (linear radiance); a tone-mapped PNG is written beside it.")  # fmt: skip
@click.option("--aov", type=click.Choice(AOVS), default=None,
              help="Write this g-buffer layer to OUTPUT instead of the lit image (no PNG).")  # fmt: skip
@click.option("--mip-bias", type=FiniteFloatRange(-16.0, 16.0), default=None, metavar="FLOAT",
              help="Added to the depth-chosen mip level (overrides the scene).")  # fmt: skip
@click.option("--no-outlines", is_flag=True, help="Skip the toon-outline pass.")
@click.option("--depfile", type=PathArg(path_type=Path, file_output=True), default=None, metavar="FILE",
              help="Also write a Make dependency file, with the image: the PNG (the EXR with --aov) against every file "
                   "the render reads (the scene, the atlas and its manifest and include, meshes, the environment image).")  # fmt: skip
@verbosity_options(verbose="Also print the scene's size, objects, lights and materials before rendering.")
@fail_on_errors
def render(scene, atlas, output, aov, mip_bias, no_outlines, depfile, verbosity):
    """Render SCENE (TOML, see docs/scenes.md) with the deferred renderer."""
    if aov is not None:  # a g-buffer layer is drawn before the lighting and the outlines
        refuse_options(click.get_current_context(), ("mip_bias", "no_outlines"),
                       "with --aov, which writes a g-buffer layer (no atlas lookup, no outlines)")  # fmt: skip
    s = read_scene(scene)
    if verbosity == VERBOSE:
        materials = ", ".join(dict.fromkeys(o.material for o in s.objects)) or "none"
        click.echo(f"{scene.as_posix()}: {s.width}x{s.height}, {counted(len(s.objects), 'object')}, "
                   f"{counted(len(s.lights), 'light')}; "
                   f"materials {materials}", err=True)  # fmt: skip
    ignored = []
    written = render_scene(s, atlas, output, aov=aov, mip_bias=mip_bias, outlines=not no_outlines, depfile=depfile,
                           warnings=ignored)  # fmt: skip
    if verbosity != QUIET:
        # After the render: a scene that fails gets its one error line and nothing else.
        echo_warnings([*s.warnings(), *ignored] if aov is None else [])
        for path in written:
            click.echo(f"wrote {path.as_posix()}")
