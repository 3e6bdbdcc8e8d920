"""``atlasgen validate``: a thin click layer over :mod:`atlasgen.validate`."""

from __future__ import annotations

import math
from pathlib import Path

import click

from atlasgen.cli.main import echo_warnings, fail_on_errors
from atlasgen.cli.options import (
    HELP_OPTIONS,
    MAX_SPP,
    QUIET,
    VERBOSE,
    MaterialProgress,
    PathArg,
    refuse_options,
    verbosity_options,
)
from atlasgen.errors import GoalsMissed
from atlasgen.io.output_paths import check_cache_folder, check_output_folder, refuse_inputs_in_folder
from atlasgen.reports.report_kind import refuse_another_report
from atlasgen.reports.validation import (
    describe_materials,
    merge_validation_reports,
    missed_goals,
    noise_floor_failures,
    summary_line,
    write_validation,
)
from atlasgen.validate.reference_cache import DEFAULT_REFERENCE_CACHE
from atlasgen.validate.run import (
    ENVIRONMENT_SCENES,
    ENVIRONMENT_SPP,
    MAX_ENVIRONMENT_SPP,
    MAX_PHYSICAL_SPP,
    PHYSICAL_SPP,
    validate_atlas,
)
from atlasgen.validate.scenes import STANDARD_SCENES

__all__ = ["validate"]


def _resolution(ctx, param, value):
    if value is None:
        return None
    try:
        w, h = (int(x) for x in value.lower().split("x"))
    except ValueError:
        raise click.BadParameter(f"expected WIDTHxHEIGHT, e.g. 128x96, got {value!r}") from None
    if not (1 <= w <= 4096 and 1 <= h <= 4096):
        raise click.BadParameter(f"expected sizes in [1, 4096], got {value!r}")
    return w, h


def _square_spp(ctx, param, value):
    """The model references' samples per pixel, a square: Mitsuba's stratified sampler lays them out k x k, and
    rounded --spp 2 up to 4 with a warning on stdout, while the report recorded 2."""
    if value is not None and math.isqrt(value) ** 2 != value:
        k = math.isqrt(value)
        raise click.BadParameter(f"expected a square number of samples (1, 4, 9, 16, ...; {k * k} or {(k + 1) ** 2} "
                                 f"here), which Mitsuba's stratified sampler lays out k x k, got {value}")  # fmt: skip
    return value


#: validate's options that shape the renders, which --merge does not make: given with it, they are refused.
_RENDER_OPTIONS = ("scenes", "spp", "physical_spp", "max_physical_spp", "resolution", "no_physical", "environment", "atlas",
                   "bake_cache", "reference_cache", "no_reference_cache")  # fmt: skip


@click.command("validate", context_settings=HELP_OPTIONS)
@click.argument("materials", nargs=-1)
@click.option("--scene", "scenes", multiple=True, default=("front", "back"), show_default=True,
              help="Validation scene: a standard name (front, back) or a scene TOML with material = \"$material\". Repeatable.")  # fmt: skip
@click.option("--spp", type=click.IntRange(1, MAX_SPP), default=1, show_default=True, callback=_square_spp,
              help="Mitsuba samples per pixel for the model references, a square (1 = pixel centres, like the rasteriser; "
                   "k x k = a k x k grid in each pixel, averaged).")  # fmt: skip
@click.option("--physical-spp", type=click.IntRange(1, MAX_SPP), default=PHYSICAL_SPP, show_default=True,
              help="Samples per pixel for stochastic physical references (sss volpathmis, spectral iridescent), to start with: each renders with two seeds (their PSNR is its noise floor), and gets the samples its floor needs (it rises 10 log10 of the ratio) while the floor is not 10 dB above the error it measures, up to --max-physical-spp in all.")  # fmt: skip
@click.option("--max-physical-spp", type=click.IntRange(1, MAX_SPP), default=None,
              help=f"The most samples per pixel a stochastic physical reference grows to (default {MAX_PHYSICAL_SPP}); a reference that stops short is named in the summary (and fails --strict). Given, it caps an environment scene's reference too, never below the {ENVIRONMENT_SPP} samples that one starts at (left out, it stops at {MAX_ENVIRONMENT_SPP}).")  # fmt: skip
@click.option("--resolution", callback=_resolution, default=None, metavar="WxH",
              help="Override the scenes' image size (default: the scene's, 128x96 for the standard ones).")  # fmt: skip
@click.option("--no-physical", is_flag=True, help="Skip the physical references.")
@click.option("--environment", is_flag=True,
              help="Also validate environment lighting: the scenes env-uniform (Mitsuba constant) and env-sky (envmap), "
                   "a lone 64x64 sphere, on the material's pixels, against the model reference.")  # fmt: skip
@click.option("--atlas", type=PathArg(path_type=Path), metavar="FILE", default=Path("build/atlas.dds"),
              show_default=True, help="Baked atlas; X.json and X.wgsl must sit beside it.")  # fmt: skip
@click.option("-o", "--output", type=PathArg(path_type=Path), default=Path("build/validation"),
              show_default=True, help="Folder for index.html, report.json, images and the plot.")  # fmt: skip
@click.option("--cache", "bake_cache", type=PathArg(path_type=Path), metavar="DIRECTORY", default=Path("build/cache"),
              show_default=True, help="The bake's cache (atlasgen bake --cache): float slices are read from a material's current entry there instead of being computed or fitted again.")  # fmt: skip
@click.option("--reference-cache", type=PathArg(path_type=Path), metavar="DIRECTORY", default=DEFAULT_REFERENCE_CACHE,
              show_default=True, help="Folder of reference renders, keyed by everything that decides each image: a second run renders nothing it holds.")  # fmt: skip
@click.option("--no-reference-cache", is_flag=True, help="Keep reference renders for this run only.")
@click.option("--merge", is_flag=True,
              help="Render nothing: merge the report.json of earlier runs, the folders given as arguments, "
                   "into one OUTPUT/index.html, report.json and plot.")  # fmt: skip
@click.option("--strict", is_flag=True, help="Exit with code 6 when a goal is missed (the report is still written): for CI.")
@verbosity_options(quiet="Print only errors and the final summary line.",
                   verbose="Print a line after every render instead of one per material.")  # fmt: skip
@fail_on_errors
def validate(
    materials,
    scenes,
    spp,
    physical_spp,
    max_physical_spp,
    resolution,
    no_physical,
    environment,
    atlas,
    bake_cache,
    reference_cache,
    no_reference_cache,
    output,
    merge,
    strict,
    verbosity,
):
    """Compare baked MATERIALs (default: all in the atlas) with Mitsuba 3 references.

    Each material is rendered on each validation scene by the bundled deferred
    renderer through the atlas, and by Mitsuba 3 with its model reference (the exact
    model the slice was baked from) and, where one exists, a physical reference.
    Writes OUTPUT/index.html and OUTPUT/report.json (docs/validation.md).

    A MATERIAL is a name in the atlas or a material file (X.toml, which must be the
    file the atlas was baked from). With --merge the arguments are folders of earlier
    runs (e.g. one per material) whose reports are combined without rendering.

    Prints one line per material naming what was measured against which goal, then
    the summary line. The goals: each LUT material's image against its model
    reference on every scene (storage: PSNR and mean FLIP); every material's look
    against its physical reference, or a separable one's source BSDF (a looser PSNR and
    FLIP, judged where the reference's noise floor allows); each separable material's
    claimed error against its error_budget, where it has one.
    """
    ctx = click.get_current_context()
    if merge:
        # -v prints a line per render; -q stays (it keeps the merge to its summary line).
        refuse_options(ctx, (*_RENDER_OPTIONS, "--verbose"), "with --merge, which renders nothing (it combines earlier "
                       "reports)")  # fmt: skip
    else:
        if no_reference_cache:
            refuse_options(ctx, ("reference_cache",), "with --no-reference-cache, which keeps no reference renders")
        if no_physical:  # --max-physical-spp stays where an environment scene's reference is rendered: it caps that
            refuse_options(ctx, ("physical_spp",), "with --no-physical, which renders no physical reference")
            if not environment and all(s in STANDARD_SCENES and s not in ENVIRONMENT_SCENES for s in scenes):
                refuse_options(ctx, ("max_physical_spp",), "with --no-physical and no environment scene, where it caps "
                               "no reference", "--environment (whose references it caps), or no --max-physical-spp")  # fmt: skip
    if not merge:
        _refuse_repeated_scenes(scenes)
    check_output_folder(output, "the report folder (-o)", writes=("report.json", "index.html"))
    if not merge:
        refuse_inputs_in_folder(output, [(atlas, "the atlas (--atlas)"), (atlas.with_suffix(".json"), "the atlas's manifest"),
                                         *((Path(s), "the scene (--scene)") for s in scenes if s not in STANDARD_SCENES),
                                         *((Path(m), "the material file") for m in materials if Path(m).is_file())])  # fmt: skip
    refuse_another_report(output, "validation")  # before minutes of rendering: the commit refuses it again
    if not merge:  # the caches are written as the renders finish: refused now, not after them
        check_cache_folder(bake_cache, "--cache")
        if not no_reference_cache:
            check_cache_folder(reference_cache, "--reference-cache")
    if not no_physical and max_physical_spp is not None and max_physical_spp < physical_spp:  # left out, it rises to it
        raise click.BadParameter(f"expected at least --physical-spp ({physical_spp}), got {max_physical_spp}",
                                 param_hint="'--max-physical-spp'")  # fmt: skip
    warnings = []
    if merge:
        written = merge_validation_reports([Path(m) for m in materials], output)
    else:

        def progress(text):
            if verbosity == VERBOSE:
                click.echo(text, err=True)

        if environment:
            scenes = tuple(dict.fromkeys((*scenes, *ENVIRONMENT_SCENES)))
        with MaterialProgress("validated", verbosity) as on_material:
            run = validate_atlas(atlas, materials or None, scenes, spp=spp, physical_spp=physical_spp,
                                 max_physical_spp=max_physical_spp,
                                 resolution=resolution, physical=not no_physical, progress=progress,
                                 on_material=on_material, bake_cache=bake_cache,
                                 reference_cache=None if no_reference_cache else reference_cache)  # fmt: skip
        written = write_validation(run, output)
        warnings = run.warnings  # reference-cache entries not used (damaged, or not a render of this size)

    if verbosity != QUIET:
        for line in describe_materials(written["data"]):
            click.echo(line)
    click.echo(summary_line(written["data"], written["html"]))
    echo_warnings([*warnings, *noise_floor_failures(written["data"])])  # loud even without --strict: noise-limited figures
    missed = missed_goals(written["data"])
    if strict and missed:
        raise GoalsMissed(f"{Path(written['html']).as_posix()}: {len(missed)} goal(s) missed: {'; '.join(missed)}")


def _refuse_repeated_scenes(scenes) -> None:
    """The same --scene given twice (a standard name, or one scene file however its path is spelled) is
    a usage error, exit 2; two different files whose scenes share a name stay bad input (validate_atlas)."""
    seen = {}
    for s in scenes:
        key = s if s in STANDARD_SCENES else Path(s).resolve().as_posix()
        if key in seen:
            raise click.BadParameter(f"{s} is given twice (the first: --scene {seen[key]}); expected each scene once",
                                     param_hint="'--scene'")  # fmt: skip
        seen[key] = s
