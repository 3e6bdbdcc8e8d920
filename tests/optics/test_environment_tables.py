"""A slice's environment tables: the SH table against closed forms (lambert, a nearest step), a uniform
environment through the whole chain, the specular table against brute-force integrals of the lobe and its
convergence, and the azimuthal average for 4D materials."""

import doctest
from pathlib import Path

import numpy as np
import pytest
from numpy.polynomial import Polynomial
from numpy.polynomial import legendre as leg

from atlasgen.contract import HEIGHT, WIDTH, texel_centres, texel_grid
from atlasgen.optics.environment_tables import (
    SPECULAR_SAMPLES,
    azimuth_averaged_slice,
    diffuse_environment,
    directional_albedo_table,
    reflect,
    slice_sh_table,
    slice_specular_table,
    specular_environment,
    table_glosses,
)
from atlasgen.optics.interpolation import interpolate_1d, sample_slice
from atlasgen.optics.prefilter import prefilter_ggx
from atlasgen.optics.specular import specular_f_cos
from atlasgen.optics.spherical_harmonics import evaluate_sh, project_equirect, zonal_coefficients

RNG = np.random.default_rng(5)
DOCS = Path(__file__).resolve().parents[2] / "docs" / "atlas-format.md"
COLOUR = np.array([0.8, 0.5, 0.2])


def _lambert(colour=COLOUR, a=1.0):
    nl, _ = texel_grid()
    s = np.empty((HEIGHT, WIDTH, 4))
    s[..., :3] = colour * np.maximum(nl, 0.0)[..., None]
    s[..., 3] = a
    return s


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _interpolated_clamped_cosine_lambdas(order):
    """2 pi int P_l(mu) c(mu) dmu for c the linear interpolant of max(mu, 0) between the 64 texel centres, exactly.

    N.L = 0 is no texel centre: between -e and e (e = 1/63) the interpolant is (mu + e) / 2, not max(mu, 0).
    Polynomial integration, independent of the Gauss-Legendre code.
    """
    e = 1.0 / (WIDTH - 1)
    out = []
    for l in range(order + 1):
        p = Polynomial(leg.leg2poly([0] * l + [1]))
        upper = (p * Polynomial([0, 1])).integ()
        middle = (p * Polynomial([e / 2, 0.5])).integ()
        value = upper(1.0) - upper(e) + middle(e) - middle(-e)
        out.append(2.0 * np.pi * value)
    return np.array(out)


def test_a_lambert_slices_table_is_its_colour_times_the_clamped_cosines():
    table = slice_sh_table(_lambert())
    lam = _interpolated_clamped_cosine_lambdas(4)
    np.testing.assert_allclose(table, np.broadcast_to(lam[:, None] * COLOUR, table.shape), atol=1e-13)
    # The interpolation's only trace: lambda_0 = pi c (1 + 1/63^2); the rest is the clamped cosine's pi, 2 pi/3, pi/4, 0, -pi/24.
    assert lam[0] == pytest.approx(np.pi * (1.0 + 1.0 / 63.0**2), rel=1e-14)
    np.testing.assert_allclose(lam[1:] / np.pi, [2 / 3, 1 / 4, 0.0, -1 / 24], atol=3e-4)


def test_a_nearest_slices_table_integrates_its_steps():
    # A toon step: 1 on the texels whose centre has N.L > 0.3, read nearest: constant on each texel.
    nl, _ = texel_grid()
    s = np.zeros((HEIGHT, WIDTH, 4))
    s[..., :3] = (nl > 0.3)[..., None]
    first = np.argmax(texel_centres()[0] > 0.3)
    edge = -1.0 + (2.0 * first - 1.0) / (WIDTH - 1)  # the left edge of the first lit texel
    expected = [
        2 * np.pi * (leg.legval(1.0, leg.legint([0] * l + [1])) - leg.legval(edge, leg.legint([0] * l + [1]))) for l in range(3)
    ]
    table = slice_sh_table(s, order=2, nearest=True)
    np.testing.assert_allclose(table[:, :, 0], np.broadcast_to(expected, (HEIGHT, 3)), atol=1e-13)
    assert not np.allclose(slice_sh_table(s, order=2)[:, :, 0], table[:, :, 0])


def test_table_rows_interpolate_as_the_slice_does():
    s = RNG.random((HEIGHT, WIDTH, 4))
    table = slice_sh_table(s)
    nv = 0.37  # between rows 11 and 12
    direct = zonal_coefficients(lambda mu: sample_slice(s[..., :3], mu, nv), 4, texel_centres()[0], 4)
    np.testing.assert_allclose(interpolate_1d(table, nv * (HEIGHT - 1)), direct, atol=1e-12)
    # The CPU twin reads the table at that N.V, as a shader does.
    coefficients = RNG.normal(size=(25, 3))
    n = _unit(RNG.normal(size=(5, 3)))
    np.testing.assert_allclose(
        diffuse_environment(coefficients, table, n, nv),
        np.maximum(evaluate_sh(coefficients, n, zonal=direct) / np.pi, 0.0),
        atol=1e-12,
    )


def test_a_uniform_environment_shades_lambert_with_its_colour_times_the_radiance():
    radiance = np.array([0.3, 1.2, 2.0])
    coefficients = project_equirect(np.broadcast_to(radiance, (16, 32, 3)))
    normals = _unit(RNG.normal(size=(40, 3)))
    n_dot_v = RNG.random(40)
    diffuse = diffuse_environment(coefficients, slice_sh_table(_lambert()), normals, n_dot_v)
    np.testing.assert_allclose(diffuse, np.broadcast_to(COLOUR * radiance * (1.0 + 1.0 / 63.0**2), diffuse.shape), rtol=1e-9)


def test_a_uniform_environment_shades_specular_with_the_table():
    radiance = np.array([0.3, 1.2, 2.0])
    levels = prefilter_ggx(np.broadcast_to(radiance, (64, 128, 3)), 6)
    table = slice_specular_table(_lambert(a=0.5), gloss_count=5, samples=(8, 4))
    n = _unit(RNG.normal(size=(30, 3)))
    v = _unit(n + RNG.normal(size=(30, 3)) * 0.5)
    n_dot_v = np.clip(np.sum(n * v, -1), 0.0, 1.0)
    gloss = RNG.random(30)
    spec = specular_environment(levels, table, reflect(v, n), n_dot_v, gloss)
    # At the table's own nodes (gloss i/4, N.V j/31) the lookup is the entry.
    np.testing.assert_allclose(
        specular_environment(levels, table, reflect(v, n)[:1], 4 / 31, 0.25)[0], radiance * table[4, 1], rtol=1e-6
    )
    ratio = spec / radiance
    np.testing.assert_allclose(ratio, np.broadcast_to(ratio[:, :1], ratio.shape), rtol=1e-6)
    assert np.all((0.0 < ratio) & (ratio <= 0.5 * (1.0 + 1e-6)))  # the levels are float32


def test_the_specular_term_reads_level_one_minus_gloss_times_five():
    levels = [np.full((8, 16, 3), float(k), dtype=np.float32) for k in range(6)]  # level k holds k
    table = np.full((HEIGHT, 5), 0.5)
    r = _unit(RNG.normal(size=(4, 3)))
    got = specular_environment(levels, table, r, 0.3, np.array([1.0, 0.9, 0.5, 0.0]))
    np.testing.assert_allclose(got[:, 0], 0.5 * np.array([0.0, 0.5, 2.5, 5.0]), rtol=1e-12)


def _brute_albedo_over_light(gloss, cos_v, n=600):
    """int D V max(N.L, 0) dl by the midpoint rule over the light's (theta, phi): no sampling of h at all."""
    t = (np.arange(n) + 0.5) * (0.5 * np.pi / n)
    p = (np.arange(2 * n) + 0.5) * (np.pi / n)
    tt, pp = np.meshgrid(t, p, indexing="ij")
    l = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1)
    h = l + [np.sqrt(1.0 - cos_v * cos_v), 0.0, cos_v]
    f = specular_f_cos(gloss, l[..., 2], cos_v, h[..., 2] / np.linalg.norm(h, axis=-1))
    return (f * np.sin(tt)).sum() * (0.5 * np.pi / n) * (np.pi / n)


def test_the_specular_table_of_a_constant_scale_is_the_lobes_albedo():
    ones = np.ones((HEIGHT, WIDTH, 4))
    table = slice_specular_table(ones, gloss_count=3)  # gloss 0, 0.5, 1: alpha 1, 0.25, 0.002
    assert table.shape == (HEIGHT, 3) and np.all(table > 0.0) and table.max() <= 1.0 + 1e-9
    # Closed form: at alpha = 1 and normal view the albedo is 1 - ln 2.
    assert table[-1, 0] == pytest.approx(1.0 - np.log(2.0), abs=1e-6)
    # A.a scales linearly.
    np.testing.assert_allclose(slice_specular_table(0.25 * ones, gloss_count=4, samples=(8, 4)),
                               0.25 * slice_specular_table(ones, gloss_count=4, samples=(8, 4)), rtol=1e-13)  # fmt: skip


@pytest.mark.slow
def test_the_specular_table_matches_a_brute_force_integral_over_the_light():
    table = slice_specular_table(np.ones((HEIGHT, WIDTH, 4)))
    glosses = table_glosses()
    for j in (1, 6, 16, 31):
        for i in (0, 4, 8):  # alpha 1, 0.538, 0.218: the brute force resolves these lobes
            assert table[j, i] == pytest.approx(_brute_albedo_over_light(glosses[i], j / 31), abs=3e-4), (j, i)


@pytest.mark.slow
def test_the_specular_tables_rule_has_converged_for_narrow_lobes_and_varying_scales():
    # A scale that varies along N.L (Fresnel-like: large at grazing light), and the narrowest lobes.
    nl, _ = texel_grid()
    scale = np.ones((HEIGHT, WIDTH, 4))
    scale[..., 3] = 0.04 + 0.96 * (1.0 - np.clip(np.abs(nl), 0.0, 1.0)) ** 5
    for s in (np.ones((HEIGHT, WIDTH, 4)), scale):
        coarse = slice_specular_table(s, samples=SPECULAR_SAMPLES)
        fine = slice_specular_table(s, samples=(4 * SPECULAR_SAMPLES[0], 4 * SPECULAR_SAMPLES[1]))
        assert np.abs(coarse - fine).max() < (5e-4 if s is not scale else 1e-3)
    # At gloss 1 (alpha = 0.002) and N.V >= 0.2 the lobe is a mirror, whose albedo 4 N.V^2 V(N.V, N.V) tends to 1.
    assert np.all(slice_specular_table(np.ones((HEIGHT, WIDTH, 4)))[7:, -1] > 0.99)


def test_an_azimuthal_average_keeps_the_zonal_part_and_a_uniform_environments_integral():
    # f cos = (c / pi) max(l.z, 0) (1 + 0.8 l.x v.x): the azimuthal term averages away.
    def f_cos(l, v):
        return (COLOUR / np.pi) * (np.maximum(l[:, 2], 0.0) * (1.0 + 0.8 * l[:, 0] * v[:, 0]))[:, None]

    s = azimuth_averaged_slice(f_cos, azimuths=64)
    np.testing.assert_allclose(s, _lambert(a=0.0), atol=1e-14)
    # Under a uniform radiance, lambda_0 / pi is int f cos dl over the whole sphere (here: c, the albedo).
    table = slice_sh_table(s)
    np.testing.assert_allclose(table[:, 0] / np.pi, np.broadcast_to(COLOUR * (1.0 + 1.0 / 63.0**2), (HEIGHT, 3)), rtol=1e-12)


def test_docs_give_the_tables_measured_shapes_and_lambert_factor():
    text = " ".join(DOCS.read_text(encoding="utf-8").split())
    assert f"`(HEIGHT, SH_ORDER + 1, 3)` = {slice_sh_table(_lambert()).shape}" in text
    assert f"shape `(HEIGHT, {slice_specular_table(_lambert(), samples=(2, 2)).shape[1]})`" in text
    e = _interpolated_clamped_cosine_lambdas(0)[0] / np.pi - 1.0
    assert f"(1 + 1/{round(1.0 / np.sqrt(e))}^2)" in text and e == pytest.approx(1.0 / (WIDTH - 1) ** 2, rel=1e-12)


def test_the_docstrings_examples_hold():
    from atlasgen.optics import environment_tables

    assert doctest.testmod(environment_tables).failed == 0


def test_an_even_integrand_takes_half_the_azimuths_for_the_same_albedo():
    # A GGX lobe about the mirror direction of v = (sin, 0, cos): even in the azimuth of l, as a separable rebuild is.
    def f_cos(l, v):
        h = l + v
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        value = specular_f_cos(0.6, l[:, 2], v[:, 2], h[:, 2])
        return np.repeat(np.nan_to_num(value)[:, None], 3, axis=1)

    calls = []

    def counted(l, v):
        calls.append(len(l))
        return f_cos(l, v)

    full = directional_albedo_table(counted, 5, (24, 32))
    half = directional_albedo_table(counted, 5, (24, 32), even=True)
    np.testing.assert_allclose(half, full, rtol=1e-12, atol=1e-15)
    assert calls[5:] == [n // 2 for n in calls[:5]] and full.max() > 0.1
    with pytest.raises(ValueError, match="even number"):
        directional_albedo_table(f_cos, 5, (24, 31), even=True)


def test_a_sharp_lobe_at_grazing_view_is_resolved_by_the_default_nodes():
    # The renderer's GGX lobe at alpha 0.04 (gloss 0.8): at N.V = 2/31 its mirror lobe lies near the
    # horizon, narrow in the azimuth; the default 64 x 128 nodes must agree with 256 x 512 to 1%
    # (a midpoint rule in the azimuth was 70% short there). 256 x 512 is converged: it agrees with
    # 512 x 1024 to 1e-11 (measured), at an eighth of the CPU time.
    def f_cos(l, v):
        h = l + v
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        with np.errstate(invalid="ignore"):
            value = specular_f_cos(0.8, l[:, 2], v[:, 2], h[:, 2])
        return np.repeat(np.nan_to_num(value)[:, None], 3, axis=1)

    dense = directional_albedo_table(f_cos, 32, (256, 512), even=True)
    default = directional_albedo_table(f_cos, 32, even=True)
    np.testing.assert_allclose(default[2:], dense[2:], rtol=1e-2)
    assert dense[2:, 0].min() > 0.1


def test_a_slice_without_specular_scale_has_a_zero_table_and_the_others_do_not():
    values = np.zeros((HEIGHT, WIDTH, 4))
    values[..., :3] = 0.5
    assert not slice_specular_table(values).any()
    values[..., 3] = 1e-3
    assert (slice_specular_table(values, gloss_count=2, samples=(8, 4)) > 0).all()


def test_the_diffuse_term_of_a_bright_sun_is_clamped_at_zero_where_its_series_rings_below():
    """The order-4 series of a sun over a black sky rings below 0 facing away from it; the renderer wrote those
    negative radiances into the image (down to -1.1 under a sun of 300)."""
    from atlasgen.optics.environment_tables import diffuse_environment
    from atlasgen.optics.spherical_harmonics import SH_ORDER, evaluate_sh, sh_basis

    sun = np.array([0.0, 0.0, -1.0])
    coefficients = 300.0 * sh_basis(sun[None])[0][:, None] * np.ones((1, 3))  # a delta of 300 towards the sun
    table = np.broadcast_to([np.pi, 2 * np.pi / 3, np.pi / 4, 0.0, -np.pi / 24], (32, 3, SH_ORDER + 1)).transpose(0, 2, 1)
    rng = np.random.default_rng(7)
    normals = rng.normal(size=(4000, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    series = evaluate_sh(coefficients, normals, zonal=np.broadcast_to(table[0], (4000, SH_ORDER + 1, 3))) / np.pi
    got = diffuse_environment(coefficients, table, normals, np.full(4000, 0.5))
    assert series.min() < -0.5  # the series does ring below 0
    np.testing.assert_allclose(got, np.maximum(series, 0.0), rtol=1e-12, atol=1e-12)
