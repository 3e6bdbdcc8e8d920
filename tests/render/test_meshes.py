"""Built-in shapes and mesh files: geometry, winding, normals, degenerate input."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.errors import SceneError
from atlasgen.render.meshes import make_box, make_plane, make_sphere, make_torus, read_mesh, sanitize_normals


def face_normals(mesh):
    p = mesh.positions[mesh.indices].astype(np.float64)
    return np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])


def enclosed_volume(mesh):
    # Divergence theorem: sum of signed tetrahedra volumes; positive for CCW-outward meshes.
    p = mesh.positions[mesh.indices].astype(np.float64)
    return np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0


@pytest.mark.parametrize(
    "mesh, volume, tol",
    [
        (make_sphere(128), 4 / 3 * np.pi, 2e-3),
        (make_box(), 8.0, 1e-6),
        (make_torus(0.25, 128), 2 * np.pi**2 * 0.25**2, 3e-3),
    ],  # fmt: skip
)
def test_closed_shapes_are_outward_ccw_with_the_right_volume(mesh, volume, tol):
    assert enclosed_volume(mesh) == pytest.approx(volume, rel=tol)
    fn = face_normals(mesh)
    ok = np.linalg.norm(fn, axis=1) > 1e-9
    vn = mesh.normals[mesh.indices].mean(axis=1)
    assert (np.einsum("ij,ij->i", fn[ok], vn[ok]) > 0).all()
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-6)


def test_sphere_normals_are_radial():
    mesh = make_sphere(32)
    np.testing.assert_allclose(np.linalg.norm(mesh.positions, axis=1), 1.0, atol=1e-6)
    np.testing.assert_allclose(mesh.normals, mesh.positions, atol=1e-6)


def test_plane_faces_up():
    mesh = make_plane()
    assert (face_normals(mesh)[:, 1] > 0).all()
    assert np.ptp(mesh.positions[:, 0]) == 2 and np.ptp(mesh.positions[:, 2]) == 2


def test_sanitize_normals_zeroes_degenerate_rows():
    out = sanitize_normals(np.array([[0, 0, 2], [0, 0, 0], [np.nan, 1, 0], [1e-30, 0, 0]]))
    np.testing.assert_array_equal(out, [[0, 0, 1], [0, 0, 0], [0, 0, 0], [0, 0, 0]])


@pytest.mark.slow
def test_read_obj_with_zero_normals(tmp_path):
    path = tmp_path / "tri.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 2 2\nvn 0 0 0\nf 1//1 2//1 3//1\nf 4//1 4//1 4//1\n")
    mesh = read_mesh(path)
    assert mesh.indices.shape[1] == 3 and mesh.indices.max() < len(mesh.positions)
    assert np.isfinite(mesh.normals).all()


def test_read_ply(tmp_path):
    import trimesh

    path = tmp_path / "box.ply"
    trimesh.creation.box().export(path)
    mesh = read_mesh(path)
    assert enclosed_volume(mesh) == pytest.approx(1.0)


@pytest.mark.parametrize("name", ["tri.obj", "tri.ply", "two-objects.obj"])
def test_the_file_s_vertex_normals_are_the_mesh_s(tmp_path, name):
    """trimesh's force="mesh" dropped them: every mesh was shaded with area-weighted normals, smooth normals lost
    (here (1, 0, 0) on a triangle whose face normal is (0, 0, 1))."""
    texts = {
        "tri.obj": "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nvn 1 0 0\nf 1//1 2//1 3//1\n",
        "two-objects.obj": "o a\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nvn 1 0 0\nf 1//1 2//1 3//1\n"
                           "o b\nv -1 -1 1\nv 1 -1 1\nv 0 1 1\nvn 1 0 0\nf 4//2 5//2 6//2\n",
        "tri.ply": "ply\nformat ascii 1.0\nelement vertex 3\n" + "".join(f"property float {p}\n" for p in "x y z nx ny nz".split())
                   + "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                   "-1 -1 0 1 0 0\n1 -1 0 1 0 0\n0 1 0 1 0 0\n3 0 1 2\n",
    }  # fmt: skip
    path = tmp_path / name
    path.write_text(texts[name])
    mesh = read_mesh(path)
    assert (face_normals(mesh)[:, 2] > 0).all()
    np.testing.assert_array_equal(mesh.normals, np.tile([1.0, 0.0, 0.0], (len(mesh.positions), 1)))


def test_bad_mesh_files(tmp_path):
    with pytest.raises(SceneError, match="no such mesh file"):
        read_mesh(tmp_path / "missing.obj", "s.toml", "objects[1].file")
    empty = tmp_path / "empty.obj"
    empty.write_text("# nothing\n")
    with pytest.raises(SceneError, match="objects\\[1\\].file"):
        read_mesh(empty, "s.toml", "objects[1].file")


def test_the_vertex_buffer_layout_describes_the_interleaved_bytes():
    """Stride and offsets come from the one declaration the packing uses: attribute k of vertex i sits at
    i * stride + offset_k bytes."""
    from atlasgen.render.meshes import VERTEX_ATTRIBUTES, vertex_buffer_layout

    mesh = make_box()
    data = mesh.interleaved()
    layout = vertex_buffer_layout()
    raw = data.tobytes()
    assert layout["array_stride"] * len(mesh.positions) == len(raw)
    for (name, components), attribute in zip(VERTEX_ATTRIBUTES, layout["attributes"]):
        assert attribute["format"] == f"float32x{components}"
        for i in (0, len(mesh.positions) - 1):
            start = i * layout["array_stride"] + attribute["offset"]
            got = np.frombuffer(raw[start : start + 4 * components], np.float32)
            np.testing.assert_array_equal(got, getattr(mesh, name)[i])
    assert [a["shader_location"] for a in layout["attributes"]] == [0, 1]


# ---- the material ball -------------------------------------------------------------------------


def welded(mesh, decimals=6):
    """Faces over vertices merged by position: the surface's topology, whatever its normals."""
    _, index = np.unique(np.round(mesh.positions.astype(np.float64), decimals), axis=0, return_inverse=True)
    return index.ravel()[mesh.indices]


def winding_numbers(mesh, points):
    """How many times the closed mesh winds round each point: 1 inside, 0 outside (van Oosterom & Strackee's
    solid angle of each triangle, tan(omega / 2) = a.(b x c) / (|a||b||c| + (a.b)|c| + (a.c)|b| + (b.c)|a|))."""
    tri = mesh.positions[mesh.indices].astype(np.float64)
    a, b, c = (tri[None, :, k] - points[:, None] for k in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
    dot = lambda x, y: np.einsum("...k,...k->...", x, y)
    numerator = dot(a, np.cross(b, c))
    denominator = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la
    return 2.0 * np.arctan2(numerator, denominator).sum(axis=1) / (4.0 * np.pi)


def test_the_material_ball_is_closed_and_consistently_wound():
    from atlasgen.render.meshes import make_material_ball

    faces = welded(make_material_ball(48))
    assert (faces[:, 0] != faces[:, 1]).all() and (faces[:, 1] != faces[:, 2]).all() and (faces[:, 0] != faces[:, 2]).all()
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    # Every edge is shared by exactly two faces, which run along it in opposite directions.
    _, counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    assert (counts == 2).all()
    assert len(np.unique(directed, axis=0)) == len(directed)
    # A sphere's topology: V - E + F = 2.
    assert len(np.unique(faces)) - len(counts) + len(faces) == 2


def test_the_material_ball_has_unit_outward_normals():
    from atlasgen.render.meshes import make_material_ball

    mesh = make_material_ball(48)
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-6)
    assert enclosed_volume(mesh) > 0
    # Each face's winding agrees with its vertices' normals...
    fn = face_normals(mesh)
    assert (np.einsum("ijk,ik->ij", mesh.normals[mesh.indices], fn) > 0).all()
    # ... and a step along a normal leaves the solid, a step against it enters it.
    rng = np.random.default_rng(7)
    pick = rng.choice(len(mesh.positions), 80, replace=False)
    p, n = mesh.positions[pick].astype(np.float64), mesh.normals[pick].astype(np.float64)
    np.testing.assert_allclose(winding_numbers(mesh, p + 0.01 * n), 0.0, atol=1e-6)
    np.testing.assert_allclose(winding_numbers(mesh, p - 0.01 * n), 1.0, atol=1e-6)


def test_the_material_balls_volume_is_its_profiles():
    """Pappus: the solid's volume is pi times the integral of r^2 dy round its profile, here summed
    exactly over a dense polyline of it (trapezoids in r^2), against the mesh's tetrahedra."""
    from atlasgen.render.meshes import MATERIAL_BALL_PROFILE, make_material_ball

    points = np.concatenate([piece.sample(4000)[0] for piece in MATERIAL_BALL_PROFILE])
    r2, y = points[:, 0] ** 2, points[:, 1]
    profile = np.pi * np.sum(0.5 * (r2[1:] + r2[:-1]) * np.diff(y))  # the axis, r = 0, adds nothing
    assert 3.0 < profile < 4 / 3 * np.pi  # a sphere less its groove and top
    assert enclosed_volume(make_material_ball(256)) == pytest.approx(profile, rel=2e-3)


def test_the_material_balls_normals_are_smooth_except_at_its_creases():
    from atlasgen.render.meshes import MATERIAL_BALL_PROFILE, make_material_ball

    segments = 64
    mesh = make_material_ball(segments)
    # The positions that carry more than one normal: the rings where two profile pieces meet.
    keys = np.round(mesh.positions.astype(np.float64), 6)
    unique, index = np.unique(keys, axis=0, return_inverse=True)
    index = index.ravel()
    normals_at = {}
    for i, n in zip(index, mesh.normals):
        normals_at.setdefault(i, []).append(n)
    split = {i: ns for i, ns in normals_at.items() if len(ns) > 1}
    assert len(split) == segments * (len(MATERIAL_BALL_PROFILE) - 1)
    # The rim: the upper body's last ring against the flat top's first, 90 - 52 degrees apart.
    rim_y = MATERIAL_BALL_PROFILE[3].start[1]
    rim = [ns for i, ns in split.items() if abs(unique[i, 1] - rim_y) < 1e-6 and np.hypot(unique[i, 0], unique[i, 2]) > 0.5]
    assert len(rim) == segments
    for a, b in rim:
        assert np.degrees(np.arccos(np.clip(np.dot(a, b), -1, 1))) == pytest.approx(38.0, abs=1e-3)
    # Everywhere else one normal per position (smooth shading), and it is the mean of the faces round
    # it to within 3 degrees, where the groove's rings are 31 degrees apart.
    fn = face_normals(mesh)
    accumulated = np.zeros((len(mesh.positions), 3))
    for k in range(3):
        np.add.at(accumulated, mesh.indices[:, k], fn)
    accumulated /= np.linalg.norm(accumulated, axis=1, keepdims=True)
    angle = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", accumulated, mesh.normals), -1, 1)))
    assert angle[~np.isin(index, list(split))].max() < 3.0


def test_the_material_balls_ply_holds_its_vertices_normals_and_faces(tmp_path):
    import trimesh

    from atlasgen.render.meshes import encode_mesh_ply, make_material_ball

    mesh = make_material_ball(24)
    path = tmp_path / "ball.ply"
    path.write_bytes(encode_mesh_ply(mesh))
    loaded = trimesh.load(path, process=False)
    np.testing.assert_array_equal(loaded.vertices, mesh.positions)
    np.testing.assert_array_equal(loaded.faces, mesh.indices)
    np.testing.assert_allclose(loaded.vertex_normals, mesh.normals, atol=1e-6)


def test_an_obj_with_a_comment_outside_utf8_reads(tmp_path):
    """OBJ is text; a Latin-1 byte in a comment sent trimesh to a charset detector it does not install."""
    path = tmp_path / "latin1.obj"
    path.write_bytes(b"# caf\xe9\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    mesh = read_mesh(path)
    assert mesh.positions.shape == (3, 3) and mesh.indices.reshape(-1).tolist() == [0, 1, 2]


def test_a_face_naming_a_missing_vertex_says_what_was_expected(tmp_path):
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n")
    with pytest.raises(SceneError) as info:
        read_mesh(path, "scenes/x.toml", "objects[0].file")
    assert str(info.value) == (f"scenes/x.toml: field 'objects[0].file': mesh {path.as_posix()!r} has a face naming a vertex "
                               "it does not have; expected face indices within its vertices")  # fmt: skip


def test_a_named_pipe_is_refused_before_it_is_opened(tmp_path):
    import os

    os.mkfifo(tmp_path / "m.obj")
    with pytest.raises(SceneError, match=r"objects\[1\].file': expected an OBJ or PLY file, got a named pipe"):
        read_mesh(tmp_path / "m.obj", "s.toml", "objects[1].file")


@pytest.mark.parametrize(("text", "mended", "expected"), [
    # OBJ counts from 1: trimesh read index 0 as some other vertex, and the triangle came out degenerate, unseen.
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "f 1 2 3", "line 4: a face names index 0; expected indices from 1"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//0\n", "f 1//1 2//1 3//1", "line 5: a face names index 0"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 00 2 3\n", "f 1 2 3", "line 4: a face names index 0"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 -0 3\n", "f 1 -2 3", "line 4: a face names index 0"),
    # A vertex line of two numbers: trimesh's vertices and normals disagreed, and building the mesh raised (exit 1).
    ("v 0 0 0\nv 1 0 0\nv 0 1\nf 1 2 3\n", "v 0 1 0\nf 1 2 3", "; expected x y z on every vertex line"),
    # A word that is no number: the message was NumPy's "could not be read to its end due to unmatched data".
    ("v 0 0 0\nv 1 0 0\nv 0 1 0 x\nf 1 2 3\n", "v 0 1 0\nf 1 2 3",
     ": line 3 is 'v 0 1 0 x'; expected a vertex as 'v x y z', three numbers"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 x\n", "f 1 2 3", ": line 4 is 'f 1 2 3 x'; expected a face as 'f i j k'"),
    # A normal the file does not have: trimesh dropped all of them, and the mesh was shaded with its own, unseen.
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//5 2//1 3//1\n", "f 1//1 2//1 3//-1",
     ": a face names normal 5 of the 1 it has; expected normal indices within its vn lines"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/-2\n", "f 1/1/1 2/1/1 3/1/1", "a face names normal -2 of the 1"),
])  # fmt: skip
def test_an_obj_that_is_not_what_it_says_is_refused_on_one_line(tmp_path, text, mended, expected):
    path = tmp_path / "m.obj"
    path.write_text(text)
    with pytest.raises(SceneError) as info:
        read_mesh(path, "s.toml", "objects[0].file")
    message = str(info.value)
    assert message.startswith(f"s.toml: field 'objects[0].file': mesh {path.as_posix()!r}") and expected in message, message
    last = text.rstrip("\n").rsplit("\n", 2 if mended.startswith("v") else 1)[0]
    path.write_text(f"{last}\n{mended}\n")
    assert read_mesh(path).indices.size == 3  # the same file, mended, reads


def test_comments_after_values_are_read_as_comments(tmp_path):
    """trimesh failed on a vertex line that ends in a comment; the comment is dropped before it reads."""
    path = tmp_path / "m.obj"
    path.write_text("# a triangle\nv 0 0 0 # origin\nv 1 0 0\t#x\nv 0 1 0#y\nf 1 2 3 # the face\n")
    mesh = read_mesh(path)
    np.testing.assert_array_equal(mesh.positions, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert mesh.indices.reshape(-1).tolist() == [0, 1, 2]


def test_a_ply_whose_vertices_lack_a_coordinate_says_which(tmp_path):
    """trimesh raised KeyError: 'z', which the message passed on as it was."""
    path = tmp_path / "m.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nelement face 1\n"
                    "property list uchar int vertex_indices\nend_header\n0 0\n1 0\n0 1\n3 0 1 2\n")  # fmt: skip
    with pytest.raises(SceneError) as info:
        read_mesh(path, "s.toml", "objects[0].file")
    assert str(info.value) == (f"s.toml: field 'objects[0].file': mesh {path.as_posix()!r}: its vertices have no property z; "
                               "expected properties x, y and z")  # fmt: skip


@pytest.mark.parametrize("index", ["7", "-1"])
def test_a_ply_face_naming_a_vertex_it_lacks_says_what_was_expected(tmp_path, index):
    """The line named the fault but not what a face must hold."""
    path = tmp_path / "m.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    f"element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 {index}\n")  # fmt: skip
    with pytest.raises(SceneError) as info:
        read_mesh(path, "s.toml", "objects[0].file")
    assert str(info.value) == (f"s.toml: field 'objects[0].file': mesh {path.as_posix()!r} has faces that are not triangles "
                               "of its vertices; expected three vertex indices from 0 to 2 on each face")  # fmt: skip


def test_a_mesh_over_the_triangle_limit_is_refused(tmp_path, monkeypatch):
    """A 300 MB PLY of 16M triangles ended in MemoryError (exit 1); the limit is lowered here to stand for it."""
    import atlasgen.render.meshes as meshes

    monkeypatch.setattr(meshes, "MAX_MESH_TRIANGLES", 1)
    path = tmp_path / "quad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
    with pytest.raises(SceneError, match=r"has 2 triangles; expected at most 1$"):
        read_mesh(path, "s.toml", "objects[0].file")


def _ply(vertices: int, faces: int, fmt: str) -> bytes:
    """A PLY of one triangle whose header declares ``vertices`` and ``faces`` (3 and 1 are the truth)."""
    import struct

    header = (f"ply\nformat {fmt} 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\n"
              f"property float z\nelement face {faces}\nproperty list uchar int vertex_indices\nend_header\n")  # fmt: skip
    if fmt == "ascii":
        return (header + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2").encode()  # no final line break: the last value needs none
    return header.encode() + struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<B3i", 3, 0, 1, 2)


@pytest.mark.parametrize(("fmt", "vertices", "faces", "expected"), [
    # trimesh read this one as a mesh without triangles
    ("ascii", 2_000_000_000, 1, "its header declares element vertex 2000000000, element face 1, at least 12000000001 "
                                "bytes, and 25 follow it; expected the counts of the elements the file holds"),
    ("ascii", 30, 1, "element vertex 30, element face 1, at least 181 bytes, and 25 follow it"),
    # and these as "PLY is unexpected length!"
    ("binary_little_endian", 2_000_000_000, 1, "element vertex 2000000000, element face 1, at least 24000000001 bytes"),
    ("binary_little_endian", 5, 1, "element vertex 5, element face 1, at least 61 bytes, and 49 follow it"),
    ("binary_big_endian", 3, 2_000_000_000, "declares 2000000000 faces; expected at most 8000000 triangles"),
])  # fmt: skip
def test_a_ply_declaring_more_than_it_holds_is_refused_on_one_line(tmp_path, fmt, vertices, faces, expected):
    path = tmp_path / "m.ply"
    path.write_bytes(_ply(vertices, faces, fmt))
    with pytest.raises(SceneError) as info:
        read_mesh(path, "s.toml", "objects[0].file")
    message = str(info.value)
    assert message.startswith(f"s.toml: field 'objects[0].file': mesh {path.as_posix()!r}") and expected in message, message
    if fmt != "binary_big_endian":  # the triangle is written little-endian
        path.write_bytes(_ply(3, 1, fmt))
        assert read_mesh(path).indices.reshape(-1).tolist() == [0, 1, 2]  # the truthful header reads


@pytest.mark.parametrize(("vertices", "faces", "extra", "lines"), [
    (2, 1, "", 4),  # an extra vertex line: trimesh read it as a face's and said "has no triangles"
    (3, 1, "\n0 0 0\n1 2 3\n", 6),  # lines after the last element: dropped without a word
])  # fmt: skip
def test_an_ascii_ply_holding_other_lines_than_it_declares_is_refused(tmp_path, vertices, faces, extra, lines):
    path = tmp_path / "m.ply"
    path.write_bytes(_ply(vertices, faces, "ascii") + extra.encode())
    with pytest.raises(SceneError) as info:
        read_mesh(path, "s.toml", "objects[0].file")
    assert str(info.value).endswith(f": {lines} lines follow its header, which declares element vertex {vertices}, "
                                    f"element face {faces}; expected one line per element, {vertices + faces}")  # fmt: skip


def test_a_ctrl_c_while_trimesh_loads_is_raised_once_it_has_loaded(tmp_path, monkeypatch):
    """trimesh imports its optional modules under ``except BaseException``: a Ctrl-C landing there was swallowed and
    the render ran on to exit 0. A stand-in module does what trimesh does; the interrupt comes out after the import."""
    import signal
    import sys

    from atlasgen.render.meshes import import_trimesh

    (tmp_path / "trimesh.py").write_text(
        "import os, signal\ntry:\n    os.kill(os.getpid(), signal.SIGINT)\n    import _no_such_optional_module\n"
        "except BaseException:\n    pass\nLOADED = True\n"
    )
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # raises KeyboardInterrupt
    monkeypatch.syspath_prepend(str(tmp_path))
    real = sys.modules.pop("trimesh", None)
    try:
        with pytest.raises(KeyboardInterrupt):
            import_trimesh()
        assert sys.modules["trimesh"].LOADED  # the import itself ran to its end
    finally:
        sys.modules.pop("trimesh", None)
        if real is not None:
            sys.modules["trimesh"] = real


def test_a_binary_ply_of_another_length_says_so_in_words(tmp_path):
    """A binary PLY with bytes after its elements gave "(ValueError: PLY is unexpected length!)": Python's class name,
    then trimesh's own words. The line gives what the header declares and the bytes that follow it."""
    import re

    path = tmp_path / "m.ply"
    path.write_bytes(_ply(3, 1, "binary_little_endian") + bytes(64))
    with pytest.raises(SceneError) as info:
        read_mesh(path, "s.toml", "objects[0].file")
    message = str(info.value)
    assert message == (f"s.toml: field 'objects[0].file': mesh {path.as_posix()!r}: the {49 + 64} bytes after its header "
                       "are not the elements it declares (element vertex 3, element face 1); expected those elements "
                       "and nothing after them"), message  # fmt: skip
    assert not re.search(r"\b[A-Z]\w*Error\b|unexpected length", message), message


_SQUARE = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n"


@pytest.mark.parametrize("written", [
    _SQUARE.replace("v ", "v\t", 1),  # the first vertex: the others shifted by one, another triangle drawn
    _SQUARE.replace("f 2", "f\t2"),  # the second face vanished
    _SQUARE.replace(" ", "\t"),  # every line: refused as "has no triangles"
    "\ufeff" + _SQUARE,  # a byte-order mark: the first vertex dropped
])  # fmt: skip
def test_an_obj_with_tabs_or_a_byte_order_mark_reads_as_with_spaces(tmp_path, written):
    """A hostile sweep's: trimesh drops a 'v' or 'f' line whose keyword a tab follows, and a line that a byte-order
    mark starts, without a word (OBJ words are split by any whitespace)."""
    plain, other = tmp_path / "plain.obj", tmp_path / "other.obj"
    plain.write_text(_SQUARE)
    other.write_text(written, encoding="utf-8")
    a, b = read_mesh(plain), read_mesh(other)
    np.testing.assert_array_equal(b.positions, a.positions)
    np.testing.assert_array_equal(b.indices, a.indices)
    assert len(b.indices) == 2


@pytest.mark.parametrize("kind", ["float", "double"])
def test_a_ply_whose_face_indices_are_not_integers_is_refused(tmp_path, kind):
    """A hostile sweep's: a face '3 0.5 1.7 2' read as vertices 0, 1, 2, without a word."""
    path = tmp_path / "m.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    f"element face 1\nproperty list uchar {kind} vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n"
                    "3 0.5 1.7 2\n")  # fmt: skip
    with pytest.raises(SceneError) as info:
        read_mesh(path, "s.toml", "objects[0].file")
    assert str(info.value) == (f"s.toml: field 'objects[0].file': mesh {path.as_posix()!r}: its faces' vertex_indices are "
                               f"of type {kind}; expected an integer type (a vertex index is a whole number)")  # fmt: skip
