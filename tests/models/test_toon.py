"""Toon: bands, silhouette and stepped specular at exact positions; the outline flag; cross-field checks."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from atlasgen.contract import texel_centres
from atlasgen.errors import MaterialError
from atlasgen.io.fields import validate_params
from atlasgen.models import get_model

MODEL = get_model("toon")
DEFAULTS = validate_params(MODEL.params, {}, "test")
RED, GREEN, BLUE, INK = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (0.1, 0.1, 0.1)
THREE = "colours = [[0,0,0],[1,1,1],[1,0,0]]"


def test_bands_switch_exactly_at_the_thresholds():
    params = {**DEFAULTS, "thresholds": (-0.2, 0.4), "colours": (RED, GREEN, BLUE), "sampling": "linear"}
    eps = 1e-12
    nl = np.array([-1.0, -0.2 - eps, -0.2, 0.4 - eps, 0.4, 1.0])
    out = MODEL.evaluate(params, nl, 0.5)
    np.testing.assert_array_equal(out[:, :3], [RED, RED, GREEN, GREEN, BLUE, BLUE])


def test_baked_slice_assigns_each_texel_its_band():
    params = {**DEFAULTS, "thresholds": (0.0, 0.5), "colours": (RED, GREEN, BLUE), "silhouette": 0.2, "silhouette_colour": INK}
    values = MODEL.bake(params).values[0]
    nl, nv = texel_centres()
    for j, v in enumerate(nv):
        for i, l in enumerate(nl):
            expected = INK if v < 0.2 else (RED if l < 0.0 else GREEN if l < 0.5 else BLUE)
            np.testing.assert_array_equal(values[j, i, :3], expected)


def test_stepped_specular_is_off_in_the_silhouette_and_below_its_threshold():
    params = {**DEFAULTS, "specular": 2.5, "specular_threshold": 0.7, "silhouette": 0.1, "sampling": "linear"}
    nl = np.array([0.69, 0.7, 1.0])[:, None]
    nv = np.array([0.05, 0.1, 0.9])[None, :]
    a = MODEL.evaluate(params, nl, nv)[..., 3]
    np.testing.assert_array_equal(a, [[0, 0, 0], [0, 2.5, 2.5], [0, 2.5, 2.5]])


def test_outline_flag_reaches_the_manifest_flags(load):
    assert MODEL.flags(DEFAULTS) == {"outline": False, "nearest": True}
    material = load("toon", 'outline = true\nsampling = "linear"')
    assert material.model.flags(material.params) == {"outline": True, "nearest": False}


def test_nearest_steps_lie_on_texel_boundaries():
    nl_edges = -1 + (2 * np.arange(63) + 1) / 63
    nv_edges = (2 * np.arange(31) + 1) / 62
    t = np.linspace(-1, 1, 401)
    snapped = MODEL.snap_n_dot_l(t)
    assert np.isin(snapped, nl_edges).all()
    assert np.abs(snapped - t).max() <= 1 / 63 + 1e-12
    v = np.linspace(0.001, 1, 300)
    assert np.isin(MODEL.snap_n_dot_v(v), nv_edges).all() and MODEL.snap_n_dot_v(0.0) == 0.0


@given(seed=st.integers(0, 2**32 - 1))
@settings(max_examples=20, deadline=None)
def test_nearest_sampled_slice_reproduces_the_model_everywhere(seed):
    """What the renderer reads (nearest texel of the baked slice) equals the model at any (N.L, N.V)."""
    from atlasgen.optics.interpolation import sample_slice

    rng = np.random.default_rng(seed)
    thresholds = tuple(sorted(rng.uniform(-1, 1, 3)))
    params = {
        **DEFAULTS,
        "thresholds": thresholds,
        "colours": (INK, RED, GREEN, BLUE),
        "silhouette": float(rng.uniform(0, 0.5)),
        "specular_threshold": float(rng.uniform(-1, 1)),
    }
    table = MODEL.bake(params).values[0]
    nl, nv = rng.uniform(-1, 1, 5000), rng.uniform(0, 1, 5000)
    np.testing.assert_array_equal(sample_slice(table, nl, nv, nearest=True), MODEL.evaluate(params, nl, nv))


def test_no_thresholds_is_a_flat_colour():
    params = {**DEFAULTS, "thresholds": (), "colours": (GREEN,)}
    out = MODEL.bake(params).values
    assert (out[..., :3] == GREEN).all()


@st.composite
def params_strategy(draw):
    thresholds = sorted(set(draw(st.lists(st.floats(-1.0, 1.0), max_size=6))))
    colour = st.lists(st.floats(0.0, 1.0), min_size=3, max_size=3)
    return {
        "thresholds": thresholds,
        "colours": draw(st.lists(colour, min_size=len(thresholds) + 1, max_size=len(thresholds) + 1)),
        "silhouette": draw(st.floats(0.0, 1.0)),
        "silhouette_colour": draw(colour),
        "specular": draw(st.floats(0.0, 16.0)),
        "specular_threshold": draw(st.floats(-1.0, 1.0)),
        "outline": draw(st.booleans()),
        "sampling": draw(st.sampled_from(["nearest", "linear"])),
    }


@pytest.mark.slow
@given(raw=params_strategy())
@settings(max_examples=50, deadline=None)
def test_random_valid_parameters_give_finite_non_negative_slices(raw, valid_slice):
    params = validate_params(MODEL.params, raw, "hypothesis")
    try:
        MODEL.check(params, "hypothesis")
    except MaterialError as exc:  # two thresholds within a texel: refused, naming the band
        assert "holds none" in str(exc)
        assume(False)
    values = valid_slice(MODEL, params)
    # Every texel holds one of the declared colours: the table never blends bands itself.
    allowed = {tuple(c) for c in raw["colours"]} | {tuple(raw["silhouette_colour"])}
    assert {tuple(t) for t in values[0, :, :, :3].reshape(-1, 3).tolist()} <= allowed
    # And every band's colour is baked: the top row (N.V = 1) lies above any silhouette.
    assert {tuple(c) for c in raw["colours"]} <= {tuple(t) for t in values[0, -1, :, :3].tolist()}


@pytest.mark.parametrize(
    "body, field, expected",
    [
        (f"thresholds = [0.5, 0.2]\n{THREE}", "thresholds", "expected strictly ascending values, got [0.5, 0.2]"),
        (f"thresholds = [0.2, 0.2]\n{THREE}", "thresholds", "strictly ascending"),
        (f"thresholds = [0.2]\n{THREE}", "colours", "expected 2 colours (one more than the 1 thresholds), got 3"),
        ("thresholds = [1.5]\ncolours = [[0,0,0],[1,1,1]]", "thresholds[0]", "<= 1"),
        ("thresholds = [nan]\ncolours = [[0,0,0],[1,1,1]]", "thresholds[0]", "got nan"),
        ('colours = [[0,0,0],"#zzzzzz",[1,1,1]]', "colours[1]", "'#rrggbb'"),
        ("outline = 1", "outline", "expected true or false"),
        ("outlines = true", "outlines", "did you mean 'outline'?"),
        # A band narrower than a texel of the N.L axis would not be baked, however it is sampled.
        (f"thresholds = [0.0, 0.001]\n{THREE}", "thresholds",
         "expected every band to hold a texel of the N.L axis (64 texels, 0.0317 apart), but colours[1]'s band, from "
         "thresholds[0] = 0 to thresholds[1] = 0.001, holds none (nearest sampling)"),
        (f'thresholds = [0.0, 0.001]\nsampling = "linear"\n{THREE}', "thresholds", "holds none (linear sampling)"),
        ('thresholds = [-1.0]\nsampling = "linear"\ncolours = [[0,0,0],[1,1,1]]', "thresholds",
         "colours[0]'s band, from -1 to thresholds[0] = -1, holds none (linear sampling)"),
    ],
)  # fmt: skip
def test_bad_parameters_are_rejected(expect_rejected, body, field, expected):
    expect_rejected("toon", body, field, expected)


def test_a_long_threshold_list_is_shortened_in_its_refusal(expect_rejected):
    """A million-byte error line once: the list is shortened as every other value in a message is."""
    message = expect_rejected("toon", "thresholds = [" + "0.0, " * 20000 + "0.0]", "thresholds",
                              "expected strictly ascending values, got [0.0, 0.0,")  # fmt: skip
    assert len(message) < 300, len(message)
