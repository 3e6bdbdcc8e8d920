"""Back-lit translucency: the (N.L, N.V) reduction against direct 3D vector evaluation."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.contract import texel_grid
from atlasgen.io.fields import validate_params
from atlasgen.models import get_model
from atlasgen.models.backlit import translucency

MODEL = get_model("backlit")
DEFAULTS = validate_params(MODEL.params, {}, "test")


def vectors(n_dot_l, n_dot_v, phi):
    """N = z; L in the xz-plane; V rotated by azimuth phi from L's plane."""
    sl, sv = np.sqrt(1 - n_dot_l**2), np.sqrt(1 - n_dot_v**2)
    phi = np.asarray(phi, dtype=float)
    light = np.stack(np.broadcast_arrays(sl, 0.0, n_dot_l), axis=-1)
    view = np.stack(np.broadcast_arrays(sv * np.cos(phi), sv * np.sin(phi), n_dot_v), axis=-1)
    return np.array([0.0, 0.0, 1.0]), light, view


def talk_formula(n_dot_l, n_dot_v, phi, distortion, power):
    """pow(saturate(dot(V, -(L + N * distortion))), p), written with vectors as in the GDC 2011 shader."""
    normal, light, view = vectors(n_dot_l, n_dot_v, phi)
    return np.clip(np.sum(view * -(light + normal * distortion), axis=-1), 0.0, 1.0) ** power


cosines = st.tuples(st.floats(-1.0, 1.0), st.floats(0.0, 1.0))


@pytest.mark.slow
@given(c=cosines, distortion=st.floats(0.0, 1.0), power=st.one_of(st.floats(0.3, 64.0), st.integers(1, 64).map(float)))
@settings(max_examples=80, deadline=None)
def test_azimuth_average_matches_a_dense_average_of_the_vector_formula(c, distortion, power):
    n_dot_l, n_dot_v = c
    phi = (np.arange(20000) + 0.5) / 20000 * 2 * np.pi  # midpoints over the full circle
    expected = talk_formula(n_dot_l, n_dot_v, phi, distortion, power).mean()
    got = translucency(n_dot_l, n_dot_v, distortion, power, "average")
    assert got == pytest.approx(expected, abs=1e-4)  # 1/40 of an 8-bit step


@given(c=cosines, distortion=st.floats(0.0, 1.0), power=st.floats(0.3, 64.0))
@settings(max_examples=60, deadline=None)
def test_coplanar_is_the_vector_formula_looking_into_the_light(c, distortion, power):
    n_dot_l, n_dot_v = c
    expected = talk_formula(n_dot_l, n_dot_v, np.pi, distortion, power)
    assert translucency(n_dot_l, n_dot_v, distortion, power, "coplanar") == pytest.approx(expected, abs=1e-12)
    # The coplanar case is the peak over azimuth, so it bounds the average.
    assert translucency(n_dot_l, n_dot_v, distortion, power, "average") <= expected + 1e-12


def test_power_one_has_a_closed_form_average():
    # (1/pi) int_phi0^pi (a - b cos phi) dphi = (a (pi - phi0) + b sin phi0) / pi, phi0 = acos(a/b).
    nl, nv = texel_grid()
    delta = 0.3
    a, b = -nl * nv - delta * nv, np.sqrt(1 - nl**2) * np.sqrt(1 - nv**2)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi0 = np.arccos(np.clip(np.where(b > 0, a / b, np.sign(a) * 2), -1, 1))
    expected = (a * (np.pi - phi0) + b * np.sin(phi0)) / np.pi
    np.testing.assert_allclose(translucency(nl, nv, delta, 1.0, "average"), expected, rtol=0, atol=1e-6)


def test_both_views_agree_where_the_table_is_exact():
    # V.(-L) has no azimuth dependence at N.L = -1 or N.V = 1.
    nl, nv = texel_grid()
    avg = translucency(nl, nv, 0.2, 5.0, "average")
    cop = translucency(nl, nv, 0.2, 5.0, "coplanar")
    np.testing.assert_allclose(avg[:, 0], cop[:, 0], atol=1e-14)
    np.testing.assert_allclose(avg[-1], cop[-1], atol=1e-14)
    # ... and straight through (N.L = -1, N.V = 1, no distortion) transmits fully.
    assert translucency(-1.0, 1.0, 0.0, 8.0) == pytest.approx(1.0)


def test_model_adds_front_diffuse_and_coloured_transmission():
    params = {
        **DEFAULTS,
        "colour": (0.2, 0.5, 0.1),
        "transmission_colour": (0.9, 0.8, 0.2),
        "scale": 2.0,
        "ambient": 0.05,
        "specular": 0.3,
    }
    nl = np.linspace(-1, 1, 9)[:, None]
    nv = np.linspace(0, 1, 5)[None, :]
    out = MODEL.evaluate(params, nl, nv)
    t = translucency(nl, nv, params["distortion"], params["power"], params["view"])
    expected = np.clip(nl, 0, None)[..., None] * (0.2, 0.5, 0.1) + (2.0 * t + 0.05)[..., None] * (0.9, 0.8, 0.2)
    np.testing.assert_allclose(out[..., :3], expected, rtol=1e-14)
    assert (out[..., 3] == 0.3).all()
    # Transmission peaks behind the surface: N.L = -1 outshines grazing light at N.V = 1.
    assert out[0, -1, 0] > out[4, -1, 0]


params_strategy = st.fixed_dictionaries(
    {
        "colour": st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
        "transmission_colour": st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3),
        "distortion": st.floats(0.0, 1.0),
        "power": st.floats(0.0, 64.0, exclude_min=True, width=32),  # valid: > 0 in float32 too
        "scale": st.floats(0.0, 16.0),
        "ambient": st.floats(0.0, 1.0),
        "view": st.sampled_from(["average", "coplanar"]),
        "specular": st.floats(0.0, 16.0),
    }
)


@given(raw=params_strategy)
@settings(max_examples=50, deadline=None)
@pytest.mark.slow
def test_random_valid_parameters_give_finite_non_negative_slices(raw, valid_slice):
    params = validate_params(MODEL.params, raw, "hypothesis")
    values = valid_slice(MODEL, params)
    assert values[..., :3].max() <= 1.0 + params["scale"] + params["ambient"] + 1e-12


@pytest.mark.parametrize(
    "body, field, expected",
    [
        ("power = 0", "power", "expected a finite number > 0 and <= 64, got 0"),
        ("power = nan", "power", "got nan"),
        ("distortion = 1.5", "distortion", "<= 1"),
        ('view = "side"', "view", "one of 'average', 'coplanar'"),
        ("transmission_color = [1, 1, 1]", "transmission_color", "did you mean 'transmission_colour'?"),
    ],
)
def test_bad_parameters_are_rejected(expect_rejected, body, field, expected):
    expect_rejected("backlit", body, field, expected)
