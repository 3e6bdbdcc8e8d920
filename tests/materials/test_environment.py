"""A scene environment's radiance image for each source, and the Mitsuba emitter docs/scenes.md maps it to."""

import doctest

import numpy as np
import pytest

from atlasgen.errors import SceneError
from atlasgen.io.images import write_exr
from atlasgen.materials.environment import Environment, environment_image, mitsuba_emitter, sky_parameters
from atlasgen.optics.equirect import (
    nearest_texel,
    resample_equirect,
    rotation_matrix,
    sample_equirect,
    texel_directions,
    texel_solid_angles,
)
from atlasgen.optics.sky import SkyParameters, sky_image

RNG = np.random.default_rng(9)


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_a_uniform_environment_is_a_constant_image():
    img = environment_image(Environment("uniform", (0.5, 1.0, 2.0), intensity=3.0), 8, 16)
    assert img.dtype == np.float32 and img.shape == (8, 16, 3)
    np.testing.assert_array_equal(img, np.broadcast_to(np.float32([1.5, 3.0, 6.0]), (8, 16, 3)))


def test_a_file_is_read_turned_and_scaled(tmp_path):
    pixels = RNG.random((16, 32, 3)).astype(np.float32)
    write_exr(tmp_path / "e.exr", pixels)
    same = environment_image(Environment("file", file=tmp_path / "e.exr", intensity=2.0), 16, 32)
    np.testing.assert_allclose(same, 2.0 * pixels, rtol=1e-7)
    turned = environment_image(Environment("file", file=tmp_path / "e.exr", rotate=45.0), 16, 32)  # 4 whole columns
    np.testing.assert_allclose(turned, np.roll(pixels, -4, axis=1), rtol=1e-6)
    small = environment_image(Environment("file", file=tmp_path / "e.exr", rotate=10.0, intensity=0.5), 8, 16)
    np.testing.assert_allclose(small, 0.5 * resample_equirect(pixels, 8, 16, 10.0), rtol=1e-6)


def test_a_bad_file_is_a_scene_error_naming_the_scene_its_field_and_the_image(tmp_path):
    """Found by a hostile sweep: the line named the image alone, not the scene that names it, nor the field."""
    write_exr(tmp_path / "wide.exr", np.ones((4, 12, 3), np.float32))
    with pytest.raises(SceneError) as info:
        environment_image(Environment("file", file=tmp_path / "wide.exr", scene="scenes/x.toml"), 8, 16)
    assert str(info.value) == (f"scenes/x.toml: field 'environment': {(tmp_path / 'wide.exr').as_posix()}: expected an "
                               "equirectangular image twice as wide as high, got 12x4")  # fmt: skip


def test_the_sky_turns_its_sun_and_scales():
    sky = SkyParameters(sun_direction=tuple(_unit([0.6, 0.5, 0.0])), sun_irradiance=4.0)
    env = Environment("sky", intensity=2.0, rotate=90.0, sky=sky)
    world_sun = rotation_matrix(90.0) @ np.asarray(sky.sun_direction)
    np.testing.assert_allclose(sky_parameters(env).sun_direction, world_sun, atol=1e-15)
    img = environment_image(env, 32, 64)
    np.testing.assert_allclose(img, 2.0 * sky_image(32, 64, sky_parameters(env)), rtol=1e-6)
    j, i = nearest_texel(world_sun, 32, 64)
    assert img[j, i, 0] == img[..., 0].max()
    # The sun's irradiance scales with the intensity: 2 x 4 W/m^2 on a face towards it.
    disc = img.astype(np.float64) - 2.0 * sky_image(32, 64, SkyParameters(sun_irradiance=0.0)).astype(np.float64)
    irradiance = (
        texel_solid_angles(32, 64)[..., None] * disc * np.maximum(texel_directions(32, 64) @ world_sun, 0.0)[..., None]
    ).sum((0, 1))
    np.testing.assert_allclose(irradiance, 8.0 * np.asarray(sky.sun_colour), rtol=1e-5)


def _sun_peak(intensity: float, irradiance: float) -> float:
    """The peak of the sun's disc alone in a 64x128 sky environment, where its few texels hold tens of
    W/(m^2 sr) for each W/m^2 of sun_irradiance: the sky with it less the sky without."""
    sky = [environment_image(Environment("sky", intensity=intensity, sky=SkyParameters(sun_irradiance=e)), 64, 128)
           for e in (irradiance, 0.0)]  # fmt: skip
    return float((sky[0].astype(np.float64) - sky[1]).max())


def test_a_sun_beyond_float32_at_a_small_intensity_is_the_sky_of_their_product():
    """A sun of 1e38 W/m^2 at intensity 1e-37 (10 W/m^2) was built in float32 first, infinite, and refused."""
    assert _sun_peak(1e-37, 1e38) == pytest.approx(_sun_peak(1.0, 10.0), rel=1e-5)


@pytest.mark.slow
def test_mitsubas_emitters_are_the_same_environment(tmp_path, mitsuba_llvm):
    mi = mitsuba_llvm
    import drjit as dr

    d = _unit(RNG.normal(size=(300, 3)))
    si = dr.zeros(mi.SurfaceInteraction3f, len(d))
    si.wi = mi.Vector3f(*(-d.T))

    def seen(env):
        value = np.array(mi.load_dict(mitsuba_emitter(env, sky_height=32)).eval(si)).reshape(3, -1).T
        return np.broadcast_to(value, (len(d), 3))  # a constant comes back as one value

    uniform = Environment("uniform", (0.5, 1.0, 2.0), intensity=3.0)
    np.testing.assert_allclose(seen(uniform), np.broadcast_to([1.5, 3.0, 6.0], (len(d), 3)), rtol=1e-6)
    pixels = RNG.random((16, 32, 4)).astype(np.float32)  # with alpha, which both ignore
    write_exr(tmp_path / "e.exr", pixels, channel_names=("R", "G", "B", "A"))
    file = Environment("file", file=tmp_path / "e.exr", intensity=1.5, rotate=-37.0)
    expected = 1.5 * sample_equirect(pixels[..., :3].astype(np.float64), d @ rotation_matrix(-37.0))  # L(R^-1 d)
    np.testing.assert_allclose(seen(file), expected, rtol=2e-5, atol=1e-6)
    sky = Environment("sky", intensity=0.5, rotate=20.0, sky=SkyParameters())
    np.testing.assert_allclose(
        seen(sky), sample_equirect(environment_image(sky, 32, 64).astype(np.float64), d), rtol=2e-5, atol=1e-5
    )


def test_the_docstrings_examples_hold():
    from atlasgen.materials import environment

    assert doctest.testmod(environment).failed == 0
