"""The fresnel model: its ends, the A convention and the coupled energy (the equations: tests/optics)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from atlasgen.contract import texel_grid
from atlasgen.io.fields import validate_params
from atlasgen.models import get_model
from atlasgen.optics.fresnel import normal_reflectance
from atlasgen.optics.microfacet import ggx_distribution
from atlasgen.optics.specular import specular_alpha, specular_f_cos
from tests.fresnel_reference import fresnel_by_angles

MODEL = get_model("fresnel")
DEFAULTS = validate_params(MODEL.params, {}, "test")


@pytest.mark.parametrize("kind", ["exact", "schlick"])
def test_ends_of_the_range(kind):
    f = MODEL.reflectance({**DEFAULTS, "fresnel": kind}, np.array([0.0, 1.0]))
    np.testing.assert_allclose(f, [1.0, 0.04], rtol=1e-12)


@pytest.mark.parametrize("kind", ["exact", "schlick"])
def test_alpha_is_f_at_the_lobe_peak_by_default_and_f_over_f0_when_normalised(kind):
    params = {**DEFAULTS, "fresnel": kind}
    nl, nv = texel_grid()
    a = MODEL.evaluate(params, nl, nv)[..., 3]
    # L.H with l and v coplanar on opposite sides of n, built from vectors.
    cl = np.clip(nl, 0.0, 1.0)
    l = np.stack([-np.sqrt(1 - cl * cl), 0 * cl, cl], -1)
    v = np.stack([np.sqrt(1 - nv * nv), 0 * nv, nv], -1)
    h = l + v
    norm = np.linalg.norm(h, axis=-1)
    ok = norm > 1e-9  # l = -v at N.L = N.V = 0: no half vector
    l_dot_h = np.sum(l * h, -1)[ok] / norm[ok]
    np.testing.assert_allclose(a[ok], MODEL.reflectance(params, l_dot_h), rtol=1e-9)
    mirror = np.abs(nl - nv) < 1e-12
    np.testing.assert_allclose(a[mirror], MODEL.reflectance(params, nv[mirror]), rtol=1e-9)  # at N.L = N.V: F(N.V)
    gain = MODEL.evaluate({**params, "normalise": True, "specular": 0.5}, nl, nv)[..., 3]
    np.testing.assert_allclose(gain, 0.5 * a / 0.04, rtol=1e-12)
    np.testing.assert_allclose(gain[-1, -1], 0.5, rtol=1e-12)  # normal incidence and view: F/F0 = 1


def _lobe_projection(model, params, nl, nv, alpha, n=4096):
    """The least-squares A for one (N.L, N.V): F(L.H) projected over azimuth with the lobe as weight,
    sum F w^2 / sum w^2, w = D(N.H) (V and N.L do not depend on azimuth)."""
    phi = (np.arange(n) + 0.5) * (2.0 * np.pi / n)
    sl, sv = np.sqrt(1 - nl * nl), np.sqrt(1 - nv * nv)
    l = np.stack([sl * np.cos(phi), sl * np.sin(phi), np.full(n, nl)], -1)
    h = l + np.array([sv, 0.0, nv])
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    w = ggx_distribution(h[:, 2], alpha) ** 2
    return float((model.reflectance(params, np.sum(l * h, -1)) * w).sum() / w.sum())


@pytest.mark.parametrize("alpha", [0.05, 0.2, 0.3])
def test_alpha_is_close_to_the_lobe_weighted_projection_of_f_of_l_dot_h(alpha):
    """The re-derived A against what the slice should hold for the GGX lobe; the previous F(N.V) is not."""
    params = dict(DEFAULTS)
    errors, old_errors = [], []
    for nl in (0.2, 0.5, 0.8, 0.95):
        for nv in (0.1, 0.3, 0.6, 0.9):
            best = _lobe_projection(MODEL, params, nl, nv, alpha)
            errors.append(abs(MODEL.evaluate(params, nl, nv)[3] / best - 1.0))
            old_errors.append(abs(MODEL.reflectance(params, nv) / best - 1.0))
    assert max(errors) < 0.11 and np.mean(errors) < 0.04, (max(errors), np.mean(errors))
    assert max(old_errors) > 5.0


def test_coupled_energy_is_two_way_transmission_renormalised():
    colour = (0.8, 0.5, 0.2)
    nl = np.linspace(-1.0, 1.0, 41)[:, None]
    nv = np.linspace(0.0, 1.0, 17)[None, :]
    coupled = MODEL.evaluate({**DEFAULTS, "colour": colour}, nl, nv)[..., :3]
    lit = np.clip(nl, 0.0, None)
    f_avg = quad(lambda c: 2 * c * fresnel_by_angles(np.arccos(c), 1.5), 0, 1, epsabs=1e-14)[0]
    t = (
        (1.0 - fresnel_by_angles(np.arccos(np.clip(lit, 1e-9, 1 - 1e-12)), 1.5))
        * (1.0 - fresnel_by_angles(np.arccos(np.clip(nv, 1e-9, 1 - 1e-12)), 1.5))
        / (1.0 - f_avg)
    )
    np.testing.assert_allclose(coupled, (lit * t)[..., None] * colour, atol=1e-7)
    plain = MODEL.evaluate({**DEFAULTS, "colour": colour, "energy": "none"}, nl, nv)[..., :3]
    np.testing.assert_allclose(plain, np.broadcast_to(lit[..., None] * colour, plain.shape), rtol=1e-15)


def _specular_albedo(params, cos_v, gloss, n=400):
    """int A(N.L, N.V) f_s cos d omega_l, stratified over microfacet normals in D cos theta_h
    (l = reflect(v, h), d omega_l = 4 (v.h) d omega_h; Walter et al. 2007, eqs. 14 and 35)."""
    alpha = float(specular_alpha(gloss))
    xi, phi = np.meshgrid((np.arange(n) + 0.5) / n, (np.arange(2 * n) + 0.5) * (np.pi / n), indexing="ij")
    c = np.sqrt((1.0 - xi) / (xi * (alpha * alpha - 1.0) + 1.0))
    s = np.sqrt(1.0 - c * c)
    h = np.stack([s * np.cos(phi), s * np.sin(phi), c], -1)
    v = np.array([np.sqrt(1.0 - cos_v * cos_v), 0.0, cos_v])
    vh = h @ v
    l = 2.0 * vh[..., None] * h - v
    a = MODEL.evaluate(params, np.clip(l[..., 2], -1, 1), cos_v)[..., 3]
    f = a * specular_f_cos(gloss, l[..., 2], cos_v, c)
    return (np.where(vh > 0, f * 4.0 * vh / (ggx_distribution(c, alpha) * c), 0.0)).mean()


@given(ior=st.floats(1.01, 4.0), kind=st.sampled_from(["exact", "schlick"]), n_dot_v=st.floats(0.05, 1.0),
       gloss=st.sampled_from([0.0, 0.5, 0.9, 1.0]))  # fmt: skip
@settings(max_examples=25, deadline=None)
@pytest.mark.slow
def test_white_coupled_coat_never_creates_energy_in_the_renderer(ior, kind, n_dot_v, gloss):
    # The renderer adds albedo * RGB / pi + A * lobe. Over all light directions (d omega =
    # 2 pi dc, by symmetry in azimuth) the diffuse term reflects 2 int_0^1 RGB(c) dc =
    # 1 - F(N.V) exactly; the GGX lobe (albedo <= 1) scaled by A adds about what the coat
    # reflects, and all of it in the mirror limit at normal view. F(c) exceeds F(N.V) where
    # l is more grazing than v, so the sum may pass 1 slightly: at most 0.44% measured on a grid
    # (ior 1.01 to 4, both Fresnel forms, every gloss), which the bound below allows.
    params = {**DEFAULTS, "colour": (1.0, 1.0, 1.0), "fresnel": kind, "ior": ior}
    diffuse = quad(lambda c: 2 * MODEL.evaluate(params, c, n_dot_v)[0], 0, 1, epsabs=1e-12, limit=200)[0]
    assert diffuse == pytest.approx(1.0 - float(MODEL.reflectance(params, n_dot_v)), abs=1e-9)
    specular = _specular_albedo(params, n_dot_v, gloss)
    assert diffuse + specular <= 1.0 + 5e-3
    if gloss == 1.0 and n_dot_v > 0.9:
        assert diffuse + specular == pytest.approx(1.0, abs=5e-3)


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
