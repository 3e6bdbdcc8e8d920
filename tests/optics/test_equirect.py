"""Equirectangular images in Mitsuba's ``envmap`` convention: the mapping, its texels, their solid
angles, the lookup, rotation and resampling, and the agreement with Mitsuba itself."""

import doctest

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.materials.scene import SceneObject, object_matrix
from atlasgen.optics.equirect import (
    direction_to_uv,
    nearest_texel,
    resample_equirect,
    rotate,
    rotation_matrix,
    sample_equirect,
    texel_directions,
    texel_solid_angles,
    uv_to_direction,
    uv_to_texel,
)

RNG = np.random.default_rng(7)


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_axes_follow_mitsubas_envmap():
    # envmap.cpp: u = atan2(d.x, -d.z) / 2 pi, v = acos(d.y) / pi; d = (sin phi sin theta, cos theta, -cos phi sin theta).
    cases = {(0, 0, -1): (0.0, 0.5), (1, 0, 0): (0.25, 0.5), (0, 0, 1): (0.5, 0.5), (-1, 0, 0): (0.75, 0.5)}
    for d, uv in cases.items():
        np.testing.assert_allclose(direction_to_uv(d), uv, atol=1e-12)
    assert direction_to_uv([0.0, 1.0, 0.0])[1] == 0.0 and direction_to_uv([0.0, -1.0, 0.0])[1] == 1.0


@pytest.mark.slow
@given(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 1e-3))
def test_uv_round_trips_to_the_direction(v):
    d = _unit(v)
    u, w = direction_to_uv(d)
    assert 0.0 <= u < 1.0 and 0.0 <= w <= 1.0
    np.testing.assert_allclose(uv_to_direction(u, w), d, atol=1e-12)


def test_the_texel_of_a_texels_direction_is_that_texel():
    h, w = 16, 32
    d = texel_directions(h, w)
    x, y = uv_to_texel(*direction_to_uv(d), h, w)
    rows, cols = nearest_texel(d, h, w)
    # The pole rows are one direction each: their columns are the same point of the sphere.
    np.testing.assert_allclose(y, np.arange(h)[:, None] * np.ones(w), atol=1e-9)
    np.testing.assert_allclose(x[1:-1], np.ones(h - 2)[:, None] * np.arange(w), atol=1e-9)
    assert (rows == np.arange(h)[:, None]).all() and (cols[1:-1] == np.arange(w)).all()
    np.testing.assert_allclose(d[0], np.broadcast_to([0.0, 1.0, 0.0], (w, 3)), atol=1e-15)


def test_sampling_returns_each_texel_at_its_direction_and_interpolates_between():
    img = RNG.random((8, 16, 3))
    d = texel_directions(8, 16)
    np.testing.assert_allclose(sample_equirect(img, d[1:-1]), img[1:-1], atol=1e-12)
    # Half-way between columns 15 and 0 (across the seam) and between rows 3 and 4.
    mid = uv_to_direction(0.0, 3.5 / 7)
    np.testing.assert_allclose(sample_equirect(img, mid), 0.25 * (img[3, 15] + img[3, 0] + img[4, 15] + img[4, 0]), atol=1e-12)


def test_solid_angles_integrate_the_bilinear_reconstruction_exactly():
    h, w = 9, 16
    omega = texel_solid_angles(h, w)
    assert omega.sum() == pytest.approx(4.0 * np.pi, rel=1e-14)
    img = RNG.random((h, w, 1))
    # Gauss-Legendre on every cell between neighbouring samples, independent of the hats' closed form.
    t, wt = np.polynomial.legendre.leggauss(6)
    cell_t = np.pi / (h - 1)
    cell_p = 2.0 * np.pi / w
    theta = ((np.arange(h - 1)[:, None] + 0.5 + 0.5 * t) * cell_t).ravel()
    phi = ((np.arange(w)[:, None] + 1.0 + 0.5 * t) * cell_p).ravel()  # column i's sample at (i + 1/2) cell_p
    wth = np.tile(0.5 * wt * cell_t, h - 1) * np.sin(theta)
    wph = np.tile(0.5 * wt * cell_p, w)
    d = uv_to_direction(phi[None, :] / (2 * np.pi), theta[:, None] / np.pi)
    exact = np.einsum("tp,t,p->", sample_equirect(img, d)[..., 0], wth, wph)
    assert (omega * img[..., 0]).sum() == pytest.approx(exact, rel=1e-12)


def test_rotation_is_right_handed_about_y_like_an_objects():
    r = rotation_matrix(90.0)
    np.testing.assert_allclose(r @ [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(r @ [1.0, 0.0, 0.0], [0.0, 0.0, -1.0], atol=1e-15)
    obj = object_matrix(SceneObject(0, "sphere", "m", rotate=(0.0, 37.0, 0.0)))
    np.testing.assert_allclose(obj[:3, :3], rotation_matrix(37.0), atol=1e-15)


def test_rotating_moves_radiance_from_d_to_r_d():
    h, w = 16, 32
    img = np.zeros((h, w, 1))
    j, i = nearest_texel(_unit([0.0, 0.3, 1.0]), h, w)
    img[j, i] = 1.0
    src = texel_directions(h, w)[j, i]
    turned = rotate(img, 90.0)  # 90 degrees is 8 whole columns of 32: exact
    jj, ii = np.unravel_index(np.argmax(turned[..., 0]), (h, w))
    np.testing.assert_allclose(texel_directions(h, w)[jj, ii], rotation_matrix(90.0) @ src, atol=1e-12)
    np.testing.assert_allclose(turned, np.roll(img, -8, axis=1), atol=1e-12)
    np.testing.assert_allclose(rotate(img, 360.0), img, atol=1e-12)


def test_resampling_keeps_constants_and_the_integral():
    img = RNG.random((33, 64, 3))
    power = (texel_solid_angles(33, 64)[..., None] * img).sum(axis=(0, 1))
    for h, w, deg in ((16, 32, 0.0), (9, 20, 17.0), (17, 32, -5.0)):
        small = resample_equirect(img, h, w, deg)
        np.testing.assert_allclose((texel_solid_angles(h, w)[..., None] * small).sum(axis=(0, 1)), power, rtol=1e-6)
        np.testing.assert_allclose(resample_equirect(np.full((33, 64, 3), 0.7), h, w, deg), 0.7, rtol=1e-6)
    np.testing.assert_allclose(resample_equirect(img, 33, 64), img, rtol=1e-6)
    # Upsampled, every second row is a source row, and column 2k + 1 lies a quarter of the way from column k to k + 1.
    np.testing.assert_allclose(resample_equirect(img, 65, 128)[::2, 1::2], 0.75 * img + 0.25 * np.roll(img, -1, 1), rtol=1e-6)


@pytest.mark.slow
def test_mitsubas_envmap_sees_the_same_radiance(mitsuba_llvm):
    mi = mitsuba_llvm
    import drjit as dr

    img = RNG.random((8, 16, 3)).astype(np.float32)
    emitter = mi.load_dict({"type": "envmap", "bitmap": mi.Bitmap(img), "scale": 2.0,
                            "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], 30.0)})  # fmt: skip
    d = _unit(RNG.normal(size=(200, 3)))
    si = dr.zeros(mi.SurfaceInteraction3f, len(d))
    si.wi = mi.Vector3f(*(-d.T))  # eval looks along -wi
    seen = np.array(emitter.eval(si)).reshape(3, -1).T
    expected = 2.0 * sample_equirect(img.astype(np.float64), d @ rotation_matrix(30.0))  # R^-1 d, as rows
    np.testing.assert_allclose(seen, expected, rtol=2e-5, atol=2e-6)


def test_the_docstrings_examples_hold():
    from atlasgen.optics import equirect

    assert doctest.testmod(equirect).failed == 0


@pytest.mark.parametrize(("degrees", "remainder"), [(1e20, 280.0), (-3.5e17, -80.0), (810.0, 90.0)])
def test_a_huge_angle_turns_as_its_remainder_of_a_whole_turn(degrees, remainder):
    """1e20 degrees cast a column index beyond int64: the environment came out all zero, exit 0. The
    remainders are worked out by hand: 1e20 = 277777777777777777 x 360 + 280 (1e20 is exact in a double)."""
    rng = np.random.default_rng(3)
    image = rng.uniform(0.1, 1.0, (8, 16, 3))
    for width in (16, 32, 8):  # the point and the averaging paths
        turned = resample_equirect(image, 8, width, degrees)
        np.testing.assert_array_equal(turned, resample_equirect(image, 8, width, remainder))
        assert turned.min() > 0.09


def test_a_scene_s_environment_rotate_is_read_as_its_remainder(tmp_path):
    """Once, where the scene is read, so that the image, the sky's sun and Mitsuba's emitter turn alike."""
    from atlasgen.materials.scene import read_scene

    scene = tmp_path / "s.toml"
    scene.write_text("[environment]\nsource = [1, 1, 1]\nrotate = 1e20\n[camera]\nposition = [0, 0, 5]\ntarget = [0, 0, 0]\n")
    assert read_scene(scene).environment.rotate == 280.0
