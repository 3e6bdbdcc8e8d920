"""The preview's standard scene: a sphere and the material ball side by side on a floor.

The scene is the dict a TOML scene file parses to (docs/scenes.md), validated by
:func:`atlasgen.materials.scene.parse_scene`, so it says nothing the scene format cannot.
Units are the format's: a directional light's ``intensity`` is the irradiance E (W/m^2)
normal to it, and a white Lambertian surface facing it has radiance E / pi.

The values were picked by looking at a Lambertian clay, rough gold (``separable-gold``) and
skin: the key light comes from above the camera's left shoulder, so the faces the camera sees
are lit and gold shows its broad highlight on both objects; the rim light, from behind on the
right, draws the silhouettes, the groove's edges and the rim, where skin's scattering and
Fresnel effects show; the floor is a dark grey so that it frames the objects without
outshining them.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

from atlasgen.io.atomic import write_file_atomically
from atlasgen.materials.scene import Scene, parse_scene
from atlasgen.render.meshes import Mesh, encode_mesh_ply

__all__ = [
    "ENVIRONMENT",
    "PREVIEW_SCENE",
    "WIDTH",
    "HEIGHT",
    "preview_scene_data",
    "parse_preview_scene",
    "ball_mesh_file",
]

#: What the preview is lit by besides its two lights: the built-in procedural sky (docs/scenes.md,
#: "Environment"), dimmed so that the key light still models the form; it is also the background.
ENVIRONMENT = {"source": "sky", "intensity": 0.6}
#: The name errors in the preview scene are reported under.
PREVIEW_SCENE = "<preview scene>"
#: One material's picture, in pixels, before its label.
WIDTH, HEIGHT = 640, 400


def preview_scene_data(material: str, floor_material: str, ball_file) -> dict:
    """The scene showing ``material`` on a sphere (left) and the material ball (right), as parsed TOML.

    ``floor_material`` is the floor's material and ``ball_file`` the ball's mesh file
    (:func:`ball_mesh_file`). Both objects have radius 1 and rest on the floor at y = 0.
    """
    return {
        "camera": {"position": [0.0, 3.1, 7.6], "target": [0.0, 0.75, 0.0], "fov": 42.0},
        "image": {"width": WIDTH, "height": HEIGHT},
        "environment": dict(ENVIRONMENT),
        "lights": [
            # Key: from above the camera's left shoulder; a point light, so the floor falls off.
            {"type": "point", "position": [-4.0, 6.5, 5.5], "intensity": 90.0, "colour": [1.0, 0.97, 0.92]},
            # Rim: from the right and a little behind, a little cooler: it draws the right-hand edges.
            {"type": "directional", "direction": [-0.8, -0.3, 0.52], "intensity": 1.2, "colour": [0.85, 0.92, 1.0]},
        ],
        "objects": [
            {"shape": "plane", "material": floor_material, "scale": 12.0, "albedo": [0.1, 0.1, 0.1]},
            {"shape": "sphere", "material": material, "translate": [-1.2, 1.0, 0.0], "segments": 128, "gloss": 0.6},
            {"shape": "mesh", "file": str(ball_file), "material": material, "translate": [1.2, 1.0, 0.0], "gloss": 0.6},
        ],  # fmt: skip
    }


def parse_preview_scene(data: dict) -> Scene:
    """``data`` (:func:`preview_scene_data`) as a :class:`~atlasgen.materials.scene.Scene`."""
    return parse_scene(data, PREVIEW_SCENE)


def ball_mesh_file(mesh: Mesh, folder=None) -> Path:
    """A PLY of ``mesh`` in ``folder`` (the temporary folder by default), named by its content, written once.

    The scene names the file and its parser checks it exists; the renderer is handed the mesh
    itself (:meth:`~atlasgen.render.renderer.Renderer.add_mesh`), so the file is read only by
    whoever renders the scene elsewhere. The name changes with the mesh, so a stale file is
    never taken for the current one. A file of that name whose bytes are not the mesh's (truncated, edited) is
    written again: ``preview --reference`` renders it with Mitsuba, and a damaged one failed every run after,
    blamed on a ``<scene>`` the user never wrote.
    """
    digest = hashlib.sha256(mesh.interleaved().tobytes() + mesh.indices.tobytes()).hexdigest()[:16]
    folder = Path(folder) if folder is not None else Path(tempfile.gettempdir()) / f"atlasgen-preview-{os.getuid()}"
    path = folder / f"material-ball-{digest}.ply"
    data = encode_mesh_ply(mesh)
    if not _holds(path, data):
        write_file_atomically(path, data)
    return path


def _holds(path: Path, data: bytes) -> bool:
    """Whether ``path`` is a regular file of exactly ``data``."""
    try:
        return path.is_file() and path.stat().st_size == len(data) and path.read_bytes() == data
    except OSError:
        return False
