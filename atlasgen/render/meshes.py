"""Triangle meshes: the built-in shapes, the preview's material ball and OBJ/PLY files (read by trimesh).

All meshes are in object space with counter-clockwise front faces and per-vertex
normals. Normals that are zero or not finite are kept as zeros: the g-buffer shader
replaces them by the face normal, so degenerate input never produces NaN pixels.
"""

from __future__ import annotations

import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from atlasgen.errors import SceneError, describe_failure, shorten
from atlasgen.interrupts import deferred_interrupts
from atlasgen.io.fields import FLOAT32_MAX
from atlasgen.io.text import MISSING, path_kind

__all__ = [
    "Mesh",
    "make_sphere",
    "make_plane",
    "make_box",
    "make_torus",
    "ProfileArc",
    "ProfileLine",
    "MATERIAL_BALL_PROFILE",
    "revolve_profile",
    "make_material_ball",
    "encode_mesh_ply",
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
    """``positions`` and ``normals`` are ``(n, 3)`` float32, ``indices`` ``(m, 3)`` uint32. ``closed``: a
    watertight surface wound counter-clockwise seen from outside, whose back faces the g-buffer
    pass may cull (from outside, a closed surface's back faces always lie behind its front ones)."""

    positions: np.ndarray
    normals: np.ndarray
    indices: np.ndarray
    closed: bool = False

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


def _mesh(positions, normals, indices, closed: bool = False) -> Mesh:
    return Mesh(
        np.ascontiguousarray(positions, dtype=np.float32),
        sanitize_normals(normals),
        np.ascontiguousarray(indices, dtype=np.uint32).reshape(-1, 3),
        closed,
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
    return _mesh(pos, pos, _grid_indices(rings, segments, wrap_cols=False), closed=True)


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
    return _mesh(positions, normals, indices, closed=True)


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
    return _mesh(pos.reshape(-1, 3), normal.reshape(-1, 3), idx, closed=True)


@dataclass(frozen=True)
class ProfileArc:
    """A circular arc of a profile in the (r, y) half-plane (r the distance from the y axis).

    Angles are in radians from +r towards +y. The arc runs from ``start`` to ``end``, and the
    solid lies on its left: counter-clockwise (``end > start``) it bulges out and its normal is
    the radius; clockwise it is hollow (a groove, a bowl) and its normal points to the centre.
    """

    name: str
    centre: tuple[float, float]
    radius: float
    start: float
    end: float

    @property
    def length(self) -> float:
        return self.radius * abs(self.end - self.start)

    def sample(self, count: int) -> tuple[np.ndarray, np.ndarray]:
        """``count`` points from start to end and their unit outward normals, each ``(count, 2)``."""
        a = np.linspace(self.start, self.end, count)
        radial = np.stack([np.cos(a), np.sin(a)], -1)
        return np.asarray(self.centre) + self.radius * radial, radial * math.copysign(1.0, self.end - self.start)


@dataclass(frozen=True)
class ProfileLine:
    """A straight piece of a profile from ``start`` to ``end`` ((r, y) points), the solid on its left."""

    name: str
    start: tuple[float, float]
    end: tuple[float, float]

    @property
    def length(self) -> float:
        return math.dist(self.start, self.end)

    def sample(self, count: int) -> tuple[np.ndarray, np.ndarray]:
        """``count`` points from start to end and the unit outward normal (dy, -dr) / length at each."""
        t = np.linspace(0.0, 1.0, count)[:, None]
        p0, p1 = np.asarray(self.start), np.asarray(self.end)
        (dr, dy) = (p1 - p0) / self.length
        return p0 + t * (p1 - p0), np.tile([dy, -dr], (count, 1))


def _material_ball_profile() -> tuple:
    """The ball's profile, bottom pole to the bottom of its top cavity: a unit sphere with a groove
    round its equator, cut flat at 52 degrees of latitude (the sharp rim), and a bowl sunk into the top.

    Each circle is fixed by the points it passes through: the groove's centre (c, 0) by the sphere
    at +-9 degrees and its depth r = 0.9, (c - 0.9)^2 = (cos 9 - c)^2 + sin^2 9; the bowl's
    centre (0, y_c) by the top's inner edge (0.36, y_top) and its depth y_b = y_top - 0.2,
    y_c = (0.36^2 + y_top^2 - y_b^2) / (2 (y_top - y_b)).
    """
    groove, depth = math.radians(9.0), 0.9
    gr, gy = math.cos(groove), math.sin(groove)
    c = (gr**2 + gy**2 - depth**2) / (2.0 * (gr - depth))
    rim = math.radians(52.0)
    top_r, top_y = math.cos(rim), math.sin(rim)
    inner, bottom = 0.36, math.sin(rim) - 0.2
    yc = (inner**2 + top_y**2 - bottom**2) / (2.0 * (top_y - bottom))
    bowl_rim = math.atan2(top_y - yc, inner)
    return (
        ProfileArc("lower body", (0.0, 0.0), 1.0, -math.pi / 2, -groove),
        # Clockwise about a centre outside the sphere: a hollow ring.
        ProfileArc("groove", (c, 0.0), c - depth, math.atan2(-gy, gr - c) + 2 * math.pi, math.atan2(gy, gr - c)),
        ProfileArc("upper body", (0.0, 0.0), 1.0, groove, rim),
        ProfileLine("top", (top_r, top_y), (inner, top_y)),
        ProfileArc("cavity", (0.0, yc), yc - bottom, bowl_rim, -math.pi / 2),
    )


#: The material ball's profile (:func:`make_material_ball`): pieces meeting at creases (the groove's
#: two edges, the rim between the upper body and the flat top, the cavity's edge).
MATERIAL_BALL_PROFILE = _material_ball_profile()


def revolve_profile(pieces, segments: int = 96) -> Mesh:
    """The closed surface swept by a profile about the y axis: ``x = r sin(phi)``, ``z = r cos(phi)``.

    ``pieces`` (:class:`ProfileArc`, :class:`ProfileLine`) run end to start, from a point on the
    axis to a point on the axis, the solid on their left. Each piece has its own rings of
    vertices, spaced about as far apart as the ``segments`` around, with its own normals: the
    surface is smooth within a piece, and where two pieces meet their rings share positions but
    not normals, so the crease stays sharp. Points on the axis are one vertex each (a pole).
    """
    step = 2.0 * math.pi / segments
    phi = step * np.arange(segments)
    sin, cos = np.sin(phi), np.cos(phi)
    positions, normals, faces = [], [], []
    count = 0
    for piece in pieces:
        points, piece_normals = piece.sample(max(2, math.ceil(piece.length / step) + 1))
        rings = []
        for (r, y), (nr, ny) in zip(points, piece_normals):
            if r < 1e-9:  # a pole: one vertex, its normal along the axis
                positions.append([[0.0, y, 0.0]])
                normals.append([[0.0, math.copysign(1.0, ny), 0.0]])
                rings.append(np.full(segments, count))
                count += 1
            else:
                positions.append(np.stack([r * sin, np.full(segments, y), r * cos], -1))
                normals.append(np.stack([nr * sin, np.full(segments, ny), nr * cos], -1))
                rings.append(count + np.arange(segments))
                count += segments
        for below, above in zip(rings, rings[1:]):
            # Counter-clockwise seen from outside: d(phi) x d(profile) is the outward normal.
            a, b = below, np.roll(below, -1)
            c, d = above, np.roll(above, -1)
            quads = np.concatenate([np.stack([a, b, c], -1), np.stack([b, d, c], -1)])
            keep = (quads[:, 0] != quads[:, 1]) & (quads[:, 1] != quads[:, 2]) & (quads[:, 0] != quads[:, 2])
            faces.append(quads[keep])
    return _mesh(np.concatenate(positions), np.concatenate(normals), np.concatenate(faces))


def make_material_ball(segments: int = 96) -> Mesh:
    """The preview's material ball (:data:`MATERIAL_BALL_PROFILE` revolved): in [-1, 1]^3 like the
    unit sphere, resting on y = -1, with a groove (a cavity ring) round it, a sharp rim and a cavity on top."""
    return revolve_profile(MATERIAL_BALL_PROFILE, segments)


def import_trimesh():
    """trimesh, imported with Ctrl-C and SIGTERM held (:func:`~atlasgen.interrupts.deferred_interrupts`): its modules
    import their optional dependencies under ``except BaseException``, so an interrupt landing while it loads was
    swallowed, and the command ran on to exit 0 (or failed later on trimesh's placeholder for what it missed)."""
    with deferred_interrupts():
        import trimesh
    return trimesh


def encode_mesh_ply(mesh: Mesh) -> bytes:
    """A binary PLY of ``mesh`` with its vertex normals, written by trimesh (for ``shape = "mesh"`` scenes)."""
    trimesh = import_trimesh()

    shape = trimesh.Trimesh(vertices=mesh.positions, faces=mesh.indices, vertex_normals=mesh.normals, process=False)
    return shape.export(file_type="ply", encoding="binary", vertex_normal=True)


#: Most triangles a mesh file may have: 8M draw in seconds on a software GPU; the 16M of a 300 MB PLY took
#: 4 GB of memory in the buffers built from them.
MAX_MESH_TRIANGLES = 8_000_000
#: Most triangles a scene's meshes may hold in all, each distinct mesh counted once: a 13 kB scene of 100 tori of
#: 1024 segments, each radius its own mesh, took 5 GB of memory.
MAX_SCENE_TRIANGLES = 16_000_000
#: A vertex (or texture or normal) index 0 on an OBJ face line, however written (00, -0, +0), before any
#: comment: OBJ counts from 1, and trimesh reads 0 as another vertex, silently.
_OBJ_ZERO_INDEX = re.compile(r"(?m)^[ \t]*f[ \t][^\n#]*?(?<=[ \t/])[+-]?0+(?=[/ \t\r#]|$)")


def _obj_text(path: Path, scene_path, field) -> str:
    """An OBJ file's text without its comments (:data:`_OBJ_COMMENT`), refused where a face names index 0.

    OBJ is text, and bytes outside UTF-8 (a Latin-1 comment) send trimesh to a charset detector it does
    not depend on: decoded here, what UTF-8 cannot say kept as U+FFFD (comments and names only)."""
    try:
        # utf-8-sig: a byte-order mark read as part of the first line dropped that line (its first vertex) silently.
        text = path.read_bytes().decode("utf-8-sig", errors="replace")
    except OSError as exc:
        raise SceneError(scene_path, field, f"cannot read mesh {path.as_posix()!r} ({exc.strerror})") from None
    # A tab is OBJ whitespace as a space is, but trimesh drops a 'v' or 'f' line whose keyword a tab follows, silently:
    # the vertices after it shifted by one, or the face vanished.
    text = _OBJ_COMMENT.sub("", text).replace("\t", " ")
    zero = _OBJ_ZERO_INDEX.search(text)
    if zero is not None:
        line = text.count("\n", 0, zero.start()) + 1
        raise SceneError(scene_path, field, f"mesh {path.as_posix()!r} line {line}: a face names index 0; expected "
                                            "indices from 1 (OBJ counts from 1, or back from -1)")  # fmt: skip
    _refuse_missing_normals(text, path, scene_path, field)
    return text


#: A face corner that names a normal (i//n or i/t/n): its normal index, the third number. Only face lines have such
#: words (vertex, texture and normal lines hold plain numbers), so the whole text is searched at once.
_OBJ_NORMAL_INDEX = re.compile(r"(?<![^ \t])[+-]?\d+/[+-]?\d*/([+-]?\d+)")
_OBJ_NORMAL_LINE = re.compile(r"(?m)^[ \t]*vn[ \t]")


def _refuse_missing_normals(text: str, path: Path, scene_path, field) -> None:
    """Refuse a face corner naming a normal the file does not have (``f 1//5`` with one ``vn``): trimesh dropped
    every normal of the file then, without a word, and the mesh was shaded with area-weighted ones. A negative
    index counts back from the last normal; it is checked against all of them, not those before its line."""
    indices = set(_OBJ_NORMAL_INDEX.findall(text))  # each distinct index once: corners repeat them
    if not indices:
        return
    have = len(_OBJ_NORMAL_LINE.findall(text))
    worst = max(indices, key=lambda i: abs(float(i)))  # float: an index beyond int64 stays a number
    if abs(float(worst)) > have:
        raise SceneError(scene_path, field, f"mesh {path.as_posix()!r}: a face names normal {shorten(worst)} of the {have} it has; "
                                            "expected normal indices within its vn lines")  # fmt: skip


#: Bytes of a PLY property's scalar type (the PLY format's names and their sized aliases).
_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
              "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}  # fmt: skip
#: Bytes a PLY header may take before ``end_header``: a header is a few hundred.
_PLY_HEADER_BYTES = 64 << 10


#: PLY's floating-point types, by their names in the header (PLY 1.0 and the sized forms).
_PLY_REALS = ("float", "double", "float32", "float64")


def _ply_header(path: Path) -> tuple[bytes, int, list[list[str]]] | None:
    """A PLY file's first :data:`_PLY_HEADER_BYTES`, where ``end_header`` starts in them (-1: not there) and the
    header's lines split into words (none without an ``end_header``); None where the file cannot be read."""
    try:
        with open(path, "rb") as f:
            head = f.read(_PLY_HEADER_BYTES)
    except OSError:
        return None
    end = head.find(b"end_header")
    lines = head[:end].decode("ascii", errors="replace").split("\n") if end >= 0 else []
    return head, end, [line.split() for line in lines]


def _ply_elements(path: Path, header=None):
    """A PLY file's layout as its header (:func:`_ply_header`, read here unless given) declares it: ``(ascii,
    elements, declared, have)``, elements as ``[name, count, least bytes of one]``, ``declared`` them in words and
    ``have`` the bytes after the header; None where the file cannot be read or its header parsed (left to trimesh's
    own message)."""
    header = _ply_header(path) if header is None else header
    try:
        size = path.stat().st_size
    except OSError:
        return None
    if header is None:
        return None
    head, end, words = header
    fmt = next((w[1] for w in words if len(w) >= 2 and w[0] == "format"), None)
    if not words or words[0] != ["ply"] or fmt is None:
        return None
    text = fmt == "ascii"
    elements = []  # (name, count, least bytes of one element)
    for w in words:
        if len(w) == 3 and w[0] == "element" and w[2].isdigit():
            elements.append([w[1], int(w[2]), 0])
        elif elements and len(w) >= 3 and w[0] == "property":
            # A list takes at least its count (an empty list); an ASCII value at least a digit and a separator.
            elements[-1][2] += 2 if text else _PLY_SIZES.get(w[2] if w[1] == "list" else w[1], 1)
    have = size - head.index(b"\n", end) - 1 if b"\n" in head[end:] else 0
    declared = ", ".join(f"element {name} {count}" for name, count, _ in elements)
    return text, elements, declared, have


def _check_ply_counts(path: Path, scene_path, field) -> None:
    """Refuse a PLY whose header declares more elements than its body can hold, more faces than a mesh may
    have, or face indices that are not integers: trimesh read an ASCII file declaring 2e9 vertices as one
    without triangles, and a binary one as "unexpected length", and truncated a float index (0.5 as vertex 0).
    A header it cannot parse is left to trimesh's own message."""
    header = _ply_header(path)
    for w in header[2] if header is not None else ():
        if len(w) == 5 and w[:2] == ["property", "list"] and w[4] in ("vertex_indices", "vertex_index") and w[3] in _PLY_REALS:
            raise SceneError(scene_path, field, f"mesh {path.as_posix()!r}: its faces' {w[4]} are of type {w[3]}; "
                                                "expected an integer type (a vertex index is a whole number)")  # fmt: skip
    layout = _ply_elements(path, header)
    if layout is None:
        return
    text, elements, declared, have = layout
    faces = sum(count for name, count, _ in elements if name == "face")
    if faces > MAX_MESH_TRIANGLES:
        raise SceneError(scene_path, field, f"mesh {path.as_posix()!r} declares {faces} faces; expected at most "
                                            f"{MAX_MESH_TRIANGLES} triangles")  # fmt: skip
    need = sum(count * least for _, count, least in elements) - text  # the last value needs no separator
    if need > have:
        raise SceneError(scene_path, field, f"mesh {path.as_posix()!r}: its header declares {declared}, at least "
                                            f"{need} bytes, and {have} follow it; expected the counts of the "
                                            "elements the file holds")  # fmt: skip
    if text:
        # An ASCII element is a line: one vertex line too many was read as a face ("has no triangles"), and lines
        # after the last element were dropped without a word.
        try:
            body = path.read_bytes()[-have:] if have else b""
        except OSError:
            return
        lines = sum(1 for line in body.splitlines() if line.strip())
        total = sum(count for _, count, _ in elements)
        if lines != total:
            raise SceneError(scene_path, field, f"mesh {path.as_posix()!r}: {lines} lines follow its header, which "
                                                f"declares {declared}; expected one line per element, {total}")  # fmt: skip


#: A number as an OBJ vertex line writes it (what Python's float() reads; nan and inf are refused later).
_OBJ_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|[+-]?(?:nan|inf(?:inity)?)", re.IGNORECASE)
#: How many numbers an OBJ vertex line may hold: x y z, an optional w, or colours r g b after x y z (and w).
_OBJ_VERTEX_COUNTS = (3, 4, 6, 7)
#: One corner of an OBJ face: a vertex index, then optionally a texture and a normal index (v, v/t, v//n, v/t/n).
_OBJ_CORNER = re.compile(r"[+-]?\d+(?:/[+-]?\d*)?(?:/[+-]?\d+)?")
#: A comment: from ``#`` to the end of its line. The OBJ format has comment lines; files put them after values too,
#: and trimesh's reader failed on such a vertex line ("could not be read to its end due to unmatched data").
_OBJ_COMMENT = re.compile(r"[ \t]*#[^\n]*")


def _explain_obj(text: str) -> str | None:
    """Which vertex or face line of an OBJ file trimesh could not read: its NumPy parser said only "string or file
    could not be read to its end due to unmatched data". Run only after trimesh failed (a loop over the lines)."""
    for number, line in enumerate(text.splitlines(), 1):
        words = line.split()
        if words[:1] == ["v"] and (len(words) - 1 not in _OBJ_VERTEX_COUNTS
                                   or not all(_OBJ_NUMBER.fullmatch(w) for w in words[1:])):  # fmt: skip
            return f"line {number} is {shorten(repr(line.strip()))}; expected a vertex as 'v x y z', three numbers"
        if words[:1] == ["f"] and (len(words) < 4 or not all(_OBJ_CORNER.fullmatch(w) for w in words[1:])):
            return (f"line {number} is {shorten(repr(line.strip()))}; expected a face as 'f i j k', three or more "
                    "vertex indices (each i, i/t, i//n or i/t/n)")  # fmt: skip
    return None


def _explain_ply(path: Path) -> str | None:
    """Why trimesh could not read a PLY file, where its header says: a vertex element without x, y and z
    (trimesh raised ``KeyError: 'z'``)."""
    header = _ply_header(path)
    if header is None:
        return None
    element, props = None, {}
    for w in header[2]:
        if len(w) >= 2 and w[0] == "element":
            element = w[1]
            props.setdefault(element, [])
        elif element is not None and len(w) >= 3 and w[0] == "property":
            props[element].append(w[-1])
    if "vertex" not in props:
        return "its header declares no vertex element; expected 'element vertex N' with properties x, y and z"
    lacking = [axis for axis in ("x", "y", "z") if axis not in props["vertex"]]
    if lacking:
        return f"its vertices have no property {', '.join(lacking)}; expected properties x, y and z"
    layout = _ply_elements(path, header)
    if layout is not None and not layout[0]:
        # Too few bytes are refused before trimesh reads (_check_ply_counts); what it then cannot read is a body of
        # another length, which it called "PLY is unexpected length!" (bytes after the last element, say).
        _, _, declared, have = layout
        return (
            f"the {have} bytes after its header are not the elements it declares ({declared}); expected those "
            "elements and nothing after them"
        )
    return None


def read_mesh(path, scene_path="<scene>", field="file") -> Mesh:
    """Read an OBJ or PLY file with trimesh; vertex normals from the file, else area-weighted.

    Raises :class:`SceneError` (naming ``scene_path`` and ``field``) when the file is
    missing, unreadable, has no triangles, has a vertex that is not finite in float32 (the
    vertex buffer's type) or a face that names a vertex it does not have.
    """
    trimesh = import_trimesh()

    path = Path(path)
    kind = path_kind(path)
    if kind == MISSING:
        raise SceneError(scene_path, field, f"no such mesh file {path.as_posix()!r}; expected an OBJ or PLY file")
    if kind is not None:
        raise SceneError(scene_path, field, f"expected an OBJ or PLY file, got {kind} ({path.as_posix()!r})")
    text = _obj_text(path, scene_path, field) if path.suffix.lower() == ".obj" else None
    if text is None:
        _check_ply_counts(path, scene_path, field)
    try:
        if text is not None:
            loaded = trimesh.load(io.StringIO(text), file_type="obj", process=False)
        else:
            loaded = trimesh.load(str(path), process=False)
        # Several meshes come as a scene, joined here as force="mesh" joins them; a lone mesh is taken as read, since
        # that conversion dropped the file's vertex normals (every mesh was shaded with area-weighted ones).
        if isinstance(loaded, trimesh.Scene):
            loaded = loaded.to_mesh()
    except IndexError:  # trimesh's OBJ reader indexing a vertex past the end
        raise SceneError(scene_path, field, f"mesh {path.as_posix()!r} has a face naming a vertex it does not have; "
                                            "expected face indices within its vertices") from None  # fmt: skip
    except Exception as exc:  # trimesh raises many types for malformed files
        reason = _explain_obj(text) if text is not None else _explain_ply(path)
        if reason is not None:
            raise SceneError(scene_path, field, f"mesh {path.as_posix()!r}: {reason}") from None
        raise SceneError(scene_path, field, f"cannot read mesh {path.as_posix()!r}; expected an OBJ or PLY file "
                                            f"({describe_failure(exc)})") from None  # fmt: skip
    faces = np.asarray(getattr(loaded, "faces", np.empty((0, 3))))
    if faces.size == 0:
        raise SceneError(scene_path, field, f"mesh {path.as_posix()!r} has no triangles; expected a triangle mesh")
    if len(faces) > MAX_MESH_TRIANGLES:
        raise SceneError(scene_path, field, f"mesh {path.as_posix()!r} has {len(faces)} triangles; expected at most "
                                            f"{MAX_MESH_TRIANGLES}")  # fmt: skip
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise SceneError(scene_path, field, f"mesh {path.as_posix()!r} has vertices that are not points; "
                                            "expected x y z on every vertex line")  # fmt: skip
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.min() < 0 or faces.max() >= len(vertices):
        raise SceneError(scene_path, field, f"mesh {path.as_posix()!r} has faces that are not triangles of its vertices; "
                                            f"expected three vertex indices from 0 to {len(vertices) - 1} on each face")  # fmt: skip
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
    if normals.shape != vertices.shape:  # trimesh keeps a vertex line of two numbers out of the normals it reads
        raise SceneError(scene_path, field, f"mesh {path.as_posix()!r} has {len(vertices)} vertices but {len(normals)} "
                                            "normals; expected x y z on every vertex line")  # fmt: skip
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
