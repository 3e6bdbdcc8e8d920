"""Lambert: the exact closed form RGB = colour * max(N.L, 0), A = 0, at every texel and off-grid."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.contract import HEIGHT, WIDTH
from atlasgen.models import get_model

MODEL = get_model("lambert")
unit = st.floats(0.0, 1.0)


@given(colour=st.tuples(unit, unit, unit))
@settings(max_examples=40, deadline=None)
@pytest.mark.slow
def test_bake_is_the_closed_form_at_texel_centres(colour, valid_slice):
    values = valid_slice(MODEL, {"colour": colour})[0]
    for j in (0, 7, HEIGHT - 1):
        for i in range(WIDTH):
            n_dot_l = -1.0 + 2.0 * i / (WIDTH - 1)
            np.testing.assert_array_equal(values[j, i, :3], np.array(colour) * max(n_dot_l, 0.0))
    assert not values[..., 3].any()
    # N.V plays no part: every row is the same.
    assert (values == values[:1]).all()


def test_evaluate_broadcasts_at_arbitrary_points():
    nl = np.array([-2.0, -0.5, 0.0, 0.25, 1.0, 3.0])[:, None]
    nv = np.linspace(0.0, 1.0, 5)[None, :]
    out = MODEL.evaluate({"colour": (0.2, 0.4, 0.8)}, nl, nv)
    assert out.shape == (6, 5, 4)
    expected = np.array([0.0, 0.0, 0.0, 0.25, 1.0, 3.0])[:, None, None] * np.array([0.2, 0.4, 0.8])
    np.testing.assert_allclose(out[..., :3], np.broadcast_to(expected, (6, 5, 3)))


@pytest.mark.parametrize(
    "body, field, expected",
    [
        ("colour = [1.5, 0, 0]", "colour", "in [0, 1]"),
        ("colour = [nan, 0, 0]", "colour", "finite"),
        ("colour = [0, inf, 0]", "colour", "finite"),
        ("color = [1, 1, 1]", "color", "unknown key (did you mean 'colour'?)"),
    ],
)
def test_bad_parameters_are_rejected(expect_rejected, body, field, expected):
    expect_rejected("lambert", body, field, expected)
