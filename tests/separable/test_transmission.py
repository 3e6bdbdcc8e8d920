"""The transmission slice (atlasgen.separable.transmission): a separable BRDF's light from below as one table slice."""

import numpy as np

from atlasgen.contract import texel_grid
from atlasgen.optics.interpolation import sample_slice
from atlasgen.separable.transmission import encode_transmission_slice, transmission_slice


def _diffuse_through(l, v):
    """A diffuse transmission seen through a film: c |N.L| (1 - N.V^2) / pi below the surface, 0 above."""
    colour = np.array([0.2, 0.5, 0.9])
    return np.where((l[:, 2] < 0.0)[:, None], colour * (-l[:, 2] * (1.0 - v[:, 2] ** 2) / np.pi)[:, None], 0.0)


def test_a_function_of_nl_and_nv_is_held_exactly_at_the_texel_centres():
    got = transmission_slice(_diffuse_through)
    nl, nv = texel_grid()
    expected = np.array([0.2, 0.5, 0.9]) * (np.maximum(-nl, 0.0) * (1.0 - nv**2))[..., None]
    np.testing.assert_allclose(got[..., :3], expected, rtol=1e-12, atol=1e-15)
    assert (got[nl > 0.0] == 0.0).all() and (got[..., 3] == 0.0).all()


def test_an_azimuth_dependent_function_becomes_its_mean_over_the_azimuth():
    """f cos = |N.L| (1 + cos phi): the mean of cos over the slice's azimuths (midpoints of [0, pi]) is 0,
    so the slice holds |N.L|; a slice that read one azimuth would hold 0 or 2 |N.L|."""

    def lobe(l, v):
        tl = l[:, :2] / np.maximum(np.linalg.norm(l[:, :2], axis=1, keepdims=True), 1e-300)
        tv = v[:, :2] / np.maximum(np.linalg.norm(v[:, :2], axis=1, keepdims=True), 1e-300)
        cos_phi = np.sum(tl * tv, axis=1)
        return np.repeat((-l[:, 2] * (1.0 + cos_phi))[:, None], 3, axis=1) * (l[:, 2] < 0.0)[:, None]

    got = transmission_slice(lobe)
    nl, nv = texel_grid()
    inside = (nl < 0.0) & (nv < 1.0)  # at N.V = 1 the azimuth is undefined (taken as 0)
    np.testing.assert_allclose(got[inside, 0], np.pi * -nl[inside], rtol=1e-12)


def test_encoding_spends_every_code_on_a_faint_slice_and_round_trips():
    values = 0.01 * transmission_slice(_diffuse_through)
    stored, scale = encode_transmission_slice(values)
    assert scale == np.float32(scale) and abs(scale - values[..., :3].max()) <= 1e-7 * scale  # float32 rounding
    assert stored[..., :3].max() > 1.0 - 1e-6 and stored.min() >= 0.0 and (stored[..., 3] == 0.0).all()
    np.testing.assert_allclose(stored[..., :3] * scale, values[..., :3], rtol=1e-6, atol=1e-12)
    codes = np.unique(np.round(stored[..., :3] * 255.0))
    assert codes.size > 200  # a max(1, peak) scale would leave this slice 3 codes
    empty, one = encode_transmission_slice(np.zeros_like(values))
    assert one == 1.0 and (empty == 0.0).all()


def test_bilinear_lookup_between_texel_centres_follows_a_linear_function():
    """The rebuild reads the slice as atlas_sample does; a function linear in N.L below the surface
    comes back exactly between the texel centres there."""
    table = transmission_slice(lambda l, v: np.repeat(np.maximum(-l[:, 2], 0.0)[:, None], 3, axis=1) / np.pi)
    nl = np.linspace(-1.0, -2.0 / 63.0, 50)
    got = sample_slice(table[..., :3], nl, np.full_like(nl, 0.37))
    np.testing.assert_allclose(got[:, 1], -nl, rtol=1e-12)
