"""A plane showing a medium is a slab of it: its geometry, its depth, and its light against the semi-infinite closed form."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from atlasgen.materials.scene import SceneObject
from atlasgen.validate.mitsuba_scene import SLAB_DIFFUSION_LENGTHS, diffusion_length, slab_object, world_mesh_arrays


def _frame(obj):
    """The plane's world normal and its two edge directions (unit), from its own transform."""
    from atlasgen.materials.scene import object_matrix

    m = object_matrix(obj)[:3, :3]
    edges = [m[:, 0] / np.linalg.norm(m[:, 0]), m[:, 2] / np.linalg.norm(m[:, 2])]
    normal = np.cross(edges[1], edges[0])
    return normal / np.linalg.norm(normal), edges


@pytest.mark.parametrize("rotate", [(0.0, 0.0, 0.0), (30.0, 45.0, 10.0)])
def test_the_slabs_top_face_is_the_plane_and_it_reaches_its_depth_below_and_beyond_the_edges(rotate):
    plane = SceneObject(0, "plane", "skin", translate=(0.2, -0.3, 0.5), rotate=rotate, scale=(1.6, 1.0, 1.2))
    depth = 0.7
    slab = slab_object(plane, depth)
    normal, (u, w) = _frame(plane)
    positions, _, _ = world_mesh_arrays(slab)
    rel = positions - np.asarray(plane.translate)
    height = rel @ normal
    # Every corner lies on the plane's own surface or depth below it, and both faces are there.
    assert np.allclose(np.minimum(np.abs(height), np.abs(height + depth)), 0.0, atol=1e-12)
    assert np.isclose(height.max(), 0.0, atol=1e-12) and np.isclose(height.min(), -depth)
    # In the plane: the plane's half-extents (1.6, 1.2) grown by the depth on every side.
    np.testing.assert_allclose(sorted(set(np.round(np.abs(rel @ u), 9))), [1.6 + depth])
    np.testing.assert_allclose(sorted(set(np.round(np.abs(rel @ w), 9))), [1.2 + depth])
    # The plane's own corners lie inside the slab's top face.
    corners, _, _ = world_mesh_arrays(plane)
    assert np.allclose((corners - np.asarray(plane.translate)) @ normal, 0.0, atol=1e-12)


def test_diffusion_length_is_the_inverse_effective_attenuation_of_the_longest_channel():
    """sigma_tr = sqrt(3 sigma_a sigma_t): sigma_t = 2 (value 1 * scale 2) and albedo 0.5 give sigma_a = 1,
    L = 1 / sqrt(6); a channel of albedo 0.9 (sigma_a = 0.2) diffuses further, 1 / sqrt(1.2); one that absorbs
    nothing is capped at 100 mean free paths."""
    medium = {"sigma_t": {"value": [1.0, 1.0, 0.5]}, "scale": 2.0, "albedo": {"value": [0.5, 0.9, 0.5]}}
    assert diffusion_length(medium) == pytest.approx(1.0 / math.sqrt(1.2))
    medium["albedo"]["value"] = [0.5, 0.5, 0.5]
    assert diffusion_length(medium) == pytest.approx(1.0 / math.sqrt(3.0 * 0.5 * 1.0))  # the sigma_t = 1 channel
    medium["albedo"]["value"] = [0.5, 1.0, 0.5]
    assert diffusion_length(medium) == pytest.approx(100.0 / 2.0)


def test_the_shipped_skins_slab_is_ten_diffusion_lengths_of_its_red():
    """Skin1's red diffuses furthest: sigma_t = 0.772 / mm * 24 mm per unit, its albedo Skin1's red, ~0.153 units."""
    from atlasgen.models.sss import SKIN1_SIGMA_A, SKIN1_SIGMA_S_REDUCED, skin_medium

    medium, _ = skin_medium(12.0, colour=(0.625, 0.385, 0.241))
    s, a = SKIN1_SIGMA_S_REDUCED[0] * 24.0, SKIN1_SIGMA_A[0] * 24.0
    assert diffusion_length(medium) == pytest.approx(1.0 / math.sqrt(3.0 * a * (s + a)), rel=2e-3)
    assert SLAB_DIFFUSION_LENGTHS == 10.0


def _h(albedo: float, mu):
    """Chandrasekhar's H(mu) at any mu in [0, 1]: one step of its equation from the converged nodes
    (:func:`atlasgen.models.sss.chandrasekhar_h`), 1 / H(mu) = sqrt(1 - w) + (w / 2) int mu' H(mu') / (mu + mu') dmu'."""
    from atlasgen.models.sss import chandrasekhar_h

    nodes, weights, h = chandrasekhar_h(albedo)
    mu = np.asarray(mu, dtype=np.float64)
    integral = (weights * nodes * h / (mu[..., None] + nodes)).sum(-1)
    return 1.0 / (np.sqrt(1.0 - albedo) + 0.5 * albedo * integral)


#: A plane of skin seen from straight above, lit straight down by unit irradiance; every pixel shows the plane.
OVERHEAD = """
[camera]
position = [0.0, 3.0, 0.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 0.0, -1.0]
fov = 20.0
[image]
width = 12
height = 9
[[lights]]
type = "directional"
direction = [0.0, -1.0, 0.0]
intensity = 1.0
[[objects]]
shape = "plane"
material = "skin"
scale = 2.0
"""


@pytest.mark.slow  # volpathmis's JIT compilation, ~5 s
def test_a_plane_of_skin_reflects_as_chandrasekhars_semi_infinite_medium(mitsuba_rgb, tmp_path):
    """Validation's reference of a plane of skin (a slab of the medium under it, rendered through the pixel centres)
    against the exact radiance leaving a semi-infinite, index-matched, isotropically scattering medium under
    light along its normal (Chandrasekhar, Radiative Transfer, 1950, ch. IV, eq. 105 with H of ch. V):

        L(mu) = E w H(mu) H(1) / (4 pi (1 + mu)),

    w the single-scattering albedo per channel, mu = cos of the view angle per pixel. The ratio of render to closed
    form, per pixel, has mean 1 within 4 standard errors (pixels are independent samples) per channel."""
    import tomllib

    from atlasgen.materials.material import read_material
    from atlasgen.materials.scene import parse_scene
    from atlasgen.models.sss import single_scattering_albedo
    from atlasgen.render.camera import pixel_rays
    from atlasgen.validate.references import physical_reference
    from atlasgen.validate.run import render_physical

    path = tmp_path / "skin.toml"
    path.write_text('type = "sss"\nradius = 12.0\ncolour = [0.625, 0.385, 0.241]\n')
    material = read_material(path)
    entry = SimpleNamespace(name="skin", type="sss", params=material.params, fit=None)
    scene = parse_scene(tomllib.loads(OVERHEAD), "overhead.toml")
    ref = render_physical(mitsuba_rgb, scene, entry, physical_reference(entry), SimpleNamespace(materials=[entry]), 256, 1)
    assert ref.mask is None and ref.second_image is not None
    image = 0.5 * (ref.image + ref.second_image).astype(np.float64)
    rays = pixel_rays(scene.camera, scene.width, scene.height)
    mu = -rays[..., 1] / np.linalg.norm(rays, axis=-1)
    for channel, w in enumerate(single_scattering_albedo(material.params["colour"])):
        exact = w * _h(w, mu) * _h(w, 1.0) / (4.0 * math.pi * (1.0 + mu))
        ratio = (image[..., channel] / exact).ravel()
        se = ratio.std(ddof=1) / math.sqrt(ratio.size)
        assert abs(ratio.mean() - 1.0) < 4.0 * se + 1e-3, (channel, ratio.mean(), se)
        assert se < 0.02  # the test can tell: a 10% bias would be 5 standard errors
