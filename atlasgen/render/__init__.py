"""The bundled deferred renderer (WebGPU through wgpu-py): g-buffer, atlas lighting,
deferred translucency with stencil masking, toon outlines, EXR and PNG output.

Only this module's functions are imported eagerly; wgpu, trimesh and OpenImageIO are
imported inside the functions that need them.
"""

from __future__ import annotations

from pathlib import Path

from atlasgen.bake.outputs import check_depfile_name
from atlasgen.errors import OutputNameError
from atlasgen.io.atomic import refuse_another_sets
from atlasgen.io.depfile import encode_depfile
from atlasgen.io.output_paths import check_output_paths
from atlasgen.materials.scene import ignored_gloss, resolve_materials
from atlasgen.render.atlas_texture import read_render_atlas
from atlasgen.render.output import write_aov, write_render
from atlasgen.render.renderer import AOVS, Renderer

__all__ = ["render_scene", "render_inputs"]


def render_scene(scene, atlas_path, output_path, aov=None, mip_bias=None, outlines=True, depfile=None,
                 warnings=None) -> list[Path]:  # fmt: skip
    """Render a scene (:func:`~atlasgen.materials.scene.read_scene`) with a baked atlas and write the result; return the paths written.

    Without ``aov``: ``output_path`` (linear EXR) and the same path with ``.png``
    (tone-mapped sRGB, the scene's exposure). With ``aov`` (normal, depth, id, albedo):
    that g-buffer layer as an EXR at ``output_path``. ``depfile``: also a Make dependency file, in the
    same commit, naming the image (the PNG, else the EXR) against every file the render read
    (:func:`render_inputs`). ``warnings``: a list that gets a line for each object whose ``gloss`` its material
    does not use (:func:`~atlasgen.materials.scene.ignored_gloss`), for a lit image.

    Raises
    ------
    InputError, SceneError
        Missing or invalid mesh, atlas, manifest or include; unknown material.
    BackendError
        No GPU adapter, or the device reported an error.
    OutputError
        The output cannot be written.
    """
    output_path = Path(output_path)
    if aov is not None and aov not in AOVS:
        raise ValueError(f"aov must be one of {AOVS}, not {aov!r}")
    if output_path.suffix.lower() != ".exr":
        raise OutputNameError(f"{output_path.as_posix()}: expected an .exr output path")
    _check_render_outputs(output_path, aov, scene, atlas_path, depfile)
    atlas = read_render_atlas(atlas_path)
    entries = resolve_materials(scene, atlas.manifest, atlas.name)  # fail before touching the GPU
    if warnings is not None and aov is None:
        warnings += ignored_gloss(scene, entries)
    image = output_path if aov is not None else output_path.with_suffix(".png")
    # Encoded before the render: a path make cannot hold fails the command before minutes of work.
    extra = {} if depfile is None else {Path(depfile): encode_depfile(image, [p for p, _ in render_inputs(scene, atlas_path)])}
    result = Renderer(atlas).render(scene, mip_bias=mip_bias, outlines=outlines, aovs=aov is not None)
    writer = render_writer(output_path)
    if aov is not None:
        write_aov(output_path, aov, result.aov(aov), extra=extra, writer=writer)
        return [output_path, *extra]
    return [*write_render(output_path, result.radiance, scene.settings.exposure, extra=extra, writer=writer), *extra]


def render_writer(output_path) -> str:
    """The render's writer in its output set, which a scene's bake may share (``X.dds`` beside ``X.exr``): a render
    does not replace the bake's files, and drops its own earlier ones (an old depfile) that it does not write."""
    return f"render -o {Path(output_path).name}"


def render_inputs(scene, atlas_path) -> list[tuple[Path, str]]:
    """Every file a render of ``scene`` reads, each with what it is: the scene, the atlas and the files beside it
    that the renderer reads, each object's mesh file and the environment image."""
    atlas_path = Path(atlas_path)
    inputs = [
        (Path(scene.path), "the scene"),
        (atlas_path, "the atlas (--atlas)"),
        (atlas_path.with_suffix(".json"), "the atlas's manifest"),
        (atlas_path.with_suffix(".wgsl"), "the atlas's include"),
    ]
    inputs += [(Path(obj.file), f"the mesh of objects[{obj.index}]") for obj in scene.objects if obj.file is not None]
    if scene.environment is not None and scene.environment.file is not None:
        inputs.append((Path(scene.environment.file), "the scene's environment image"))
    return inputs


def _check_render_outputs(output_path, aov, scene, atlas_path, depfile=None) -> None:
    """Refuse outputs that would overwrite an input (:func:`render_inputs`), a folder, or another command's
    outputs, before anything is rendered."""
    outputs = [(output_path, "the render (-o)")]
    if depfile is not None:
        outputs.append((Path(depfile), "--depfile"))
    png = output_path.with_suffix(".png")
    if aov is None:
        outputs.append((png, "the PNG written beside the render"))
    # With --aov the PNG's name is removed by the commit (write_aov): a scene named X.png was deleted.
    removed = [(png, "the PNG beside the render (removed with --aov)")] if aov is not None else []
    check_output_paths(outputs + removed, render_inputs(scene, atlas_path))
    check_depfile_name(depfile)
    # Before the render, not at its commit; the set's primary is the PNG where one is written (render/output.py).
    refuse_another_sets([path for path, _ in outputs], outputs[-1][0], render_writer(output_path))
