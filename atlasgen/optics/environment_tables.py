"""A material slice's tables for environment lighting, and the CPU twin of the shading that reads them.

Under an environment of radiance L(l), the renderer's equation (:mod:`atlasgen.optics.specular`)
integrated over l is, per pixel (docs/atlas-format.md, "Environment lighting"),

    diffuse  = albedo / pi * sum_l lambda_l(N.V) sum_m L_lm Y_lm(n)          (Funk-Hecke; exact to band l <= order)
    specular = Lpre(r, alpha) * S(N.V, alpha)                                 (the split sum; Karis 2013)

with lambda_l(N.V) = 2 pi int_-1^1 A.rgb(mu, N.V) P_l(mu) dmu (:func:`slice_sh_table`),
S(N.V, alpha) = int_H A.a(n.l, N.V) D V (n.l) dl (:func:`slice_specular_table`), L_lm the
environment's harmonics (:func:`atlasgen.optics.spherical_harmonics.project_equirect`), Lpre the
GGX-prefiltered environment (:func:`atlasgen.optics.prefilter.prefilter_ggx`) and r the
reflection of v about n.

Both tables are linear in the slice's texels, so a table row interpolated linearly in N.V is the
table of the slice interpolated the same way: a shader samples them as it samples the atlas, row
j at N.V = j / (H - 1) (clamp-to-edge), and gets what integrating the bilinear slice would give.
"""

from __future__ import annotations

import numpy as np

from atlasgen.contract import HEIGHT, WIDTH, texel_centres
from atlasgen.optics.interpolation import interpolate_1d, interpolate_2d, sample_slice
from atlasgen.optics.microfacet import ggx_distribution
from atlasgen.optics.prefilter import sample_prefiltered
from atlasgen.optics.quadrature import gauss_legendre_rule
from atlasgen.optics.specular import specular_alpha, specular_f_cos
from atlasgen.optics.spherical_harmonics import SH_ORDER, evaluate_sh, zonal_coefficients

__all__ = [
    "GLOSS_COUNT",
    "SPECULAR_SAMPLES",
    "table_glosses",
    "slice_breakpoints",
    "slice_sh_table",
    "slice_specular_table",
    "azimuth_averaged_slice",
    "diffuse_environment",
    "specular_environment",
    "reflect",
    "directional_albedo_table",
    "split_sum_environment",
]

#: Columns of the specular table: gloss i / (GLOSS_COUNT - 1), i = 0..15.
GLOSS_COUNT = 16
#: Gauss-Legendre nodes (per piece of the CDF of D cos(theta_h), in the azimuth) of :func:`slice_specular_table`.
#: With 4x as many in each, the table moves by less than 5e-4 for A.a = 1 and 1e-3 for an A.a that varies
#: along N.L like a Fresnel factor (tests/optics/test_environment_tables.py), a quarter of an 8-bit step.
SPECULAR_SAMPLES = (32, 16)


def table_glosses(gloss_count: int = GLOSS_COUNT) -> np.ndarray:
    """The specular table's glosses, i / (gloss_count - 1).

    >>> table_glosses(5).tolist()
    [0.0, 0.25, 0.5, 0.75, 1.0]
    """
    return np.linspace(0.0, 1.0, gloss_count)


def _check_slice(values) -> np.ndarray:
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 3 or v.shape[2] not in (3, 4) or v.shape[0] < 2 or v.shape[1] < 2:
        raise ValueError(f"expected a float slice (HEIGHT, WIDTH, 4) as the bake makes it, got shape {v.shape}")
    return v


def slice_breakpoints(width: int = WIDTH, nearest: bool = False) -> np.ndarray:
    """The N.L where a slice row's reconstruction has kinks: texel centres (bilinear) or texel edges (``nearest``).

    Bilinear filtering is linear between texel centres N.L_i = -1 + 2 i / (W - 1); a slice
    flagged ``nearest`` is constant on each texel, whose edges lie at u = k / W, N.L = -1 +
    (2k - 1) / (W - 1) (:func:`atlasgen.contract.atlas_uv`), clipped to [-1, 1].
    """
    if not nearest:
        return texel_centres(width, 2)[0]
    edges = -1.0 + (2.0 * np.arange(1, width) - 1.0) / (width - 1)
    return np.concatenate([[-1.0], edges, [1.0]])


def slice_sh_table(values, order: int = SH_ORDER, nearest: bool = False) -> np.ndarray:
    """lambda_l at each N.V row of a float slice ``(H, W, 4)``: ``(H, order + 1, 3)``.

    lambda_l(N.V_j) = 2 pi int_-1^1 A.rgb(mu, N.V_j) P_l(mu) dmu, with A.rgb the slice as the GPU
    sampler reconstructs it along N.L at row j (:func:`atlasgen.optics.interpolation.sample_slice`):
    piecewise linear between texel centres, or constant per texel for a ``nearest`` slice. Gauss-Legendre
    on each piece (:func:`atlasgen.optics.spherical_harmonics.zonal_coefficients`) is exact there.
    A ``lambert`` slice of colour c (c max(N.L, 0)) gives lambda_0 = pi c, so a uniform radiance L
    shades it c L.
    """
    v = _check_slice(values)
    h, w = v.shape[:2]
    _, nv = texel_centres(w, h)
    rgb = v[..., :3]
    nodes = order // 2 + 2  # exact for (degree 1 piece) x P_l, l <= order
    lam = zonal_coefficients(lambda mu: sample_slice(rgb, mu[:, None], nv[None, :], nearest=nearest), order,
                             slice_breakpoints(w, nearest), nodes)  # fmt: skip
    return np.moveaxis(lam, 0, 1)  # (order + 1, H, 3) -> (H, order + 1, 3)


def _view(n_dot_v):
    nv = np.asarray(n_dot_v, dtype=np.float64)
    return np.stack([np.sqrt(np.maximum(1.0 - nv * nv, 0.0)), np.zeros_like(nv), nv], axis=-1)


def slice_specular_table(values, gloss_count: int = GLOSS_COUNT, samples=SPECULAR_SAMPLES, nearest: bool = False) -> np.ndarray:
    """S(N.V_j, alpha_i) = int_H A.a(n.l, N.V_j) D V max(n.l, 0) dl, ``(H, gloss_count)``, the slice's "DFG" table.

    Rows are the slice's N.V texel centres, columns the glosses of :func:`table_glosses` (alpha =
    :func:`atlasgen.optics.specular.specular_alpha`); the lobe is the renderer's,
    :func:`atlasgen.optics.specular.specular_f_cos`, and A.a the slice's alpha as the sampler
    reconstructs it along N.L at row j. The integral runs over half vectors h drawn from
    D(h) cos(theta_h) (Walter et al. 2007, eqs. 35-36): l = reflect(v, h), dl = 4 (v.h) dh, so
    S = E[A.a D V (n.l) 4 (v.h) / (D cos(theta_h))], taken with a fixed product rule (``samples``):
    Gauss-Legendre in xi, cos^2(theta_h) = (1 - xi) / (1 + (alpha^2 - 1) xi), on three pieces split
    where reflect(v, h) starts and stops grazing the horizon, times Gauss-Legendre in the azimuth
    over the part of [0, pi] (the integrand is even in it) where l is above the horizon. The rule
    follows the lobe, so it is as good at alpha = 0.002 as at 1 (:data:`SPECULAR_SAMPLES` says how
    well it has converged). For A.a = 1 it is the lobe's directional albedo, at most 1; at alpha =
    1 and normal view, 1 - ln 2 (tests/optics/test_environment_tables.py checks both, and a
    brute-force integral over l).
    """
    v = _check_slice(values)
    if v.shape[2] != 4:
        raise ValueError(f"expected a float slice with alpha (H, W, 4), got shape {v.shape}")
    h, w = v.shape[:2]
    _, nv = texel_centres(w, h)
    a = v[..., 3:4]
    if not np.any(a):
        return np.zeros((h, gloss_count))  # no specular scale anywhere (a diffuse slice): S = 0, exactly
    n_xi, n_phi = samples
    t_xi, w_xi = gauss_legendre_rule(n_xi)
    t_phi, w_phi = gauss_legendre_rule(n_phi)
    sin_v = np.sqrt(np.maximum(1.0 - nv * nv, 0.0))[:, None]
    out = np.empty((h, gloss_count))
    for i, gloss in enumerate(table_glosses(gloss_count)):
        alpha = float(specular_alpha(gloss))
        # The range of phi below changes abruptly where reflect(v, h) grazes the horizon at phi = 0 or pi,
        # cos^2(theta_h) = (1 -+ sin(theta_v)) / 2: split xi there, so each piece's integrand is smooth.
        c2 = np.concatenate([0.5 * (1.0 + sin_v), 0.5 * (1.0 - sin_v)], axis=1)  # (H, 2)
        knots = np.sort(
            np.concatenate([np.zeros((h, 1)), (1.0 - c2) / (1.0 + c2 * (alpha * alpha - 1.0)), np.ones((h, 1))], 1), 1
        )
        # Within each piece xi = a + (b - a)(3 s^2 - 2 s^3), s Gauss-Legendre in [0, 1]: the nodes crowd both
        # ends, where the integrand has square-root behaviour (the range of phi opening at a knot; D V cos
        # growing as 1 / sqrt(1 - xi) at N.V = 0) and, for a small alpha, all its variation (within alpha^2 of 1).
        lo, span = knots[:, :-1, None], np.diff(knots, axis=1)[..., None]  # (H, 3, 1)
        s_ = 0.5 * (t_xi + 1.0)
        xi = (lo + span * (s_ * s_ * (3.0 - 2.0 * s_))).reshape(h, -1)
        w_x = (span * (6.0 * s_ * (1.0 - s_) * 0.5 * w_xi)).reshape(h, -1)  # (H, 3 n_xi), sums to 1
        cos_h = np.sqrt(
            np.clip((1.0 - xi) / (1.0 + (alpha * alpha - 1.0) * xi), 1e-24, 1.0)
        )  # (H, xi); > 0 where a piece is empty
        sin_h = np.sqrt(np.maximum(1.0 - cos_h * cos_h, 0.0))
        # l = 2 (v.h) h - v is above the horizon where sin_v sin_h cos(phi) > N.V (1 - 2 cos_h^2) / (2 cos_h),
        # which also makes v.h > 0: integrate phi over [0, phi_max] only, where the integrand is smooth.
        bound = nv[:, None] * (1.0 - 2.0 * cos_h * cos_h) / (2.0 * cos_h)  # (H, xi)
        across = sin_v * sin_h
        with np.errstate(divide="ignore", invalid="ignore"):
            cos_max = np.where(across > 1e-12, bound / across, np.where(bound < 0.0, -np.inf, np.inf))
        phi_max = np.arccos(np.clip(cos_max, -1.0, 1.0))  # (H, xi)
        phi = phi_max[..., None] * (0.5 * (t_phi + 1.0))  # (H, xi, phi)
        weight = w_x[..., None] * (phi_max / np.pi)[..., None] * (0.5 * w_phi)
        v_dot_h = across[..., None] * np.cos(phi) + (nv[:, None] * cos_h)[..., None]
        n_dot_l = 2.0 * v_dot_h * cos_h[..., None] - nv[:, None, None]
        c_h = np.broadcast_to(cos_h[..., None], n_dot_l.shape)
        with np.errstate(invalid="ignore"):  # V is infinite at N.L = N.V = 0, where specular_f_cos masks it
            lobe = specular_f_cos(gloss, n_dot_l, nv[:, None, None], c_h)
        # The density of h is D cos(theta_h); dl = 4 (v.h) dh.
        ratio = lobe * 4.0 * np.maximum(v_dot_h, 0.0) / (ggx_distribution(c_h, alpha) * c_h)
        scale = sample_slice(a, np.clip(n_dot_l, -1.0, 1.0), nv[:, None, None], nearest=nearest)[..., 0]
        out[:, i] = np.sum(np.where(n_dot_l > 0.0, ratio * scale, 0.0) * weight, axis=(1, 2))
    return out


def azimuth_averaged_slice(f_cos, azimuths: int = 256, width: int = WIDTH, height: int = HEIGHT,
                           min_n_dot_v: float = 0.0) -> np.ndarray:  # fmt: skip
    """An (N.L, N.V) slice ``(height, width, 4)`` holding pi x the azimuthal mean of ``f_cos``: for environment tables.

    ``f_cos(l, v)`` maps unit ``(N, 3)`` light and view directions in the local frame (n = +z) to
    f |cos(theta_l)| in linear RGB, ``(N, 3)`` (as :class:`atlasgen.models.base.PhysicalFCos`, or a
    separable material's rebuild); v = (sin(theta_v), 0, N.V) with N.V at least ``min_n_dot_v``,
    l at azimuth phi_k = 2 pi (k + 1/2) / ``azimuths`` (the midpoint rule, spectrally accurate
    for a smooth periodic f cos). RGB = pi * mean_k f_cos, A = 0, so the renderer's
    albedo * A.rgb / pi is the mean and :func:`slice_sh_table` of this slice serves a material
    whose f cos is 4D (a separable one). That is exact for a uniform environment, and in general
    for the part of f cos that is symmetric about n (its zonal part, the azimuthal mean); the
    rest of f cos, what depends on the azimuth between l and v, is lost.
    """
    nl, nv = texel_centres(width, height)
    nv = np.maximum(nv, min_n_dot_v)
    phi = 2.0 * np.pi * (np.arange(azimuths) + 0.5) / azimuths
    sin_l = np.sqrt(np.maximum(1.0 - nl * nl, 0.0))
    l = np.stack(np.broadcast_arrays(sin_l[:, None] * np.cos(phi), sin_l[:, None] * np.sin(phi), nl[:, None]), axis=-1)
    out = np.zeros((height, width, 4))
    for j, c in enumerate(nv):
        v = np.broadcast_to(_view(c), l.shape)
        value = np.asarray(f_cos(l.reshape(-1, 3), v.reshape(-1, 3)), dtype=np.float64).reshape(width, azimuths, 3)
        out[j, :, :3] = np.pi * value.mean(axis=1)
    return out


def reflect(v, n) -> np.ndarray:
    """r = 2 (n.v) n - v, the mirror direction of ``v`` about ``n`` (both unit, ``(..., 3)``)."""
    v = np.asarray(v, dtype=np.float64)
    n = np.asarray(n, dtype=np.float64)
    return 2.0 * np.sum(n * v, axis=-1, keepdims=True) * n - v


def diffuse_environment(sh_coefficients, sh_table, normals, n_dot_v) -> np.ndarray:
    """max((1/pi) sum_l lambda_l(N.V) sum_m L_lm Y_lm(n), 0): the environment's diffuse term before the albedo,
    ``(..., 3)``. The truncated series of a bright sun rings below 0 on the far side; like Filament's irradiance,
    it is clamped there, as the include's ``atlas_sh_diffuse`` is.

    ``sh_coefficients`` ``(K, 3)`` (:func:`atlasgen.optics.spherical_harmonics.project_equirect`),
    ``sh_table`` ``(H, order + 1, 3)`` (:func:`slice_sh_table`) read linearly at N.V (clamped to
    [0, 1]), as the atlas is read.
    """
    table = np.asarray(sh_table, dtype=np.float64)
    nv = np.clip(np.asarray(n_dot_v, dtype=np.float64), 0.0, 1.0)
    lam = interpolate_1d(table, nv * (table.shape[0] - 1))
    return np.maximum(evaluate_sh(sh_coefficients, normals, zonal=lam) / np.pi, 0.0)


def specular_environment(levels, specular_table, reflected, n_dot_v, gloss) -> np.ndarray:
    """Lpre(r, alpha) S(N.V, alpha): the environment's specular term, ``(..., 3)``.

    ``levels`` from :func:`atlasgen.optics.prefilter.prefilter_ggx`, read at level (1 - gloss)
    (levels - 1); ``specular_table`` ``(H, G)`` (:func:`slice_specular_table`) read bilinearly at
    (gloss (G - 1), N.V (H - 1)); ``reflected`` the mirror directions r (:func:`reflect`).
    """
    table = np.asarray(specular_table, dtype=np.float64)
    g = np.clip(np.asarray(gloss, dtype=np.float64), 0.0, 1.0)
    nv = np.clip(np.asarray(n_dot_v, dtype=np.float64), 0.0, 1.0)
    s = interpolate_2d(table, g * (table.shape[1] - 1), nv * (table.shape[0] - 1))
    pre = sample_prefiltered(levels, reflected, (1.0 - g) * (len(levels) - 1))
    return pre * np.asarray(s)[..., None]


def directional_albedo_table(f_cos, height: int = HEIGHT, nodes=(64, 128), even: bool = False) -> np.ndarray:
    """S_sep(N.V_j) = int_H f cos(l, v_j) dl, ``(height, 3)``: the directional albedo of a 4D f cos, per N.V row.

    For materials whose f cos has no (N.L, N.V) slice (separable ones): the renderer gives them
    the split sum with their own albedo, Lpre(r, alpha) S_sep(N.V) (:func:`split_sum_environment`).
    ``f_cos(l, v)`` as for :func:`azimuth_averaged_slice` (local frame, n = +z, ``(N, 3)`` each);
    rows at N.V_j = j / (height - 1), v = (sin(theta_v), 0, N.V). The integral is Gauss-Legendre in
    cos(theta_l) (``nodes[0]``) times Gauss-Legendre in the azimuth on (0, pi) and (pi, 2 pi)
    (``nodes[1]`` in all): its nodes crowd towards the azimuth pi, where the mirror lobe of a sharp
    BRDF lies (azimuth pi from v's), so a lobe narrower than the node spacing elsewhere is still
    resolved (a GGX lobe of alpha 0.05 at N.V 0.26: 0.8% with 64 x 128 nodes, where the midpoint
    rule in the azimuth was 73% short). ``even``: f cos is even in the azimuth of l (isotropic, v in
    the xz plane, as a separable rebuild's angles are), so the nodes in (pi, 2 pi), the mirror
    images of those in (0, pi), are not evaluated and the others count twice: the same sum for
    half the work (even ``nodes[1]`` only).

    >>> t = directional_albedo_table(lambda l, v: np.repeat(l[:, 2:] / np.pi, 3, 1), 3, (8, 4))
    >>> t.round(12).tolist()[0]  # a white Lambertian surface reflects everything
    [1.0, 1.0, 1.0]
    """
    t, w = gauss_legendre_rule(nodes[0])
    mu, w_mu = 0.5 * (t + 1.0), 0.5 * w
    if nodes[1] % 2:
        raise ValueError(f"the azimuth rule has two halves, so an even number of azimuths; got {nodes[1]}")
    tp, wp = gauss_legendre_rule(nodes[1] // 2)
    half, w_half = 0.5 * np.pi * (tp + 1.0), 0.5 * np.pi * wp  # on (0, pi)
    phi, w_phi = (half, 2.0 * w_half) if even else (np.concatenate([half, 2.0 * np.pi - half]), np.tile(w_half, 2))
    s = np.sqrt(np.maximum(1.0 - mu * mu, 0.0))
    l = np.stack(np.broadcast_arrays(s[:, None] * np.cos(phi), s[:, None] * np.sin(phi), mu[:, None]), -1).reshape(-1, 3)
    weight = (w_mu[:, None] * w_phi[None, :]).reshape(-1)
    out = np.empty((height, 3))
    for j, c in enumerate(np.linspace(0.0, 1.0, height)):
        v = np.broadcast_to(_view(c), l.shape)
        out[j] = weight @ np.asarray(f_cos(l, v), dtype=np.float64).reshape(-1, 3)
    return out


def split_sum_environment(levels, albedo_table, reflected, n_dot_v, gloss) -> np.ndarray:
    """Lpre(r, alpha) S_sep(N.V): the split sum of a material with its own directional albedo ``(H, 3)``, ``(..., 3)``.

    ``albedo_table`` from :func:`directional_albedo_table`, read linearly at N.V (H - 1); the lobe
    width comes from the object's gloss, level (1 - gloss) (levels - 1), as for
    :func:`specular_environment`. Exact for a uniform environment, whatever the lobe.
    """
    table = np.asarray(albedo_table, dtype=np.float64)
    g = np.clip(np.asarray(gloss, dtype=np.float64), 0.0, 1.0)
    nv = np.clip(np.asarray(n_dot_v, dtype=np.float64), 0.0, 1.0)
    s = interpolate_1d(table, nv * (table.shape[0] - 1))
    return sample_prefiltered(levels, reflected, (1.0 - g) * (len(levels) - 1)) * s
