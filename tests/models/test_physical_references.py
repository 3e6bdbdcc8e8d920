"""Physical references of the models: the thin-film BSDF against Mitsuba's own microfacet at zero
film thickness; skin scaling; which models have one."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.models.sss import SKIN1_SIGMA_A, SKIN1_SIGMA_S_REDUCED, skin_medium
from atlasgen.optics.microfacet import smith_g2_separable_over_cos, smith_visibility_correlated_ggx
from atlasgen.optics.thin_film import thin_film_f_cos


def _dirs(rng, n):
    d = rng.normal(size=(n, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.05
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_thin_film_without_film_is_mitsubas_rough_dielectric_reflection(mitsuba_llvm):
    """At d = 0 the Airy reflectance is the bare base's Fresnel (Belcour & Barla 2017), so the
    lobe must equal Mitsuba's ``roughdielectric`` reflection with the same GGX alpha, once the
    masking is put in Mitsuba's form: the reference uses the renderer's height-correlated
    V = G2 / (4 cos_i cos_o), Mitsuba the separable G1(i) G1(o)."""
    import drjit as dr

    mi = mitsuba_llvm
    alpha, ior = 0.2, 1.5
    rng = np.random.default_rng(11)
    wi, wo = _dirs(rng, 300), _dirs(rng, 300)
    lam = np.full((300, 3), 550.0)
    film = {"thickness": 0.0, "film_ior": 1.33, "base_ior": ior, "base_k": 0.0}
    ours = thin_film_f_cos(wi, wo, lam, film, alpha, np.zeros((300, 3)))[:, 0]
    separable = 0.25 * smith_g2_separable_over_cos(wi[:, 2], wo[:, 2], alpha, "ggx")
    ours = ours * separable / smith_visibility_correlated_ggx(wi[:, 2], wo[:, 2], alpha)

    bsdf = mi.load_dict({"type": "roughdielectric", "distribution": "ggx", "alpha": alpha,
                         "int_ior": ior, "ext_ior": 1.0, "sample_visible": False})  # fmt: skip
    si = dr.zeros(mi.SurfaceInteraction3f, 300)
    si.wi = mi.Vector3f(*[mi.Float(np.ascontiguousarray(wi[:, k], np.float32)) for k in range(3)])
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    ctx = mi.BSDFContext()
    value = bsdf.eval(ctx, si, mi.Vector3f(*[mi.Float(np.ascontiguousarray(wo[:, k], np.float32)) for k in range(3)]))
    theirs = np.asarray(value.x)
    keep = theirs > 1e-4  # both lobes vanish far from the mirror direction
    assert keep.sum() > 30
    np.testing.assert_allclose(ours[keep], theirs[keep], rtol=3e-3)


def test_skin_medium_is_scaled_to_the_curvature_radius():
    for radius in (2.0, 10.0):
        medium, ior = skin_medium(radius, object_radius=0.5)
        t = np.asarray(medium["sigma_t"]["value"]) * medium["scale"]
        expected = (np.asarray(SKIN1_SIGMA_S_REDUCED) + np.asarray(SKIN1_SIGMA_A)) * radius / 0.5
        np.testing.assert_allclose(t, expected, rtol=1e-12)
        np.testing.assert_allclose(medium["albedo"]["value"], np.asarray(SKIN1_SIGMA_S_REDUCED) / (expected * 0.5 / radius))
        assert ior == pytest.approx(1.3)
