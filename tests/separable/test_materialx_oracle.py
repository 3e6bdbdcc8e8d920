"""The MaterialX oracle against closed forms: a Lambertian standard_surface and a standard_surface metal.

The metal's reference is an independent NumPy GGX: Gulbrandsen's artistic IOR, the exact
conductor Fresnel in complex arithmetic (Born & Wolf), Walter's D, Heitz's height-correlated G2,
and Turquin's energy compensation with MaterialX's rational fit of the GGX directional albedo
(pbrlib/genglsl/lib/mx_microfacet_specular.glsl, ``mx_ggx_dir_albedo_analytic``).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("MaterialX")
pytest.importorskip("moderngl")

pytestmark = pytest.mark.slow  # compiling a surface model's program costs seconds of CPU

from atlasgen.separable.materialx_oracle import (  # noqa: E402
    SURFACE_MODELS,
    adapt_pixel_stage,
    evaluate_materialx_f_cos,
    materialx_oracle,
    varyings_of,
)


@pytest.fixture(autouse=True)
def _no_gl_error():
    """Every test leaves OpenGL without an error (one left behind would go unseen by the next caller)."""
    yield
    from atlasgen.errors import BackendError
    from atlasgen.separable.materialx_oracle import gl_context

    try:
        context = gl_context()
    except BackendError:
        return
    assert context.error == "GL_NO_ERROR"


def _directions(rng, n):
    z = rng.random(n)
    phi = 2.0 * np.pi * rng.random(n)
    s = np.sqrt(1.0 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], -1)


def test_lambert_is_cos_over_pi():
    rng = np.random.default_rng(1)
    l, v = _directions(rng, 4096), _directions(rng, 4096)
    got = evaluate_materialx_f_cos("standard_surface", {"base": 1.0, "base_color": (1.0, 1.0, 1.0), "specular": 0.0}, l, v)
    np.testing.assert_allclose(got, np.repeat(l[:, 2:3] / np.pi, 3, 1), rtol=0, atol=1e-6)


def test_light_below_the_horizon_gives_nothing():
    rng = np.random.default_rng(2)
    l, v = _directions(rng, 256), _directions(rng, 256)
    l[:, 2] *= -1.0
    got = evaluate_materialx_f_cos("standard_surface", {"base": 1.0, "specular": 1.0}, l, v)
    assert np.abs(got).max() < 1e-7


def _artistic_ior(r, g):
    """Gulbrandsen 2014 (JCGT 3(4)), eqs. as MaterialX's mx_artistic_ior."""
    r = np.clip(r, 0.0, 0.99)
    n = g * (1.0 - r) / (1.0 + r) + (1.0 - g) * (1.0 + np.sqrt(r)) / (1.0 - np.sqrt(r))
    k = np.sqrt(np.maximum(((n + 1.0) ** 2 * r - (n - 1.0) ** 2) / (1.0 - r), 0.0))
    return n, k


def _fresnel_conductor(cos_i, n, k):
    """Unpolarised reflectance of a conductor n + ik from air, from Snell's law in complex numbers."""
    eta = n + 1j * k
    cos_i = cos_i[:, None]
    sin_t2 = (1.0 - cos_i**2) / eta**2
    cos_t = np.sqrt(1.0 - sin_t2)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)


def _dir_albedo(nv, a):
    """MaterialX's rational fit of the GGX directional albedo with F0 = F90 = 1 (the A + B of its AB)."""
    x, y = nv, a
    c = np.array([[0.1003, 0.9345, 1.0, 1.0], [-0.6303, -2.323, -1.765, 0.2281], [9.748, 2.229, 8.263, 15.94],
                  [-2.038, -3.748, 11.53, -55.83], [29.34, 1.424, 28.96, 13.08], [-8.245, -0.7684, -7.507, 41.26],
                  [-26.44, 1.436, -36.11, 54.9], [19.99, 0.2913, 15.86, 300.2], [-5.448, 0.6286, 33.37, -285.1]])  # fmt: skip
    basis = np.stack([np.ones_like(x), x, y * np.ones_like(x), x * y, x * x, y * y * np.ones_like(x), x * x * y, x * y * y,
                      x * x * y * y], -1)  # fmt: skip
    r = basis @ c
    return np.clip(r[:, 0] / r[:, 2], 0, 1) + np.clip(r[:, 1] / r[:, 3], 0, 1)


def _ggx_metal_f_cos(l, v, colour, edge, roughness):
    n, k = _artistic_ior(np.asarray(colour), np.asarray(edge))
    a = max(roughness * roughness, 1e-8)
    nl, nv = np.clip(l[:, 2], 1e-8, 1), np.clip(v[:, 2], 1e-8, 1)
    h = (l + v) / np.linalg.norm(l + v, axis=-1, keepdims=True)
    nh, vh = h[:, 2], np.clip(np.sum(v * h, -1), 1e-8, 1)
    d = a * a / (np.pi * (nh * nh * (a * a - 1.0) + 1.0) ** 2)
    g2 = 2.0 * nl * nv / (nv * np.sqrt(a * a + (1 - a * a) * nl**2) + nl * np.sqrt(a * a + (1 - a * a) * nv**2))
    f = _fresnel_conductor(vh, n, k)
    ess = _dir_albedo(nv, a)
    comp = 1.0 + f * ((1.0 - ess) / ess)[:, None]
    return (d * g2 / (4.0 * nv))[:, None] * f * comp


@pytest.mark.parametrize("roughness", [0.25, 0.6])
def test_metal_matches_an_independent_ggx(roughness):
    rng = np.random.default_rng(3)
    l, v = _directions(rng, 8192), _directions(rng, 8192)
    keep = (l[:, 2] > 0.05) & (v[:, 2] > 0.05)
    l, v = l[keep], v[keep]
    gold, edge = (0.944, 0.776, 0.373), (0.998, 0.981, 0.751)
    inputs = {"base": 1.0, "base_color": gold, "metalness": 1.0, "specular": 1.0, "specular_color": edge,
              "specular_roughness": roughness}  # fmt: skip
    got = evaluate_materialx_f_cos("standard_surface", inputs, l, v)
    want = _ggx_metal_f_cos(l, v, gold, edge, roughness)
    # float32 on the GPU path against float64: 1e-4 relative, 1e-6 absolute where the lobe is dark
    np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-6)


def test_inputs_reset_between_materials():
    """One program serves every material of a surface model: an input set for one material must not leak."""
    rng = np.random.default_rng(4)
    l, v = _directions(rng, 512), _directions(rng, 512)
    plain = evaluate_materialx_f_cos("standard_surface", {}, l, v)
    evaluate_materialx_f_cos("standard_surface", {"coat": 1.0, "metalness": 1.0}, l, v)
    np.testing.assert_array_equal(evaluate_materialx_f_cos("standard_surface", {}, l, v), plain)


@pytest.mark.parametrize("category", SURFACE_MODELS)
def test_every_surface_model_compiles_and_reflects(category):
    oracle = materialx_oracle(category)
    assert ("vec3", "normalWorld") in varyings_of(_source(category))
    rng = np.random.default_rng(5)
    l, v = _directions(rng, 1024), _directions(rng, 1024)
    got = oracle.f_cos({}, l, v)
    assert np.isfinite(got).all() and got.min() >= 0.0 and got.mean() > 0.01


def _source(category):
    from atlasgen.separable.materialx_oracle import _generate

    return _generate(category)


def test_adapted_stage_declares_the_missing_uniform():
    src = adapt_pixel_stage(_source("standard_surface"))
    assert "uniform bool u_refractionTwoSided = false;" in src
    assert "uniform LightData u_lightData" not in src


def test_another_thread_can_evaluate_it():
    """Mitsuba calls its Python plugins from worker threads: the GL context must be made current there."""
    import threading

    l = v = np.array([[0.0, 0.0, 1.0]])
    here = evaluate_materialx_f_cos("standard_surface", {}, l, v)
    there: list = []
    worker = threading.Thread(target=lambda: there.append(evaluate_materialx_f_cos("standard_surface", {}, l, v)))
    worker.start()
    worker.join()
    assert len(there) == 1
    np.testing.assert_array_equal(there[0], here)
