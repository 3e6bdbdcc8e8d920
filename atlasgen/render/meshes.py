"""Triangle meshes: the built-in shapes and OBJ/PLY files (read by trimesh).

All meshes are in object space with counter-clockwise front faces and per-vertex
normals. Normals that are zero or not finite are kept as zeros: the g-buffer shader
replaces them by the face normal, so degenerate input never produces NaN pixels.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from atlasgen.errors import SceneError
from atlasgen.io.fields import FLOAT32_MAX

__all__ = [
    "Mesh",
    "make_sphere",
    "make_plane",
    "make_box",
    "make_torus",
    "read_mesh",
    "build_mesh",
    "sanitize_normals",
    "VERTEX_ATTRIBUTES",
    "vertex_buffer_layout",
]

#: The vertex buffer, declared once: (attribute, float32 components), interleaved in this order at
#: shader locations 0, 1, ... :meth:`Mesh.interleaved` packs it and :func:`vertex_buffer_layout`
#: describes it to the pipeline (gbuffer.wgsl's ``vs_main`` takes the same locations).
VERTEX_ATTRIBUTES = (("positions", 3), ("normals", 3))


def vertex_buffer_layout() -> dict:
    """The wgpu vertex buffer layout of :data:`VERTEX_ATTRIBUTES`: stride, offsets and formats from it."""
    attributes, offset = [], 0
    for location, (_, components) in enumerate(VERTEX_ATTRIBUTES):
        attributes.append({"format": f"float32x{components}", "offset": offset, "shader_location": location})
        offset += 4 * components
    return {"array_stride": offset, "step_mode": "vertex", "attributes": attributes}


@dataclass
class Mesh:
    """``positions`` and ``normals`` are ``(n, 3)`` float32, ``indices`` ``(m, 3)`` uint32."""

    positions: np.ndarray
    normals: np.ndarray
    indices: np.ndarray

    def interleaved(self) -> np.ndarray:
        """``(n, 6)`` float32 rows in :data:`VERTEX_ATTRIBUTES`' order: the vertex buffer."""
        columns = [np.asarray(getattr(self, name)).reshape(-1, components) for name, components in VERTEX_ATTRIBUTES]
        return np.ascontiguousarray(np.concatenate(columns, axis=1), dtype=np.float32)


def sanitize_normals(normals: np.ndarray) -> np.ndarray:
    """Unit normals; rows that are zero or non-finite become exact zeros."""
    n = np.asarray(normals, dtype=np.float64)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    ok = np.isfinite(length) & (length > 1e-12)
    out = np.where(ok, n / np.where(ok, length, 1.0), 0.0)
    return out.astype(np.float32)


def _mesh(positions, normals, indices) -> Mesh:
    return Mesh(
        np.ascontiguousarray(positions, dtype=np.float32),
        sanitize_normals(normals),
        np.ascontiguousarray(indices, dtype=np.uint32).reshape(-1, 3),
    )


def _grid_indices(rows: int, cols: int, wrap_cols: bool) -> np.ndarray:
    """Two triangles per cell of a (rows+1) x (cols[+1]) vertex grid, CCW seen from outside."""
    stride = cols if wrap_cols else cols + 1
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a = r * stride + c
    b = r * stride + (c + 1) % stride if wrap_cols else a + 1
    d = a + stride
    e = b + stride
    return np.stack([np.stack([a, d, b], -1), np.stack([b, d, e], -1)], 2).reshape(-1, 3)


def make_sphere(segments: int = 64) -> Mesh:
    """Unit sphere as a UV grid: ``segments`` around, ``segments // 2`` from pole to pole."""
    rings = max(2, segments // 2)
    theta = np.linspace(0.0, np.pi, rings + 1)  # from +y down
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    pos = np.stack([np.sin(t) * np.sin(p), np.cos(t), np.sin(t) * np.cos(p)], -1).reshape(-1, 3)
    return _mesh(pos, pos, _grid_indices(rings, segments, wrap_cols=False))


def make_plane() -> Mesh:
    """The square [-1, 1]^2 in the xz plane, facing +y."""
    pos = np.array([[-1, 0, -1], [-1, 0, 1], [1, 0, -1], [1, 0, 1]], dtype=np.float64)
    nrm = np.tile([0.0, 1.0, 0.0], (4, 1))
    return _mesh(pos, nrm, [[0, 1, 2], [2, 1, 3]])


def make_box() -> Mesh:
    """The cube [-1, 1]^3 with flat faces (4 vertices per face)."""
    positions, normals, indices = [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u = np.zeros(3)
            u[(axis + 1) % 3] = 1.0
            v = np.cross(n, u)
            base = len(positions)
            for a, b in ((-1, -1), (1, -1), (-1, 1), (1, 1)):
                positions.append(n + a * u + b * v)
                normals.append(n)
            indices += [[base, base + 1, base + 2], [base + 2, base + 1, base + 3]]
    return _mesh(positions, normals, indices)


def make_torus(minor_radius: float = 0.25, segments: int = 64) -> Mesh:
    """Torus about the y axis with major radius 1 and the given minor radius."""
    minor_segments = max(3, segments // 2)
    u = np.linspace(0.0, 2.0 * np.pi, segments + 1)  # around y
    v = np.linspace(0.0, 2.0 * np.pi, minor_segments + 1)  # around the tube
    uu, vv = np.meshgrid(u, v, indexing="ij")
    centre = np.stack([np.sin(uu), np.zeros_like(uu), np.cos(uu)], -1)
    normal = np.stack([np.cos(vv) * np.sin(uu), np.sin(vv), np.cos(vv) * np.cos(uu)], -1)
    pos = centre + minor_radius * normal
    idx = _grid_indices(segments, minor_segments, wrap_cols=False)
    return _mesh(pos.reshape(-1, 3), normal.reshape(-1, 3), idx)


def read_mesh(path, scene_path="<scene>", field="file") -> Mesh:
    """Read an OBJ or PLY file with trimesh; vertex normals from the file, else area-weighted.

    Raises :class:`SceneError` (naming ``scene_path`` and ``field``) when the file is
    missing, unreadable, has no triangles, has a vertex that is not finite in float32 (the
    vertex buffer's type) or a face that names a vertex it does not have.
    """
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise SceneError(scene_path, field, f"no such mesh file {path.as_posix()!r}; expected an OBJ or PLY file")
    try:
        loaded = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for malformed files
        raise SceneError(scene_path, field, f"cannot read mesh {path.as_posix()!r} ({type(exc).__name__}: {exc})") from None
    faces = np.asarray(getattr(loaded, "faces", np.empty((0, 3))))
    if faces.size == 0:
        raise SceneError(scene_path, field, f"mesh {path.as_posix()!r} has no triangles; expected a triangle mesh")
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.min() < 0 or faces.max() >= len(vertices):
        raise SceneError(scene_path, field, f"mesh {path.as_posix()!r} has faces that are not triangles of its vertices")
    with np.errstate(invalid="ignore"):
        bad = ~(np.abs(vertices) <= FLOAT32_MAX)  # NaN compares False
    if bad.any():
        row = int(np.argwhere(bad)[0][0])
        raise SceneError(scene_path, field, f"mesh {path.as_posix()!r}: vertex {row + 1} is {vertices[row].tolist()}; "
                                            "expected finite float32 coordinates")  # fmt: skip
    # trimesh computes area-weighted vertex normals when the file has none; zero-area
    # faces contribute nothing, and a vertex used only by them gets a zero normal.
    with np.errstate(invalid="ignore", divide="ignore"):
        normals = np.asarray(loaded.vertex_normals, dtype=np.float64)
    return _mesh(vertices, normals, faces)


def build_mesh(obj, scene_path="<scene>") -> Mesh:
    """The object-space mesh of a :class:`~atlasgen.materials.scene.SceneObject`;
    ``scene_path`` is the scene file that errors name."""
    if obj.shape == "sphere":
        return make_sphere(obj.segments)
    if obj.shape == "plane":
        return make_plane()
    if obj.shape == "box":
        return make_box()
    if obj.shape == "torus":
        return make_torus(obj.minor_radius, obj.segments)
    return read_mesh(obj.file, scene_path, field=f"objects[{obj.index}].file")
