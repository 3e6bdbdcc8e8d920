"""pi1 / pi2 maps: angle round trips, texel coordinates, quadrature weights, grid extension."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.separable.parametrization import (
    ANGLE_RANGES,
    PARAMETRIZATIONS,
    SYSTEM_ANGLES,
    angles_of_directions,
    clamp_phi_d,
    directions_of_angles,
    get_parametrization,
)

Z = np.array([0.0, 0.0, 1.0])


@pytest.mark.slow
@given(
    th=st.floats(0.01, 1.5),
    td=st.floats(0.01, 1.5),
    pd=st.floats(0.01, 3.13),
)
@settings(max_examples=200, deadline=None)
def test_half_diff_angles_round_trip(th, td, pd):
    l, v = directions_of_angles("half_diff", th, td, pd)
    np.testing.assert_allclose(np.linalg.norm(l), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(v), 1.0, atol=1e-12)
    # Independent check of the geometry: h is the normalised l + v.
    h = (l + v) / np.linalg.norm(l + v)
    np.testing.assert_allclose(np.arccos(np.clip(h[2], -1, 1)), th, atol=1e-7)
    np.testing.assert_allclose(np.arccos(np.clip(l @ h, -1, 1)), td, atol=1e-7)
    (a, b, c), valid = angles_of_directions("half_diff", Z, l, v)
    np.testing.assert_allclose([a, b, c], [th, td, pd], atol=1e-7)
    # Rusinkiewicz 1998: cos theta_l = cos th cos td + sin th sin td cos pd.
    np.testing.assert_allclose(l[2], np.cos(th) * np.cos(td) + np.sin(th) * np.sin(td) * np.cos(pd), atol=1e-12)
    assert bool(valid) == bool(l[2] > 0 and v[2] > 0)


@given(tl=st.floats(0.01, 1.56), tv=st.floats(0.01, 1.56), phi=st.floats(0.01, 3.13), spin=st.floats(0, 6.28))
@settings(max_examples=200, deadline=None)
@pytest.mark.slow
def test_in_out_angles_round_trip_and_rotation_invariance(tl, tv, phi, spin):
    l, v = directions_of_angles("in_out", tl, tv, phi)
    c, s = np.cos(spin), np.sin(spin)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    (a, b, p), valid = angles_of_directions("in_out", Z, rot @ l, rot @ v)
    np.testing.assert_allclose([a, b, p], [tl, tv, phi], atol=1e-7)
    assert valid


@given(spin=st.floats(0, 6.28), tilt=st.floats(0.0, 3.0))
@settings(max_examples=50, deadline=None)
def test_angles_do_not_depend_on_the_frame(spin, tilt):
    """The angles use n, l, v only: rotating all three together changes nothing."""
    rng = np.random.default_rng(3)
    l = rng.normal(size=(50, 3))
    v = rng.normal(size=(50, 3))
    l /= np.linalg.norm(l, axis=1, keepdims=True)
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    c, s, ct, st_ = np.cos(spin), np.sin(spin), np.cos(tilt), np.sin(tilt)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.array([[1, 0, 0], [0, ct, -st_], [0, st_, ct]])
    for system in ("half_diff", "in_out"):
        base, valid = angles_of_directions(system, Z, l, v)
        moved, valid2 = angles_of_directions(system, rot @ Z, l @ rot.T, v @ rot.T)
        np.testing.assert_allclose(np.array(moved), np.array(base), atol=1e-9)
        np.testing.assert_array_equal(valid, valid2)


@pytest.mark.parametrize("name", sorted(PARAMETRIZATIONS))
def test_grid_directions_map_back_to_their_texels(name):
    p = get_parametrization(name)
    n = 16
    l, v = p.grid_directions(n, extend=False)
    x1, x2, y2, valid = p.coordinates(Z, l, v, n)
    idx = np.arange(n, dtype=float)
    expect1 = np.broadcast_to(idx[:, None, None], x1.shape)
    expect2 = np.broadcast_to(idx[None, None, :], x2.shape)
    expecty = np.broadcast_to(idx[None, :, None], y2.shape)
    # Away from the degenerate azimuths (a polar angle of 0) every texel maps to itself.
    a1, (ax, ay) = p.grid(n)
    ok = valid & (l[..., 2] < 1 - 1e-9) & (v[..., 2] < 1 - 1e-9)
    ok &= np.broadcast_to(a1[:, None, None] > 1e-9, ok.shape) & np.broadcast_to(ax[None, None, :] > 1e-9, ok.shape)
    ok &= np.broadcast_to(ay[None, :, None] > 1e-9, ok.shape)
    ok &= (x1 < n - 1) | (expect1 == n - 1)  # a texel on the horizon is clamped in valid
    assert ok.sum() > 0.25 * ok.size
    np.testing.assert_allclose(x1[ok], expect1[ok], atol=1e-6)
    np.testing.assert_allclose(x2[ok], expect2[ok], atol=1e-6)
    np.testing.assert_allclose(y2[ok], expecty[ok], atol=1e-6)


@pytest.mark.parametrize("warp", ["linear", "sqrt", "sqrt_hi", "cos"])
def test_warps_invert(warp):
    from atlasgen.separable.parametrization import Parametrization

    p = Parametrization("t", "half_diff", "theta_h", (("theta_h", warp),))
    t = np.linspace(0, 1, 101)
    angle = p.angle_at("theta_h", t)
    assert angle[0] == pytest.approx(0.0, abs=1e-12) and angle[-1] == pytest.approx(np.pi / 2)
    assert np.all(np.diff(angle) > 0)
    np.testing.assert_allclose(p.texel_of("theta_h", angle, 32), t * 31, atol=1e-9)


@pytest.mark.parametrize("name", ["half_diff", "in_out", "half_diff_phi_d", "in_out_theta_l"])
def test_quadrature_weights_integrate_uniform_pairs(name):
    """E[cos_l cos_v] over independent uniform l, v on the hemisphere is (1/2)^2 = 1/4."""
    p = get_parametrization(name)
    n = 32
    w1, w2 = p.quadrature_weights(n)
    assert np.all(w1 > 0) and np.all(w2 > 0)
    l, v = p.grid_directions(n, extend=False)
    w = (w1[:, None] * w2[None, :]).reshape(l.shape[:-1])
    valid = (l[..., 2] > 0) & (v[..., 2] > 0)
    mean = np.sum(w * valid * l[..., 2] * v[..., 2]) / np.sum(w * valid)
    assert mean == pytest.approx(0.25, rel=0.03)


@given(th=st.floats(0, 1.5707), td=st.floats(0, 1.5707), pd=st.floats(0, 3.1415))
@settings(max_examples=200, deadline=None)
@pytest.mark.slow
def test_clamp_phi_d_lands_above_the_horizon_and_keeps_valid_ones(th, td, pd):
    clamped = clamp_phi_d(th, td, pd)
    l, v = directions_of_angles("half_diff", th, td, clamped)
    assert l[2] >= -1e-12 and v[2] >= -1e-12
    l0, v0 = directions_of_angles("half_diff", th, td, pd)
    if l0[2] >= 0 and v0[2] >= 0:
        assert clamped == pytest.approx(pd, abs=1e-7)


def test_extended_grid_is_above_the_horizon():
    for name in ("half_diff", "in_out"):
        l, v = get_parametrization(name).grid_directions(32)
        assert l[..., 2].min() >= 1e-4 - 1e-12 and v[..., 2].min() >= 1e-4 - 1e-12
        np.testing.assert_allclose(np.linalg.norm(l, axis=-1), 1.0, atol=1e-12)


def test_every_angle_has_a_range():
    for angles in SYSTEM_ANGLES.values():
        for a in angles:
            lo, hi = ANGLE_RANGES[a]
            assert hi > lo
