"""The fresnel model: its ends, the A convention and the coupled energy (the equations: tests/optics)."""

import numpy as np
import pytest
from tests.fresnel_reference import fresnel_by_angles
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from atlasgen.contract import texel_grid
from atlasgen.models import get_model
from atlasgen.optics.fresnel import normal_reflectance
from atlasgen.io.fields import validate_params

MODEL = get_model("fresnel")
DEFAULTS = validate_params(MODEL.params, {}, "test")


@pytest.mark.parametrize("kind", ["exact", "schlick"])
def test_ends_of_the_range(kind):
    f = MODEL.reflectance({**DEFAULTS, "fresnel": kind}, np.array([0.0, 1.0]))
    np.testing.assert_allclose(f, [1.0, 0.04], rtol=1e-12)


@pytest.mark.parametrize("kind", ["exact", "schlick"])
def test_alpha_is_f_by_default_and_f_over_f0_when_normalised(kind):
    params = {**DEFAULTS, "fresnel": kind}
    nl, nv = texel_grid()
    a = MODEL.evaluate(params, nl, nv)[..., 3]
    np.testing.assert_allclose(a, np.broadcast_to(MODEL.reflectance(params, nv), a.shape), rtol=1e-15)
    gain = MODEL.evaluate({**params, "normalise": True, "specular": 0.5}, nl, nv)[..., 3]
    np.testing.assert_allclose(gain, 0.5 * a / 0.04, rtol=1e-12)
    np.testing.assert_allclose(gain[0], 0.5 * 25.0, rtol=1e-12)  # row 0 is N.V = 0: F/F0 = 25
    np.testing.assert_allclose(gain[-1], 0.5, rtol=1e-12)


def test_coupled_energy_is_two_way_transmission_renormalised():
    colour = (0.8, 0.5, 0.2)
    nl = np.linspace(-1.0, 1.0, 41)[:, None]
    nv = np.linspace(0.0, 1.0, 17)[None, :]
    coupled = MODEL.evaluate({**DEFAULTS, "colour": colour}, nl, nv)[..., :3]
    lit = np.clip(nl, 0.0, None)
    f_avg = quad(lambda c: 2 * c * fresnel_by_angles(np.arccos(c), 1.5), 0, 1, epsabs=1e-14)[0]
    t = (1.0 - fresnel_by_angles(np.arccos(np.clip(lit, 1e-9, 1 - 1e-12)), 1.5)) * (
        1.0 - fresnel_by_angles(np.arccos(np.clip(nv, 1e-9, 1 - 1e-12)), 1.5)
    ) / (1.0 - f_avg)
    np.testing.assert_allclose(coupled, (lit * t)[..., None] * colour, atol=1e-7)
    plain = MODEL.evaluate({**DEFAULTS, "colour": colour, "energy": "none"}, nl, nv)[..., :3]
    np.testing.assert_allclose(plain, np.broadcast_to(lit[..., None] * colour, plain.shape), rtol=1e-15)


@given(ior=st.floats(1.01, 4.0), kind=st.sampled_from(["exact", "schlick"]), n_dot_v=st.floats(0.0, 1.0))
@settings(max_examples=40, deadline=None)
def test_white_coupled_coat_conserves_energy_in_the_renderer(ior, kind, n_dot_v):
    # The renderer adds albedo * RGB / pi + A * lobe, with a lobe of unit albedo. Over all
    # light directions (d omega = 2 pi dc, by symmetry in azimuth) the diffuse term then
    # reflects (1/pi) int RGB d omega = 2 int_0^1 RGB(c) dc; with A = F the two add up to 1.
    params = {**DEFAULTS, "colour": (1.0, 1.0, 1.0), "fresnel": kind, "ior": ior}
    diffuse = quad(lambda c: 2 * MODEL.evaluate(params, c, n_dot_v)[0], 0, 1, epsabs=1e-12, limit=200)[0]
    specular = MODEL.evaluate(params, 1.0, n_dot_v)[3]
    assert diffuse + specular == pytest.approx(1.0, abs=1e-9)


params_strategy = st.fixed_dictionaries(
    {
        "colour": st.tuples(*[st.floats(0.0, 1.0)] * 3),
        "fresnel": st.sampled_from(["exact", "schlick"]),
        "ior": st.floats(1.01, 4.0),
        "specular": st.floats(0.0, 16.0),
        "normalise": st.booleans(),
        "energy": st.sampled_from(["coupled", "none"]),
    }
)


@given(raw=params_strategy)
@settings(max_examples=50, deadline=None)
def test_random_valid_parameters_give_finite_non_negative_slices(raw, valid_slice):
    params = validate_params(MODEL.params, {**raw, "colour": list(raw["colour"])}, "hypothesis")
    MODEL.check(params, "hypothesis")
    values = valid_slice(MODEL, params)
    # Fresnel never exceeds 1 and never drops below F0: A stays in [F0, 1] (times the scales).
    f0 = float(normal_reflectance(params["ior"]))
    top = params["specular"] / (f0 if params["normalise"] else 1.0)
    assert values[..., 3].max() <= top * (1 + 1e-12)


@pytest.mark.parametrize(
    "body, field, expected",
    [
        ("ior = 0.5", "ior", "expected a finite number >= 1.01 and <= 4, got 0.5"),
        ("ior = nan", "ior", "got nan"),
        ("specular = inf", "specular", "got inf"),
        ('fresnel = "fast"', "fresnel", "one of 'exact', 'schlick'"),
        ("normalise = 1", "normalise", "true or false"),
        ('energy = "conserve"', "energy", "one of 'coupled', 'none'"),
        ("iorr = 1.5", "iorr", "did you mean 'ior'?"),
    ],
)
def test_bad_parameters_are_rejected(expect_rejected, body, field, expected):
    expect_rejected("fresnel", body, field, expected)


def test_a_valid_file_loads_with_defaults_filled(load):
    m = load("fresnel", 'fresnel = "schlick"\nior = 1.33')
    assert m.params == {**DEFAULTS, "fresnel": "schlick", "ior": 1.33}
