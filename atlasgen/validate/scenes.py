"""The standard validation scenes, and binding a scene to the material under test.

A validation scene is an ordinary renderer scene (docs/scenes.md) in which every
object whose material is :data:`MATERIAL_PLACEHOLDER` takes the material being
validated. The standard ones are installed with the package, in
``atlasgen/data/validation/`` (``front``: a sphere on a plane lit from the front;
``back``: the same lit from behind); any other TOML path works too.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from atlasgen.errors import InputError, SceneError
from atlasgen.io.package_data import package_data_path
from atlasgen.materials.scene import read_scene

__all__ = ["MATERIAL_PLACEHOLDER", "STANDARD_SCENES", "scene_folder", "load_validation_scene", "bind_material", "resize_scene"]

MATERIAL_PLACEHOLDER = "$material"
#: Standard scene name -> one-line description (files: ``atlasgen/data/validation/<name>.toml``).
STANDARD_SCENES = {
    "front": "a sphere on a plane, lit from the front (point key light, directional fill)",
    "back": "the same sphere and plane, lit from behind (point and directional lights)",
    "env-uniform": "a sphere alone under a uniform environment, no lights (Mitsuba: constant)",
    "env-sky": "a sphere alone under the procedural sky, no lights (Mitsuba: envmap of the same image)",
}


def scene_folder() -> Path:
    """The installed folder of the standard validation scenes (package data)."""
    return package_data_path("validation")


def load_validation_scene(name_or_path):
    """A standard scene by name, or a scene TOML by path; ``(name, Scene)``.

    Raises
    ------
    InputError
        Neither a standard name nor an existing file; the message lists the names.
    SceneError
        The file is not a valid scene, or no object uses ``"$material"``.
    """
    text = str(name_or_path)
    if text in STANDARD_SCENES:
        path, name = scene_folder() / f"{text}.toml", text
    else:
        path, name = Path(text), Path(text).stem
        if not path.is_file():
            raise InputError(
                f"{text}: unknown validation scene; expected one of {', '.join(STANDARD_SCENES)} or a scene TOML file"
            )
    scene = read_scene(path)
    if not any(o.material == MATERIAL_PLACEHOLDER for o in scene.objects):
        raise SceneError(scene.path, "objects", f"no object uses material = {MATERIAL_PLACEHOLDER!r}; expected at least one")
    return name, scene


def bind_material(scene, material: str):
    """A copy of ``scene`` with the placeholder material replaced by ``material``."""
    objects = [dataclasses.replace(o, material=material) if o.material == MATERIAL_PLACEHOLDER else o for o in scene.objects]
    return dataclasses.replace(scene, objects=objects)


def resize_scene(scene, width: int | None = None, height: int | None = None):
    """A copy of ``scene`` rendered at another resolution (same camera and field of view)."""
    return dataclasses.replace(scene, width=int(width or scene.width), height=int(height or scene.height))
