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
