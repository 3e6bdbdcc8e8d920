"""The procedural sky: its gradient's closed forms, the sun's irradiance and position, determinism,
and the figures docs/scenes.md gives for it."""

import doctest
import re
from pathlib import Path

import numpy as np
import pytest

from atlasgen.optics.equirect import nearest_texel, texel_directions, texel_solid_angles
from atlasgen.optics.sky import SkyParameters, sky_image, sun_radius_at

DOCS = Path(__file__).resolve().parents[2] / "docs" / "scenes.md"


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def _no_sun(**kw):
    return SkyParameters(sun_irradiance=0.0, **kw)


def test_the_gradient_has_its_closed_form_means():
    # Over the upper hemisphere sqrt(d.y) has mean 2/3 and int sqrt(y) y dw = 4 pi / 5, so the sky's mean is
    # (horizon + 2 zenith) / 3 and its irradiance on an upward face pi (horizon + 4 zenith) / 5.
    p = _no_sun()
    h, w = 257, 512
    img, d, omega = sky_image(h, w, p).astype(np.float64), texel_directions(h, w), texel_solid_angles(h, w)
    up = (d[..., 1] > 0.0)[..., None]
    hor, zen = np.array(p.horizon), np.array(p.zenith)
    mean = (omega[..., None] * img * up).sum((0, 1)) / (omega[..., None] * up).sum((0, 1))
    # The image samples sqrt(d.y), whose slope is infinite at the horizon: 1% at 257 rows.
    np.testing.assert_allclose(mean, (hor + 2.0 * zen) / 3.0, rtol=1e-2)
    irradiance = (omega[..., None] * img * np.maximum(d[..., 1:2], 0.0)).sum((0, 1))
    np.testing.assert_allclose(irradiance, np.pi * (hor + 4.0 * zen) / 5.0, rtol=1e-2)
    np.testing.assert_allclose(img[-1, 0], p.ground)


@pytest.mark.parametrize("sun", [(0.0, 0.6, 0.8), (0.7, 0.2, -0.3), (-0.2, 0.95, 0.1), (0.5, -0.3, 0.4)])
def test_the_sun_lands_on_its_texel_with_its_irradiance(sun):
    h, w = 64, 128
    p = SkyParameters(sun_direction=tuple(_unit(sun)), sun_irradiance=2.5, sun_colour=(1.0, 0.5, 0.25))
    img = sky_image(h, w, p).astype(np.float64)
    disc = img - sky_image(h, w, _no_sun()).astype(np.float64)
    brightest = np.unravel_index(np.argmax(disc[..., 0]), (h, w))
    j, i = nearest_texel(_unit(sun), h, w)
    assert disc[j, i, 0] == pytest.approx(disc[brightest][0], rel=1e-6)
    d, omega = texel_directions(h, w), texel_solid_angles(h, w)
    irradiance = (omega[..., None] * disc * np.maximum(d @ _unit(sun), 0.0)[..., None]).sum((0, 1))
    np.testing.assert_allclose(irradiance, [2.5, 1.25, 0.625], rtol=1e-5)
    # The disc is centred on the sun: its radiance-weighted mean direction is the sun's.
    centre = _unit((disc[..., :1] * omega[..., None] * d).sum((0, 1)))
    assert np.degrees(np.arccos(min(1.0, centre @ _unit(sun)))) < 0.5


def test_a_sun_smaller_than_a_texel_is_widened_to_one_and_a_half():
    assert sun_radius_at(0.27, 32, 64) == pytest.approx(1.5 * np.pi / 31)  # rows are pi / (H - 1) apart
    assert sun_radius_at(0.27, 129, 256) == pytest.approx(1.5 * 2.0 * np.pi / 256)
    assert sun_radius_at(10.0, 32, 64) == pytest.approx(np.radians(10.0))
    assert np.count_nonzero(sky_image(32, 64, SkyParameters(sun_radius=0.27)) > 5.0) > 0


def test_the_sky_is_deterministic_float32():
    a, b = sky_image(16, 32), sky_image(16, 32)
    assert a.dtype == np.float32 and a.shape == (16, 32, 3)
    np.testing.assert_array_equal(a, b)


def test_docs_give_the_default_skys_measured_figures():
    text = DOCS.read_text(encoding="utf-8")
    p = SkyParameters()
    hor, zen = np.array(p.horizon), np.array(p.zenith)
    mean = ", ".join(f"{x:.2f}" for x in (hor + 2.0 * zen) / 3.0)
    up = ", ".join(f"{x:.2f}" for x in np.pi * (hor + 4.0 * zen) / 5.0)
    assert f"mean radiance ({mean})" in text, mean
    assert f"upward face ({up})" in text, up
    assert re.search(rf"`sun_irradiance`[^\n]*default {p.sun_irradiance:g}\b", text)


def test_the_docstrings_examples_hold():
    from atlasgen.optics import sky

    assert doctest.testmod(sky).failed == 0
