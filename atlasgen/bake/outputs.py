"""A bake's output paths, checked before anything is baked or written."""

from __future__ import annotations

import os
from pathlib import Path

from atlasgen.bake.cache import cache_path
from atlasgen.bake.pipeline import ATLAS_SUFFIXES, bake_writer, other_container_path, read_previous_slots, sibling_paths
from atlasgen.errors import OutputError, OutputNameError
from atlasgen.io.atomic import refuse_another_sets
from atlasgen.io.output_paths import check_output_paths, check_suffix
from atlasgen.materials.material import is_material_file_name
from atlasgen.materials.scene import read_scene

__all__ = ["ATLAS_SUFFIXES", "check_bake_outputs", "check_depfile_name"]


def check_bake_outputs(dds_path, materials, preview=None, depfile=None, cache_dir=None, scene=None, ids_from=None,
                       allow_empty=False, cache_only=False, library=None, depfile_target=None) -> None:  # fmt: skip
    """Refuse a bake whose outputs clash with its inputs or each other, or would empty an atlas.

    Checked: the atlas's extension (:data:`ATLAS_SUFFIXES`) and the preview's (``.png``);
    no output (atlas, manifest, include, timings, preview, depfile, cache entries) is a
    folder, lies under a file, names an input (a material or scene file, ``--ids-from``)
    or another output; and an atlas whose manifest lists materials is not replaced by an
    empty one unless ``allow_empty``. With ``cache_only`` only the cache entries and the depfile
    are written, and checked. ``library`` is every material read (``materials`` being those a scene
    selected from it): all of their files are inputs. The depfile is not named as a material file (a folder's
    next bake would read it as one), and its target (``depfile_target``) is none of the inputs (which it would
    then make depend on themselves).

    Raises
    ------
    OutputError
        The first problem found, on one line.
    """
    paths = sibling_paths(dds_path)
    outputs = []
    if not cache_only:
        check_suffix(dds_path, "the atlas (-o)", ATLAS_SUFFIXES)
        if preview is not None:
            check_suffix(preview, "--preview", (".png",))
        outputs += [
            (paths["dds"], "the atlas (-o)"),
            (paths["manifest"], "the manifest written beside the atlas"),
            (paths["include"], "the include written beside the atlas"),
            (paths["timings"], "the timings written beside the atlas"),
            # Written or removed by the commit, whatever this bake writes: --depfile X.ktx2 beside X.dds, or X.glsl
            # where only WGSL was asked for, was written as a Make fragment under the name an engine loads.
            (paths["glsl"], "the GLSL include's name beside the atlas"),
            (paths["hlsl"], "the HLSL include's name beside the atlas"),
            (paths["separable"], "the separable side-car's name beside the atlas"),
            (other_container_path(paths["dds"]), "the other container's name beside the atlas (removed by the bake)"),
        ]
        if preview is not None:
            outputs.append((preview, "--preview"))
    if depfile is not None:
        outputs.append((depfile, "--depfile"))
    committed = [path for path, _ in outputs]  # the files of the atlas's output set (the cache entries are not)
    if cache_dir is not None:
        outputs += [(cache_path(cache_dir, m), f"the cache entry of {m.name!r}") for m in materials]
    read = materials if library is None else library
    inputs = [(m.source, f"the material file of {m.name!r}") for m in read]
    # A MaterialX document's xi:includes are read as much as the document is: an output there would replace one.
    inputs += [(Path(f), f"a file the material file of {m.name!r} includes") for m in read for f in m.includes]
    if scene is not None:
        inputs.append((scene, "the scene (--scene)"))
        inputs += [(obj.file, f"the mesh of the scene's objects[{obj.index}]")
                   for obj in read_scene(scene).objects if obj.file is not None]  # fmt: skip
    # realpath, not resolve(): Python 3.11's resolve raises RuntimeError on a symbolic link loop (an internal error,
    # exit 1); the loop is then refused by the manifest's reader on one line.
    if ids_from is not None and os.path.realpath(ids_from) != os.path.realpath(paths["manifest"]):
        inputs.append((ids_from, "--ids-from"))
    check_output_paths(outputs, inputs)
    _check_depfile_names(depfile, depfile_target, inputs)
    if not cache_only:
        # An output that is another set's link (--depfile build/atlas.dds beside a scene atlas) is refused at the
        # commit too, but by then the lock had made this set's store: refused here, the bake leaves nothing behind.
        refuse_another_sets([*committed, *paths.values()], paths["dds"], bake_writer(paths["dds"]))
    if not materials and not allow_empty and not cache_only:
        existing = read_previous_slots(paths["manifest"])
        if existing or (paths["dds"].exists() and not paths["manifest"].exists()):
            what = f"{len(existing)} materials" if existing else "materials"
            raise OutputError(f"{paths['dds'].as_posix()}: no materials to bake would replace an atlas of {what} "
                              "with an empty one; expected material files (or --allow-empty)")  # fmt: skip


def check_depfile_name(depfile) -> None:
    """Refuse a ``--depfile`` (of any command) named as a material file: in a folder a bake reads, the next bake read
    the make fragment as a material and failed on it, as did every bake after it until it was removed by hand."""
    if depfile is not None and is_material_file_name(Path(depfile).name):
        raise OutputNameError(f"{Path(depfile).as_posix()}: --depfile must not end in .toml or .mtlx, the names bake "
                              "reads as material files; expected a make fragment's name, such as atlas.d")  # fmt: skip


def _check_depfile_names(depfile, target, inputs) -> None:
    """Refuse a depfile named as a material file, and a depfile target that is one of the bake's ``inputs``."""
    check_depfile_name(depfile)
    if target is None:
        return
    for path, role in inputs:
        if os.path.realpath(path) == os.path.realpath(target):
            raise OutputNameError(f"{target}: --depfile-target is {role}, which the depfile would make depend on "
                                  "itself (make drops such a circular dependency); expected the target make builds, "
                                  "such as the atlas or a stamp")  # fmt: skip
