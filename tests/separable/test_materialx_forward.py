"""The MaterialX forward render against closed forms and against the oracle at the same (n, l, v).

A Lambertian standard_surface (base 1, specular 0) must give E cos / pi per pixel under a
directional light and I W(d, r) cos / (pi d^2) under a ranged point light (atlasgen's falloff,
not MaterialX's (d + 1)^-2); a gold must give, pixel by pixel, the oracle's f cos at the pixel's
own (n, l, v) summed over the lights. Every test checks that OpenGL reported no error.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("MaterialX")
pytest.importorskip("moderngl")

pytestmark = pytest.mark.slow  # compiling a surface model's program costs seconds of CPU on a cold shader cache

from atlasgen.errors import BackendError  # noqa: E402
from atlasgen.materials.scene import Camera, Light  # noqa: E402
from atlasgen.optics.falloff import spot_factor, windowed_irradiance  # noqa: E402
from atlasgen.render.camera import pixel_rays  # noqa: E402
from atlasgen.render.meshes import make_plane, make_sphere  # noqa: E402
from atlasgen.separable.materialx_forward import (  # noqa: E402
    ForwardDraw,
    adapt_forward_pixel_stage,
    render_materialx_forward,
    vertex_tangents,
)
from atlasgen.separable.materialx_oracle import evaluate_materialx_f_cos, generate_surface_stages  # noqa: E402
from atlasgen.validate.materialx_reference import gl_view_projection  # noqa: E402

LAMBERT = {"base": 1.0, "base_color": (1.0, 1.0, 1.0), "specular": 0.0}
GOLD = {"base": 1.0, "base_color": (0.944, 0.776, 0.373), "metalness": 1.0, "specular_color": (0.998, 0.981, 0.751),
        "specular_roughness": 0.25}  # fmt: skip
CAMERA = Camera(position=(0.0, 1.15, 3.2), target=(0.0, 0.42, 0.0), fov=34.0)
SIZE = (48, 36)


@pytest.fixture(scope="module")
def gl():
    """The oracle's EGL context; skips where there is none (no libEGL, no Mesa)."""
    from atlasgen.separable.materialx_oracle import gl_context

    try:
        return gl_context()
    except BackendError as exc:
        pytest.skip(str(exc))


def _draw(mesh, scale=1.0, offset=(0.0, 0.0, 0.0), albedo=(1.0, 1.0, 1.0)) -> ForwardDraw:
    positions = mesh.positions.astype(np.float64) * scale + np.asarray(offset)
    return ForwardDraw(positions, mesh.normals, vertex_tangents(mesh.normals), mesh.indices, albedo)


def _render(gl, inputs, draws, lights, category="standard_surface", camera=CAMERA, size=SIZE):
    image = render_materialx_forward(category, inputs, draws, gl_view_projection(camera, *size), camera.position, lights, *size)
    assert gl.error == "GL_NO_ERROR"
    return image


def _scene():
    return [_draw(make_plane(), 1.6), _draw(make_sphere(48), 0.5, (0.0, 0.5, 0.0), albedo=(1.0, 0.7, 0.4))]


def _unit(x):
    x = np.asarray(x, dtype=np.float64)
    return x / np.linalg.norm(x)


def test_lambert_under_a_directional_light_is_e_cos_over_pi(gl):
    d = _unit([0.55, -0.35, -0.75])
    image = _render(gl, LAMBERT, [_draw(make_plane(), 1.6)], [Light("directional", (1.0, 0.9, 0.5), 0.8, direction=tuple(d))])
    covered = image.covered
    assert covered.mean() > 0.3  # the plane fills a good part of the frame
    want = 0.8 * np.array([1.0, 0.9, 0.5]) * -d[1] / np.pi
    np.testing.assert_allclose(image.radiance[covered], np.broadcast_to(want, (covered.sum(), 3)), rtol=1e-5, atol=1e-7)
    assert np.all(image.radiance[~covered] == 0.0)
    np.testing.assert_allclose(image.normal[covered], np.broadcast_to([0.0, 1.0, 0.0], (covered.sum(), 3)), atol=1e-6)


def test_a_sphere_pixel_is_e_cos_over_pi_at_its_shaded_normal_times_the_albedo(gl):
    d = _unit([0.3, -0.6, -0.7])
    image = _render(gl, LAMBERT, _scene(), [Light("directional", (1.0, 1.0, 1.0), 1.3, direction=tuple(d))])
    n = image.normal[image.covered].astype(np.float64)
    albedo = np.where(image.position[image.covered][:, 1:2] > 1e-4, [1.0, 0.7, 0.4], [1.0, 1.0, 1.0])
    want = (1.3 * np.clip(n @ -d, 0.0, None) / np.pi)[:, None] * albedo
    np.testing.assert_allclose(image.radiance[image.covered], want, rtol=1e-5, atol=2e-7)


def test_the_pixels_are_the_renderers_pixel_centres(gl):
    """The shaded position lies on the camera ray through the pixel's centre (atlasgen.render.camera.pixel_rays)."""
    image = _render(gl, LAMBERT, _scene(), [Light("directional", (1.0, 1.0, 1.0), 1.0, direction=(0.0, -1.0, 0.0))])
    rays = pixel_rays(CAMERA, *SIZE)[image.covered]
    to_point = image.position[image.covered] - np.asarray(CAMERA.position)
    cosine = np.sum(rays * to_point, -1) / (np.linalg.norm(rays, axis=-1) * np.linalg.norm(to_point, axis=-1))
    assert np.all(cosine > 1.0 - 2e-6)


def test_a_ranged_point_light_falls_off_as_inverse_square_times_the_window(gl):
    """atlasgen's falloff, I W(d, r) / d^2 (MaterialX's own point light divides by (d + 1)^2)."""
    position, intensity, light_range = np.array([0.4, 1.0, 0.6]), 3.0, 2.0
    light = Light("point", (1.0, 1.0, 1.0), intensity, position=tuple(position), range=light_range)
    image = _render(gl, LAMBERT, [_draw(make_plane(), 1.6)], [light])
    x = image.position[image.covered].astype(np.float64)
    to_light = position - x
    d = np.linalg.norm(to_light, axis=-1)
    want = windowed_irradiance(intensity, d, light_range) * np.clip(to_light[:, 1] / d, 0.0, None) / np.pi
    assert (want == 0.0).any() and (want > 0.0).any()  # the window's edge crosses the plane
    np.testing.assert_allclose(image.radiance[image.covered], np.repeat(want[:, None], 3, 1), rtol=2e-5, atol=1e-6)


def test_a_ranged_point_light_a_ten_millionth_the_size_is_lit_the_same(gl):
    """The test above's scene at 1e-7 of its size (camera, plane, light position and range), its intensity at 1e-14:
    the same image. A floor of 1e-12 on d^2, in the window and the direction too, left such a light dark."""
    k = 1e-7
    position, light_range = np.array([0.4, 1.0, 0.6]), 2.0

    def image(scale):
        camera = Camera(position=tuple(np.multiply(CAMERA.position, scale)), target=tuple(np.multiply(CAMERA.target, scale)),
                        fov=CAMERA.fov, near=CAMERA.near * scale, far=10.0 * scale)  # fmt: skip
        light = Light("point", (1.0, 1.0, 1.0), 3.0 * scale * scale, position=tuple(position * scale),
                      range=light_range * scale)  # fmt: skip
        return _render(gl, LAMBERT, [_draw(make_plane(), 1.6 * scale)], [light], camera=camera)

    big, small = image(1.0), image(k)
    assert (big.radiance[big.covered] > 0).mean() > 0.2
    np.testing.assert_array_equal(small.covered, big.covered)
    np.testing.assert_allclose(small.radiance, big.radiance, rtol=1e-3, atol=1e-6)


def test_a_point_light_without_a_range_is_the_plain_inverse_square(gl):
    position = np.array([1.6, 2.4, 2.6])
    image = _render(gl, LAMBERT, [_draw(make_plane(), 1.6)], [Light("point", (1.0, 1.0, 1.0), 13.0, position=tuple(position))])
    x = image.position[image.covered].astype(np.float64)
    to_light = position - x
    d2 = np.sum(to_light**2, -1)
    want = 13.0 / d2 * to_light[:, 1] / np.sqrt(d2) / np.pi
    np.testing.assert_allclose(image.radiance[image.covered][:, 0], want, rtol=1e-5)


def _local(n):
    """Rows of a tangent frame (t, b, n) per normal: world directions to the oracle's frame (n = +z)."""
    t = np.cross(np.where(np.abs(n[:, 1:2]) > 0.99, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]), n)
    t /= np.linalg.norm(t, axis=-1, keepdims=True)
    b = np.cross(n, t)
    return lambda w: np.stack([np.sum(w * t, -1), np.sum(w * b, -1), np.sum(w * n, -1)], -1)


def test_the_forward_render_equals_the_oracle_at_each_pixels_n_l_v(gl):
    """Gold under a point and a directional light: per pixel, sum over the lights of E albedo f cos(l, v)
    from the oracle, with l, v in the frame of the pixel's shaded normal."""
    d = _unit([0.55, -0.35, -0.75])
    point = np.array([1.6, 2.4, 2.6])
    lights = [Light("point", (1.0, 1.0, 1.0), 13.0, position=tuple(point)),
              Light("directional", (0.9, 0.95, 1.0), 0.8, direction=tuple(d))]  # fmt: skip
    image = _render(gl, GOLD, _scene(), lights)
    covered = image.covered
    n = image.normal[covered].astype(np.float64)
    x = image.position[covered].astype(np.float64)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    to_local = _local(n)
    v = np.asarray(CAMERA.position) - x
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    to_light = point - x
    d2 = np.sum(to_light**2, -1, keepdims=True)
    want = 13.0 / d2 * evaluate_materialx_f_cos("standard_surface", GOLD, to_local(to_light / np.sqrt(d2)), to_local(v))
    want += (
        0.8
        * np.array([0.9, 0.95, 1.0])
        * evaluate_materialx_f_cos("standard_surface", GOLD, to_local(np.broadcast_to(-d, n.shape)), to_local(v))
    )
    want *= np.where(x[:, 1:2] > 1e-4, [1.0, 0.7, 0.4], [1.0, 1.0, 1.0])
    assert want.max() > 1.0  # the highlights are in the frame
    np.testing.assert_allclose(image.radiance[covered], want, rtol=2e-4, atol=2e-6 * want.max())


def test_a_back_face_is_shaded_with_the_flipped_normal_as_the_renderer_does(gl):
    below = Camera(position=(0.0, -2.0, 2.5), target=(0.0, 0.0, 0.0), fov=40.0)
    up = Light("directional", (1.0, 1.0, 1.0), 1.0, direction=(0.0, 1.0, 0.0))  # travelling up: lights the underside
    image = _render(gl, LAMBERT, [_draw(make_plane(), 1.6)], [up], camera=below)
    covered = image.covered
    assert covered.mean() > 0.2
    np.testing.assert_allclose(image.radiance[covered], 1.0 / np.pi, rtol=1e-5)
    np.testing.assert_allclose(image.normal[covered], np.broadcast_to([0.0, -1.0, 0.0], (covered.sum(), 3)), atol=1e-6)


def test_an_object_of_another_material_occludes_and_stays_black(gl):
    d = (0.0, -1.0, 0.0)
    light = [Light("directional", (1.0, 1.0, 1.0), 1.0, direction=d)]
    alone = _render(gl, LAMBERT, [_draw(make_plane(), 1.6)], light)
    blocker = _draw(make_sphere(32), 0.5, (0.0, 0.5, 0.0), albedo=(0.0, 0.0, 0.0))
    both = _render(gl, LAMBERT, [_draw(make_plane(), 1.6), blocker], light)
    hidden = alone.covered & (both.position[..., 1] > 1e-4)
    assert hidden.sum() > 20
    assert np.all(both.radiance[hidden] == 0.0)
    shown = both.covered & (both.position[..., 1] <= 1e-4)
    np.testing.assert_array_equal(both.radiance[shown], alone.radiance[shown])


def test_inputs_are_reset_between_renders(gl):
    light = [Light("directional", (1.0, 1.0, 1.0), 1.0, direction=(0.0, -1.0, 0.0))]
    first = _render(gl, LAMBERT, _scene(), light).radiance
    _render(gl, GOLD, _scene(), light)
    np.testing.assert_array_equal(_render(gl, LAMBERT, _scene(), light).radiance, first)


def test_a_spot_light_is_the_point_falloff_times_atlasgens_cone(gl):
    """Mitsuba's spot, as atlasgen's renderer: linear in the angle from the inner to the outer cone."""
    position, axis = np.array([0.3, 1.5, 0.2]), _unit([0.2, -1.0, 0.1])
    light = Light("spot", (1.0, 0.8, 0.6), 4.0, position=tuple(position), direction=tuple(axis), range=3.0,
                         inner_angle=15.0, outer_angle=35.0)  # fmt: skip
    image = _render(gl, LAMBERT, [_draw(make_plane(), 1.6)], [light])
    x = image.position[image.covered].astype(np.float64)
    to_light = position - x
    d = np.linalg.norm(to_light, axis=-1)
    l = to_light / d[:, None]
    cone = spot_factor(-(l @ axis), 15.0, 35.0)
    assert (cone == 0.0).any() and (cone == 1.0).any() and ((cone > 0.05) & (cone < 0.95)).any()
    lit = (windowed_irradiance(4.0, d, 3.0) * np.clip(l[:, 1], 0.0, None) / np.pi)[:, None] * [1.0, 0.8, 0.6]
    got = image.radiance[image.covered]
    np.testing.assert_allclose(got[cone == 1.0], lit[cone == 1.0], rtol=1e-5)
    assert np.all(got[cone == 0.0] == 0.0)
    # In the cone's ramp the shader's float32 acos (llvmpipe's, as the renderer's) sets the precision.
    ramp = (cone > 0.0) & (cone < 1.0) & (lit[:, 0] > 1e-3)
    np.testing.assert_allclose(got[ramp, 0] / lit[ramp, 0], cone[ramp], atol=2e-4)


def test_a_light_it_cannot_bind_is_refused(gl):
    area = Light("area", (1.0, 1.0, 1.0), 1.0, position=(0.0, 2.0, 0.0), direction=(0.0, -1.0, 0.0))
    with pytest.raises(BackendError, match="no 'area' light; expected one of directional, point, spot"):
        _render(gl, LAMBERT, _scene(), [area])
    assert gl.error == "GL_NO_ERROR"


def test_the_pixel_stage_keeps_materialx_bsdf_code_and_replaces_only_the_lights_falloff():
    _, pixel = generate_surface_stages("standard_surface", (("directional_light", 1), ("point_light", 2), ("spot_light", 3)), 4)
    adapted = adapt_forward_pixel_stage(pixel)
    assert "pow(distance + 1.0, light.decay_rate" in pixel and "decay_rate + M_FLOAT_EPS" not in adapted
    assert "smoothstep(low, high, cosDir)" in pixel and "smoothstep(low, high, cosDir)" not in adapted
    assert "struct LightData\n{\n    float range;" in adapted and "gl_FrontFacing" in adapted
    bsdf = pixel[pixel.index("void mx_roughness_anisotropy") : pixel.index("\nvoid main()")]
    assert bsdf in adapted  # every function after the lights, verbatim
