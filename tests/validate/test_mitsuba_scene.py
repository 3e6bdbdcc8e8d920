"""The Mitsuba twin of a renderer scene: units of lights and camera rays, against closed forms."""

from __future__ import annotations

import numpy as np
import pytest

SCENE = """
[camera]
position = [0.3, 2.0, 1.5]
target = [0.0, 0.0, 0.0]
fov = 50.0
[image]
width = 24
height = 18
[[lights]]
type = "directional"
direction = [0.3, -1.0, -0.2]
intensity = 2.0
colour = [1.0, 0.5, 0.25]
[[lights]]
type = "point"
position = [0.4, 0.8, -0.3]
intensity = 3.0
[[objects]]
shape = "plane"
material = "any"
scale = 4.0
"""


def _scene():
    import tomllib

    from atlasgen.materials.scene import parse_scene

    return parse_scene(tomllib.loads(SCENE), "units.toml")


def test_lights_and_camera_match_the_closed_form_radiance_of_a_lambertian_plane(mitsuba_rgb):
    """L = rho / pi * (E_dir * cos_dir + I cos_p / d^2) at the point each pixel-centre ray hits."""
    from atlasgen.render.camera import pixel_rays
    from atlasgen.validate.mitsuba_scene import build_mitsuba_scene, render_mitsuba

    mi = mitsuba_rgb
    scene = _scene()
    rho = np.array([0.7, 0.6, 0.5])
    mi_scene = build_mitsuba_scene(mi, scene, [{"type": "diffuse", "reflectance": {"type": "rgb", "value": rho.tolist()}}])
    image, seconds = render_mitsuba(mi, mi_scene, spp=1)
    assert image.shape == (18, 24, 3) and seconds > 0

    eye = np.array(scene.camera.position)
    rays = pixel_rays(scene.camera, 24, 18)
    t = -eye[1] / rays[..., 1]
    hit = eye + rays * t[..., None]  # on the plane y = 0
    d = np.array([0.3, -1.0, -0.2])
    d /= np.linalg.norm(d)
    e_dir = 2.0 * np.array([1.0, 0.5, 0.25]) * (-d[1])
    to_light = np.array([0.4, 0.8, -0.3]) - hit
    dist2 = (to_light**2).sum(-1)
    e_point = 3.0 * (to_light[..., 1] / np.sqrt(dist2)) / dist2
    expected = rho / np.pi * (e_dir + e_point[..., None])
    on_plane = (np.abs(hit[..., 0]) < 3.9) & (np.abs(hit[..., 2]) < 3.9)
    assert on_plane.mean() > 0.9
    np.testing.assert_allclose(image[on_plane], expected[on_plane], rtol=2e-4)


def test_direct_integrator_has_no_shadows_and_lights_back_faces_through_the_bsdf(mitsuba_rgb):
    """A light below an opaque plane still reaches a BSDF that transmits (no visibility test)."""
    import tomllib

    from atlasgen.io.manifest import MaterialEntry
    from atlasgen.materials.scene import parse_scene
    from atlasgen.validate.mitsuba_scene import build_mitsuba_scene, render_mitsuba
    from atlasgen.validate.references import model_reference, register_references

    mi = mitsuba_rgb
    register_references(mi)
    text = SCENE.replace("direction = [0.3, -1.0, -0.2]", "direction = [0.0, 1.0, 0.0]").replace(
        "intensity = 3.0", "intensity = 0.0"
    )
    scene = parse_scene(tomllib.loads(text), "below.toml")
    leaf = MaterialEntry(name="leaf", id=0, constant="MATERIAL_LEAF", first_slice=0, type="backlit", params={
        "colour": [0.0, 0.0, 0.0], "transmission_colour": [1.0, 1.0, 1.0], "distortion": 0.0, "power": 1.0,
        "scale": 0.0, "ambient": 1.0, "view": "average", "specular": 0.0})  # fmt: skip
    mi_scene = build_mitsuba_scene(mi, scene, [model_reference(leaf).bsdf])
    image, _ = render_mitsuba(mi, mi_scene)
    # backlit with ambient = 1 and nothing else: RGB = transmission_colour for every N.L, so
    # L = albedo (1) * 1 / pi * E, with E = 2 * colour: light from below, through the plane.
    expected = 2.0 * np.array([1.0, 0.5, 0.25]) / np.pi
    np.testing.assert_allclose(image[9, 12], expected, rtol=1e-5)


def test_stochastic_references_trace_every_sample_through_the_pixel_centre(mitsuba_rgb):
    """render_pixel_centres with the independent sampler gives the pixel-centre image (what the
    rasteriser shades) of a deterministic scene exactly, silhouette pixels included, where
    mi.render's samples spread over each pixel and antialias the sphere's edge."""
    import tomllib

    from atlasgen.materials.scene import parse_scene
    from atlasgen.validate.mitsuba_scene import build_mitsuba_scene, render_mitsuba, render_pixel_centres

    mi = mitsuba_rgb
    text = SCENE.replace('shape = "plane"', 'shape = "sphere"').replace("scale = 4.0", "scale = 0.6")
    scene = parse_scene(tomllib.loads(text), "sphere.toml")
    diffuse = [{"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.7, 0.6, 0.5]}}]
    centres, _ = render_mitsuba(mi, build_mitsuba_scene(mi, scene, diffuse, spp=1))
    stochastic = build_mitsuba_scene(mi, scene, diffuse, spp=16, stochastic=True)
    mine, seconds = render_pixel_centres(mi, stochastic, 16, seed=3)
    assert mine.shape == centres.shape and seconds > 0
    np.testing.assert_allclose(mine, centres, rtol=1e-5, atol=1e-6)
    footprint, _ = render_mitsuba(mi, stochastic, 16)
    edge = np.abs(footprint - centres).max(-1) > 0.05
    assert edge.sum() >= 10  # the antialiased silhouette


@pytest.mark.slow
def test_a_render_continued_from_sample_n_averages_to_the_longer_render(mitsuba_rgb):
    """Samples [0, 64) and [64, 192), weighted 64 : 128, are the render of samples [0, 192):
    a reference that needs more samples continues its render instead of starting again."""
    import tomllib

    from atlasgen.materials.scene import parse_scene
    from atlasgen.validate.mitsuba_scene import build_mitsuba_scene, render_pixel_centres

    mi = mitsuba_rgb
    sphere = SCENE.replace("scale = 4.0", 'scale = 4.0\n[[objects]]\nshape = "sphere"\nmaterial = "any"\nscale = 0.5')
    scene = parse_scene(tomllib.loads(sphere), "two.toml")
    diffuse = [{"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.7, 0.6, 0.5]}}] * 2
    # Path tracing with a bounce: the plane lights the sphere by inter-reflection, so every
    # sample is random and a repeated or skipped sample would show.
    mi_scene = build_mitsuba_scene(mi, scene, diffuse, spp=64, integrator={"type": "path", "max_depth": 3}, stochastic=True)
    whole, _ = render_pixel_centres(mi, mi_scene, 192, seed=2)
    first, _ = render_pixel_centres(mi, mi_scene, 64, seed=2)
    rest, _ = render_pixel_centres(mi, mi_scene, 128, seed=2, first_sample=64)
    np.testing.assert_allclose((64 * first + 128 * rest) / 192, whole, rtol=1e-5, atol=1e-6)
    assert np.abs(first - rest).max() > 1e-3  # the two parts are different samples
    again, _ = render_pixel_centres(mi, mi_scene, 128, seed=2, first_sample=0)
    assert np.abs(again - rest).max() > 1e-3  # numbering matters


RANGED = """
[camera]
position = [0.3, 2.0, 1.5]
target = [0.0, 0.0, 0.0]
fov = 70.0
[image]
width = 32
height = 24
[[lights]]
type = "point"
position = [0.4, 0.5, -0.3]
intensity = 3.0
range = 1.2
[[lights]]
type = "spot"
position = [-0.5, 1.0, 0.2]
direction = [0.2, -1.0, 0.1]
intensity = 2.0
inner_angle = 15.0
outer_angle = 35.0
range = 2.5
[[objects]]
shape = "plane"
material = "any"
scale = 4.0
"""


def test_ranged_point_and_spot_lights_fall_off_as_the_renderer_in_the_reference(mitsuba_rgb):
    """atlasgen_direct windows each ranged emitter, and Mitsuba's spot is the renderer's cone:
    L = rho / pi * sum I W(d, r) S cos / d^2 (atlasgen.optics.falloff), 0 beyond each range."""
    import tomllib

    from atlasgen.materials.scene import parse_scene
    from atlasgen.optics.falloff import range_window, spot_factor
    from atlasgen.render.camera import pixel_rays
    from atlasgen.validate.mitsuba_scene import build_mitsuba_scene, render_mitsuba

    mi = mitsuba_rgb
    scene = parse_scene(tomllib.loads(RANGED), "ranged.toml")
    rho = np.array([0.7, 0.6, 0.5])
    mi_scene = build_mitsuba_scene(mi, scene, [{"type": "diffuse", "reflectance": {"type": "rgb", "value": rho.tolist()}}])
    image, _ = render_mitsuba(mi, mi_scene, spp=1)

    eye = np.array(scene.camera.position)
    rays = pixel_rays(scene.camera, 32, 24)
    hit = eye + rays * (-eye[1] / rays[..., 1])[..., None]
    irradiance = np.zeros(hit.shape[:2])
    for light in scene.lights:
        to_light = np.array(light.position) - hit
        dist = np.linalg.norm(to_light, axis=-1)
        scale = range_window(dist, light.range)
        if light.type == "spot":
            scale = scale * spot_factor(-(to_light / dist[..., None]) @ np.array(light.direction), light.inner_angle,
                                        light.outer_angle)  # fmt: skip
        irradiance += light.intensity * scale * (to_light[..., 1] / dist) / dist**2
    expected = rho / np.pi * irradiance[..., None]
    on_plane = (np.abs(hit[..., 0]) < 3.9) & (np.abs(hit[..., 2]) < 3.9)
    dark = on_plane & (irradiance == 0)
    assert dark.mean() > 0.2 and (on_plane & (irradiance > 0)).mean() > 0.2  # both sides of the ranges in view
    np.testing.assert_allclose(image[on_plane], expected[on_plane], rtol=2e-4, atol=1e-7)
    assert (image[dark] == 0).all()


def test_an_integrator_that_cannot_window_a_range_is_refused(mitsuba_rgb):
    import tomllib

    from atlasgen.errors import SceneError
    from atlasgen.materials.scene import parse_scene
    from atlasgen.validate.mitsuba_scene import build_mitsuba_scene

    scene = parse_scene(tomllib.loads(RANGED), "ranged.toml")
    with pytest.raises(SceneError, match=r"ranged.toml: field 'lights\[0\].range': the 'path' reference cannot apply"):
        build_mitsuba_scene(mitsuba_rgb, scene, [{"type": "diffuse"}], integrator={"type": "path"})


UNIFORM = """
environment = [0.6, 0.7, 0.8]
[camera]
position = [0.0, 0.35, 3.0]
target = [0.0, 0.0, 0.0]
fov = 26.0
[image]
width = 16
height = 16
[[objects]]
shape = "sphere"
material = "any"
scale = 0.6
"""


@pytest.mark.slow
def test_a_uniform_environment_reference_samples_the_bsdf_on_quasi_random_points(mitsuba_rgb):
    """Under a constant emitter alone, render_environment_qmc gives a diffuse sphere rho L exactly (cosine
    sampling is the BSDF's own), and a glossy one to far less error than atlasgen_direct's emitter MIS at
    the same samples: the two seeds' difference is the estimate's error, and both agree on the mean."""
    import tomllib

    from atlasgen.materials.scene import parse_scene
    from atlasgen.validate.mitsuba_scene import build_mitsuba_scene, render_environment_qmc, render_pixel_centres

    mi = mitsuba_rgb
    scene = parse_scene(tomllib.loads(UNIFORM), "uniform.toml")
    rho, radiance = np.array([0.7, 0.6, 0.5]), np.array([0.6, 0.7, 0.8])
    diffuse = build_mitsuba_scene(mi, scene, [{"type": "diffuse", "reflectance": {"type": "rgb", "value": rho.tolist()}}],
                                  stochastic=True)  # fmt: skip
    image, _ = render_environment_qmc(mi, diffuse, 16, seed=0)
    hit = image.max(-1) > 0
    assert hit.mean() > 0.3
    np.testing.assert_allclose(image[hit], np.broadcast_to(rho * radiance, image[hit].shape), rtol=1e-5)

    glossy = [{"type": "roughplastic", "distribution": "ggx", "alpha": 0.08,
               "diffuse_reflectance": {"type": "rgb", "value": [0.3, 0.05, 0.05]}}]  # fmt: skip
    mi_scene = build_mitsuba_scene(mi, scene, glossy, stochastic=True)
    qmc = [render_environment_qmc(mi, mi_scene, 256, seed=s)[0][hit] for s in (0, 1)]
    mc = [render_pixel_centres(mi, mi_scene, 256, seed=s)[0][hit] for s in (0, 1)]
    qmc_error, mc_error = (np.sqrt(np.mean((a - b) ** 2)) for a, b in (qmc, mc))
    assert 0.0 < qmc_error < mc_error / 10
    # The same integral: the two means agree within the Monte Carlo estimate's own noise.
    assert np.sqrt(np.mean((0.5 * (qmc[0] + qmc[1]) - 0.5 * (mc[0] + mc[1])) ** 2)) < mc_error
    # A scene with lights besides its environment is refused: the lights are atlasgen_direct's.
    light = '[[lights]]\ntype = "directional"\ndirection = [0.0, -1.0, 0.0]\nintensity = 1.0\n'
    lit = parse_scene(tomllib.loads(UNIFORM + light), "lit.toml")
    with pytest.raises(ValueError, match="only emitter"):
        render_environment_qmc(mi, build_mitsuba_scene(mi, lit, glossy, stochastic=True), 4)
