"""The ``sss`` slice fitted to volpath renders of a sphere of skin (``from = "physical"``, issue 11).

The skin model's physical reference is light transport through a homogeneous medium
inside the sphere (:meth:`atlasgen.models.sss.Subsurface.physical_reference`): no BSDF, so
:mod:`atlasgen.models.physical_fit` has nothing to project. Instead the sphere itself is
rendered, ray by ray, and the slice fitted to what it shows.

**Samples.** A sphere of radius 0.5 scene units (the validation sphere; :func:`skin_medium`
scales the medium so that it is as large in mean free paths as a ``radius`` mm ball) holds
the medium behind an index-matched boundary, lit by one directional light of unit
irradiance arriving from +z, against black. The sphere is symmetric about its centre, so
one light direction shows every configuration: a configuration (N.L, N.V, phi), phi the
azimuth between l and v about N, is the point p = R n with n = (sqrt(1 - N.L^2), 0, N.L)
seen along v = N.V n + sqrt(1 - N.V^2) (cos phi t + sin phi b), t = (-N.L, 0, sqrt(1 - N.L^2))
the direction towards the light in the tangent plane and b = (0, 1, 0). A ray from p + v
towards -v meets the sphere first at p (the sphere is convex and N.V > 0), and Mitsuba's
``volpath`` (the reference's own integrator) returns the radiance L leaving p towards v.
It is an orthographic camera with one pixel per configuration: no pixel straddles the
silhouette, and N is exact rather than a pixel centre's.

Configurations are stratified: N.L uniform in [-1, 1], N.V in [0, 1] (at least
:data:`MIN_N_DOT_V`) and phi in [0, pi] (the response is even in phi), jittered in each
stratum by a NumPy generator of fixed seed, so uniform (N.L, N.V, phi) samples (l, v)
pairs uniformly over the hemisphere pair, the measure of
:func:`atlasgen.models.physical_fit.fit_slice`. The same configurations are rendered with
Mitsuba seeds 0 and 1.

**Fit.** With unit irradiance and albedo 1 the renderer's equation reads
L = M.rgb(N.L, N.V) / pi + M.a f_s cos(l, v) (docs/atlas-format.md), M the slice as the
renderer samples it: bilinearly between the four texels around (N.L, N.V)
(:func:`atlasgen.optics.interpolation.linear_stencil` at
:func:`atlasgen.contract.atlas_uv`). M.a is the model's ``specular`` (the reference's
boundary reflects nothing, docs/validation.md), so each sample is one linear equation in
the texels, y_s = pi (L_s - M.a f_s cos) = sum_k w_sk x_k per channel, solved by least
squares with a small penalty on the texels' second differences along both axes (it
vanishes on any bilinear function; it ties down texels few samples weigh), x >= 0
(:func:`fit_texels`).

**Error and noise.** The slices fitted to each seed alone differ by MC noise only; their
relative RMS difference (uniform (l, v) pairs) is the seeds' disagreement, and half of it
the noise of the slice fitted to both. The fit's own error is the relative RMS of the
residual r_s = y_s - M(N.L_s, N.V_s) per sample, estimated without MC noise as
sqrt(mean(r0 r1) / mean(y0 y1)), r0 and r1 the residuals of the two seeds' renders of the
same configuration (independent noise averages out of the product).
"""

from __future__ import annotations

import gc
import json
import time
from functools import lru_cache

import numpy as np

from atlasgen.contract import HEIGHT, WIDTH, atlas_uv
from atlasgen.errors import BackendError
from atlasgen.interrupts import deferred_interrupts
from atlasgen.optics.interpolation import linear_stencil
from atlasgen.optics.specular import half_vector_cosine, specular_f_cos

__all__ = ["FIT_STRATA", "FIT_PASSES", "FIT_SEEDS", "GEOMETRY_SEED", "MIN_N_DOT_V", "SMOOTHNESS", "OBJECT_RADIUS",
           "FIT_RADII", "SCORE_RADII", "SCORE_PASSES",
           "sample_configurations", "local_directions", "sphere_rays", "bilinear_stencil", "fit_texels",
           "render_sphere_samples", "fit_sss_slice", "fitted_sss_slice"]  # fmt: skip

#: Strata per pass along N.L, N.V and phi: two per texel along each slice axis.
FIT_STRATA = (2 * WIDTH, 2 * HEIGHT, 8)
#: Jittered passes per seed (each a full set of strata).
FIT_PASSES = 48
#: Mitsuba seeds of the two renders of the same configurations.
FIT_SEEDS = (0, 1)
#: The NumPy seed of the configurations' jitter.
GEOMETRY_SEED = 11
#: Smallest N.V sampled: a ray in the tangent plane would graze the sphere.
MIN_N_DOT_V = 1e-3
#: Weight of the second-difference penalty, relative to the mean sample weight per texel.
SMOOTHNESS = 0.1
#: Radius of the validation scenes' sphere in scene units: the medium is scaled so that it is as
#: large in mean free paths as a ``radius`` mm ball (:func:`atlasgen.models.sss.skin_medium`).
OBJECT_RADIUS = 0.5
#: Radii of the spheres the slice is fitted to, the same medium inside (curvatures 0.7 and 1.4 times
#: the material's ``radius``): not the validation sphere, so the fit is scored there out of sample.
FIT_RADII = (0.35, 0.7)
#: Geometries the fit is scored on and not fitted to: the validation sphere, and a sphere 40 times
#: its radius, flat over the skin's scattering distance (a flat part the validation plane cannot
#: show: it holds no medium).
SCORE_RADII = (("validation_sphere", OBJECT_RADIUS), ("flat", 20.0))
#: Jittered passes per seed of each scored geometry, per :data:`FIT_PASSES` of the fit.
SCORE_PASSES = 8
#: Rays per ``volpath`` call (memory, not results: every ray has its own random stream).
_BATCH = 1 << 20


def sample_configurations(passes: int = FIT_PASSES, strata=FIT_STRATA, seed: int = GEOMETRY_SEED):
    """``(n_dot_l, n_dot_v, phi)``, each ``(passes * prod(strata),)``: jittered strata of N.L in [-1, 1],
    N.V in [MIN_N_DOT_V, 1] and phi in [0, pi], uniform in each; the same for the same arguments."""
    rng = np.random.default_rng(seed)
    a, b, c = (int(s) for s in strata)
    grid = np.stack(np.meshgrid(np.arange(a), np.arange(b), np.arange(c), indexing="ij"), -1).reshape(-1, 3)
    cells = np.tile(grid, (int(passes), 1)).astype(np.float64)
    unit = (cells + rng.random(cells.shape)) / np.asarray([a, b, c], dtype=np.float64)
    n_dot_l = -1.0 + 2.0 * unit[:, 0]
    n_dot_v = MIN_N_DOT_V + (1.0 - MIN_N_DOT_V) * unit[:, 1]
    return n_dot_l, n_dot_v, np.pi * unit[:, 2]


def local_directions(n_dot_l, n_dot_v, phi):
    """Unit l, v ``(N, 3)`` in the shading frame (n = +z, l in the xz plane, v at azimuth phi
    from it), n.h and whether l + v = 0: what the renderer's lobe is evaluated with."""
    nl, nv, phi = (np.asarray(x, dtype=np.float64) for x in (n_dot_l, n_dot_v, phi))
    sl, sv = np.sqrt(np.maximum(1.0 - nl * nl, 0.0)), np.sqrt(np.maximum(1.0 - nv * nv, 0.0))
    l = np.stack([sl, np.zeros_like(nl), nl], -1)
    v = np.stack([sv * np.cos(phi), sv * np.sin(phi), nv], -1)
    return (l, v, *half_vector_cosine(l, v))


def sphere_rays(n_dot_l, n_dot_v, phi, radius: float = OBJECT_RADIUS):
    """Ray origins and directions ``(N, 3)`` that show the sphere of ``radius`` at the origin, lit
    from +z, in each configuration: the ray from p + v towards -v, p = radius * n (module docstring)."""
    nl, nv, phi = (np.asarray(x, dtype=np.float64) for x in (n_dot_l, n_dot_v, phi))
    sl, sv = np.sqrt(np.maximum(1.0 - nl * nl, 0.0)), np.sqrt(np.maximum(1.0 - nv * nv, 0.0))
    zero = np.zeros_like(nl)
    n = np.stack([sl, zero, nl], -1)
    t = np.stack([-nl, zero, sl], -1)  # towards the light, in the tangent plane (any tangent at N.L = +-1)
    b = np.stack([zero, np.ones_like(nl), zero], -1)
    v = nv[:, None] * n + sv[:, None] * (np.cos(phi)[:, None] * t + np.sin(phi)[:, None] * b)
    return radius * n + v, -v


def bilinear_stencil(n_dot_l, n_dot_v, width: int = WIDTH, height: int = HEIGHT):
    """``(index (N, 4), weight (N, 4))``: the texels (flat, row-major) and weights with which the
    renderer's bilinear lookup (:func:`atlasgen.optics.interpolation.interpolate_2d`) mixes a slice
    at each (N.L, N.V)."""
    u, v = atlas_uv(n_dot_l, n_dot_v, width, height)
    x0, x1, fx = linear_stencil(width, u * width - 0.5)
    y0, y1, fy = linear_stencil(height, v * height - 0.5)
    index = np.stack([y0 * width + x0, y0 * width + x1, y1 * width + x0, y1 * width + x1], -1)
    weight = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], -1)
    return index, weight


def _second_differences(width: int, height: int) -> np.ndarray:
    """D^T D ``(k, k)`` of the second differences of a ``(height, width)`` grid along both axes."""
    k = width * height
    grid = np.arange(k).reshape(height, width)
    triples = np.concatenate([np.stack([grid[:, :-2], grid[:, 1:-1], grid[:, 2:]], -1).reshape(-1, 3),
                              np.stack([grid[:-2], grid[1:-1], grid[2:]], -1).reshape(-1, 3)])  # fmt: skip
    coef = (1.0, -2.0, 1.0)
    dtd = np.zeros((k, k))
    for i in range(3):
        for j in range(3):
            np.add.at(dtd, (triples[:, i], triples[:, j]), coef[i] * coef[j])
    return dtd


def _banded_cholesky(a: np.ndarray):
    """``(L, p)``: a = L L^T for ``a`` symmetric positive definite and banded, p its half-bandwidth.

    Column by column (Golub & Van Loan, Matrix Computations, 4th ed., alg. 4.3.5), touching
    only the band of half-width p (the farthest non-zero from the diagonal): n p^2 work
    instead of the n^3 / 3 of a dense factorisation. The slice's normal matrix has p = 2 W
    (the second differences along N.V). Only L's lower band is meaningful.
    """
    n = len(a)
    rows, cols = np.nonzero(a)
    p = int(np.max(np.abs(rows - cols))) if len(rows) else 0
    low = a.copy()
    for j in range(n):
        end = min(n, j + p + 1)
        d = np.sqrt(low[j, j])
        low[j, j] = d
        column = low[j + 1 : end, j] / d
        low[j + 1 : end, j] = column
        low[j + 1 : end, j + 1 : end] -= column[:, None] * column[None, :]
    return low, p


def _banded_solve(low: np.ndarray, p: int, b: np.ndarray) -> np.ndarray:
    """x with L L^T x = b (:func:`_banded_cholesky`): L z = b forwards, then L^T x = z backwards."""
    n = len(b)
    z = np.empty(n)
    for j in range(n):
        start = max(0, j - p)
        z[j] = (b[j] - low[j, start:j] @ z[start:j]) / low[j, j]
    x = np.empty(n)
    for j in range(n - 1, -1, -1):
        end = min(n, j + p + 1)
        x[j] = (z[j] - low[j + 1 : end, j] @ x[j + 1 : end]) / low[j, j]
    return x


def fit_texels(n_dot_l, n_dot_v, y, smoothness: float = SMOOTHNESS, width: int = WIDTH, height: int = HEIGHT):
    """The non-negative slice ``(height, width, C)`` whose bilinear lookups best match ``y`` ``(N, C)``.

    Minimises sum_s (y_s - sum_k w_sk x_k)^2 + lambda |D x|^2 per channel, w_sk the bilinear
    weights of sample s (:func:`bilinear_stencil`), D the second differences along both slice
    axes and lambda = ``smoothness`` * N / (width * height), subject to x >= 0: the normal
    equations (2048 unknowns, banded: :func:`_banded_cholesky`) are solved on the free texels, texels that come out
    negative are fixed at 0, and the solve repeated until none is negative (an active-set
    scheme that only ever adds constraints). With samples of a bilinear function of
    (N.L, N.V) the penalty is 0 at the truth, so it is returned exactly.
    """
    y = np.asarray(y, dtype=np.float64)
    y = y[:, None] if y.ndim == 1 else y
    index, weight = bilinear_stencil(n_dot_l, n_dot_v, width, height)
    k = width * height
    # A sample's four texels are its first one plus fixed offsets (0, 1, W, W + 1), so the
    # normal matrix gathers per first texel: 16 bincounts of length k, not of length k^2.
    base = index[:, 0]
    offsets = index[0] - index[0, 0]
    normal = smoothness * len(y) / k * _second_differences(width, height)
    rows = np.arange(k)
    for i in range(4):
        for j in range(4):
            total = np.bincount(base, weight[:, i] * weight[:, j], minlength=k)
            reached = rows[total != 0.0]
            normal[reached + offsets[i], reached + offsets[j]] += total[reached]
    rhs_all = np.zeros((k, y.shape[1]))
    for i in range(4):
        for c in range(y.shape[1]):
            rhs_all[:, c] += np.bincount(index[:, i], weight[:, i] * y[:, c], minlength=k)
    out = np.zeros((k, y.shape[1]))
    factors = {}  # free set -> Cholesky factor: channels (and fits) with the same free set share it
    for c in range(y.shape[1]):
        free = np.ones(k, dtype=bool)
        while True:
            key = free.tobytes()
            if key not in factors:
                factors[key] = _banded_cholesky(normal[np.ix_(free, free)])
            x = np.zeros(k)
            x[free] = _banded_solve(*factors[key], rhs_all[free, c])
            negative = x < 0.0
            if not negative.any():
                break
            free &= ~negative
        out[:, c] = x
    return out.reshape(height, width, y.shape[1])


def _mitsuba():
    """Mitsuba in ``llvm_ad_rgb``, or :class:`BackendError` saying what is missing."""
    with deferred_interrupts():  # a Ctrl-C during start-up is raised once it is over
        try:
            import mitsuba as mi

            if mi.variant() != "llvm_ad_rgb":
                mi.set_variant("llvm_ad_rgb")
        except Exception as exc:  # ImportError, or no libLLVM
            first = (str(exc).splitlines() or [type(exc).__name__])[0]
            raise BackendError(f"Mitsuba 3 llvm_ad_rgb is unavailable ({first}); the sss physical fit renders with it") from None
    return mi


def render_sphere_samples(
    medium: dict, integrator: dict, origins, directions, seed: int, radius: float = OBJECT_RADIUS
) -> np.ndarray:
    """Radiance ``(N, 3)`` along each ray into the sphere of ``radius`` and ``medium`` lit from +z (unit irradiance),
    by Mitsuba's ``llvm_ad_rgb`` ``integrator``, one independent sample per ray, Mitsuba seed ``seed``."""
    mi = _mitsuba()
    # A symbolic loop (volpath's) traces every live Python plugin instance: free them first.
    gc.collect()
    scene = mi.load_dict({
        "type": "scene",
        "sphere": {"type": "sphere", "radius": float(radius), "bsdf": {"type": "null"}, "interior": medium},
        "light": {"type": "directional", "direction": [0.0, 0.0, -1.0], "irradiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
    })  # fmt: skip
    integ = mi.load_dict(integrator)
    origins = np.asarray(origins, dtype=np.float32)
    directions = np.asarray(directions, dtype=np.float32)
    out = np.empty((len(origins), 3))
    for batch, start in enumerate(range(0, len(origins), _BATCH)):
        o, d = origins[start : start + _BATCH], directions[start : start + _BATCH]
        sampler = mi.load_dict({"type": "independent"})
        # One stream per ray: the seed names the render and the batch.
        sampler.seed(int(seed) * 1_000_003 + batch, len(o))
        ray = mi.Ray3f(mi.Point3f(*[mi.Float(np.ascontiguousarray(o[:, i])) for i in range(3)]),
                       mi.Vector3f(*[mi.Float(np.ascontiguousarray(d[:, i])) for i in range(3)]))  # fmt: skip
        spectrum, _, _ = integ.sample(scene, sampler, ray, None, True)
        out[start : start + _BATCH] = np.array(spectrum, dtype=np.float64).reshape(3, -1).T
    del scene, integ
    return out


def _relative_rms_between(a, b, stencil) -> float:
    """Relative RMS of slice ``a`` against ``b`` looked up at the samples (uniform (l, v) pairs)."""
    index, weight = stencil
    la = (a.reshape(-1, a.shape[-1])[index] * weight[..., None]).sum(1)
    lb = (b.reshape(-1, b.shape[-1])[index] * weight[..., None]).sum(1)
    return float(np.sqrt(np.mean((la - lb) ** 2) / np.mean(lb * lb)))


def _render_geometry(medium, integrator, specular, gloss, radius, passes, seed):
    """Configurations of one sphere (``radius``, jitter ``seed``) and y = pi (L - A f_s cos) of both Mitsuba seeds' renders."""
    nl, nv, phi = sample_configurations(passes, seed=seed)
    origins, directions = sphere_rays(nl, nv, phi, radius)
    l, v, nh, degenerate = local_directions(nl, nv, phi)
    lobe = specular_f_cos(gloss, l[:, 2], v[:, 2], nh, degenerate)[:, None]  # the renderer's f_s cos
    renders = [render_sphere_samples(medium, integrator, origins, directions, s, radius) for s in FIT_SEEDS]
    # y = pi (L - A f_s cos): the diffuse part the slice's RGB must supply.
    return nl, nv, [np.pi * (r - float(specular) * lobe) for r in renders]


def _noise_free_error(slice_rgb, stencil, ys) -> float:
    """Relative RMS of the slice against the renders y of two seeds: sqrt(mean(r0 r1) / mean(y0 y1)), r the
    residuals (the seeds' noise is independent, so it averages out of the product)."""
    index, weight = stencil
    looked_up = (np.asarray(slice_rgb).reshape(-1, 3)[index] * weight[..., None]).sum(1)
    r0, r1 = ys[0] - looked_up, ys[1] - looked_up
    return float(np.sqrt(max(np.mean(r0 * r1), 0.0) / np.mean(ys[0] * ys[1])))


def fit_sss_slice(medium: dict, integrator: dict, specular: float, gloss: float, passes: int = FIT_PASSES, model_rgb=None):
    """The ``(HEIGHT, WIDTH, 4)`` slice fitted to volpath renders of the spheres of :data:`FIT_RADII` filled
    with ``medium``, and a dict describing the fit (module docstring): ``spp`` (renders per configuration
    and seed), ``rays``, ``light_directions``, ``seeds``, ``fit_radii``, ``relative_rms`` (in sample: on the
    fitted spheres), ``seed_disagreement_relative_rms``, ``noise_relative_rms``, ``out_of_sample``
    (the same measure on fresh configurations of each geometry of :data:`SCORE_RADII`, which the fit
    never saw: ``{name: {"radius", "rays", "relative_rms"[, "model_relative_rms"]}}``), and with
    ``model_rgb`` (the closed form's ``(HEIGHT, WIDTH, 3)`` slice) ``model_relative_rms``, that slice's
    error measured as the fit's; and the renders' wall seconds (not part of the slice: timings vary).

    The fitted spheres share ``passes`` between them; each scored geometry gets
    ``passes * SCORE_PASSES / FIT_PASSES`` (at least 1), with jitter seeds of its own.
    """
    t0 = time.perf_counter()
    per_radius = max(1, int(passes) // len(FIT_RADII))
    parts = [
        _render_geometry(medium, integrator, specular, gloss, r, per_radius, GEOMETRY_SEED + k) for k, r in enumerate(FIT_RADII)
    ]
    nl = np.concatenate([p[0] for p in parts])
    nv = np.concatenate([p[1] for p in parts])
    ys = [np.concatenate([p[2][s] for p in parts]) for s in range(len(FIT_SEEDS))]
    # The three fits share their normal matrix (same configurations): one call, nine columns.
    fits = fit_texels(nl, nv, np.concatenate([0.5 * (ys[0] + ys[1]), ys[0], ys[1]], axis=1))
    rgb, single = fits[..., :3], (fits[..., 3:6], fits[..., 6:])
    stencil = bilinear_stencil(nl, nv)
    disagreement = _relative_rms_between(single[0], single[1], stencil) / np.sqrt(2.0)
    scored = {}
    score_passes = max(1, int(passes) * SCORE_PASSES // FIT_PASSES)
    for k, (name, radius) in enumerate(SCORE_RADII):
        snl, snv, sys_ = _render_geometry(medium, integrator, specular, gloss, radius, score_passes, GEOMETRY_SEED + 100 + k)
        score_stencil = bilinear_stencil(snl, snv)
        scored[name] = {
            "radius": float(radius),
            "rays": int(len(snl)),
            "relative_rms": _noise_free_error(rgb, score_stencil, sys_),
        }
        if model_rgb is not None:
            scored[name]["model_relative_rms"] = _noise_free_error(model_rgb, score_stencil, sys_)
    seconds = time.perf_counter() - t0
    rgba = np.concatenate([rgb, np.full((HEIGHT, WIDTH, 1), float(specular))], -1)
    info = {
        "spp": 1,
        "passes": int(per_radius * len(FIT_RADII)),
        "rays": int(len(nl)),
        "light_directions": 1,
        "seeds": list(FIT_SEEDS),
        "fit_radii": [float(r) for r in FIT_RADII],
        "relative_rms": _noise_free_error(rgb, stencil, ys),
        # Two slices differing by independent noise: their RMS difference over sqrt(2) is
        # one slice's noise, and the slice fitted to both has half their variance.
        "seed_disagreement_relative_rms": float(np.sqrt(2.0) * disagreement),
        "noise_relative_rms": float(disagreement / np.sqrt(2.0)),
        "out_of_sample": scored,
    }
    if model_rgb is not None:
        info["model_relative_rms"] = _noise_free_error(model_rgb, stencil, ys)
    return rgba, info, seconds


@lru_cache(maxsize=8)
def _cached(key: str):
    args = json.loads(key)
    model_rgb = None if args["model_rgb"] is None else np.asarray(args["model_rgb"], dtype=np.float64)
    rgba, info, seconds = fit_sss_slice(args["medium"], args["integrator"], args["specular"], args["gloss"], args["passes"],
                                        model_rgb)  # fmt: skip
    rgba.setflags(write=False)
    return rgba, info, seconds


def fitted_sss_slice(medium: dict, integrator: dict, specular: float, gloss: float, passes: int = FIT_PASSES, model_rgb=None):
    """:func:`fit_sss_slice`, cached per arguments (the renders cost tens of seconds)."""
    model = None if model_rgb is None else np.asarray(model_rgb, dtype=np.float64).tolist()
    key = json.dumps({"medium": medium, "integrator": integrator, "specular": float(specular), "gloss": float(gloss),
                      "passes": int(passes), "model_rgb": model}, sort_keys=True)  # fmt: skip
    return _cached(key)
