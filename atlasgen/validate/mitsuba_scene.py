"""A renderer scene (:mod:`atlasgen.materials.scene`) as a Mitsuba 3 scene, for pixel-by-pixel comparison.

What is kept identical, so that only the shading differs:

- **Camera.** Mitsuba's ``perspective`` sensor with ``fov_axis = "x"``, built by
  ``look_at(position, target, up)`` with the renderer's near and far planes; the
  renderer's camera follows the same conventions (:mod:`atlasgen.render.camera`).
- **Sampling.** A ``stratified`` sampler without jitter and a ``box`` reconstruction
  filter: with one sample per pixel the ray goes through the pixel centre, as the
  rasteriser's g-buffer sample does. With N = k^2 samples they sit at the centres of a
  k x k grid and the box filter averages them (an anti-aliased reference). Stochastic
  references (``volpath``, and spectral ones, whose wavelengths are drawn from the sampler
  per sample) use the ``independent`` sampler, so every sample draws its own paths and
  wavelengths, and two seeds give independent renders (their noise floor); they are
  rendered by :func:`render_pixel_centres`, every camera ray through its pixel's centre,
  so that their many samples do not antialias what the one-sample rasteriser shows.
- **Geometry.** The renderer's own triangle meshes (:func:`atlasgen.render.meshes.build_mesh`)
  in world space, with the renderer's normal transform (inverse transpose, not
  renormalised per vertex), so interpolated shading normals match the g-buffer's.
- **Lights.** ``point`` -> Mitsuba ``point`` with ``intensity`` = colour * intensity
  (W/sr, falls off as I/d^2); ``spot`` -> ``spot`` with the same intensity on its axis,
  ``cutoff_angle`` = outer and ``beam_width`` = inner angle (the renderer's spot falloff is
  Mitsuba's, :func:`atlasgen.optics.falloff.spot_factor`); ``directional`` -> ``directional``
  with ``irradiance`` = colour * intensity, travelling along the same direction. A light's
  ``range`` has no Mitsuba counterpart: ``atlasgen_direct`` applies its window
  (:func:`atlasgen.optics.falloff.range_window`) to that emitter's sample, so the references
  fall off exactly as the renderer does (:func:`light_ranges`).
- **Integration.** Direct lighting only, and without the visibility test: the deferred
  renderer casts no shadows, so :class:`DirectNoShadow` (registered as
  ``atlasgen_direct``) evaluates every emitter at every hit point. That also checks
  back-lighting on closed geometry, where Mitsuba's ``direct`` would see the far side
  of a sphere shadow its own back-lit front.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from atlasgen.errors import SceneError
from atlasgen.materials.environment import mitsuba_emitter
from atlasgen.materials.scene import object_matrix
from atlasgen.optics.low_discrepancy import halton_points
from atlasgen.render.environment import IMAGE_HEIGHT
from atlasgen.render.meshes import build_mesh

__all__ = [
    "render_pixel_centres",
    "render_environment_qmc",
    "object_mask",
    "SLAB_DIFFUSION_LENGTHS",
    "diffusion_length",
    "slab_object",
    "DIRECT_INTEGRATOR",
    "SHADOW_INTEGRATOR",
    "register_direct_integrator",
    "register_shadow_integrator",
    "cast_shadow_mask",
    "sensor_dict",
    "emitter_dicts",
    "light_ranges",
    "mitsuba_mesh",
    "build_mitsuba_scene",
    "render_mitsuba",
]

DIRECT_INTEGRATOR = "atlasgen_direct"
SHADOW_INTEGRATOR = "atlasgen_cast_shadow"
_registered: set = set()


def register_direct_integrator(mi) -> str:
    """Register :class:`DirectNoShadow` as ``atlasgen_direct`` for the current variant; return its name.

    For a hit point x with shading frame (n at +z), view direction w_i and each emitter
    e sampled deterministically (point and directional emitters are delta lights, so one
    sample is exact), the pixel value is

        L(x, w_i) = sum_e f(w_i, w_o,e) cos(theta_o,e) E_e(x),

    with E_e = I / d^2 for a point and E for a directional emitter, and no shadow ray.
    An emitter named in the ``light_ranges`` property (:func:`light_ranges`) is scaled by the
    renderer's range window W(d, r) = saturate(1 - (d/r)^4)^2, and is 0 at and beyond d = r.
    Rays that miss every shape return the constant ``background`` radiance.
    """
    variant = mi.variant()
    if (variant, DIRECT_INTEGRATOR) in _registered:
        return DIRECT_INTEGRATOR
    import drjit as dr

    class DirectNoShadow(mi.SamplingIntegrator):
        def __init__(self, props):
            mi.SamplingIntegrator.__init__(self, props)
            self.background = [props.get(f"background_{c}", 0.0) for c in "rgb"]
            text = props.get("light_ranges", "")
            self.ranges = {k: float(v) for k, v in (item.split("=") for item in text.split(";") if item)}

        def sample(self, scene, sampler, ray, medium=None, active=True):
            si = scene.ray_intersect(ray, active)
            hit = si.is_valid()
            bsdf = si.bsdf(ray)
            ctx = mi.BSDFContext()
            result = mi.Spectrum(0.0)
            for emitter in scene.emitters():
                # An environment: infinite and not a delta light (a directional emitter is infinite too).
                if mi.has_flag(emitter.flags(), mi.EmitterFlags.Infinite) and not mi.has_flag(
                    emitter.flags(), mi.EmitterFlags.Delta
                ):
                    result += _environment_estimate(mi, dr, emitter, bsdf, ctx, si, sampler, hit)
                    continue
                ds, weight = emitter.sample_direction(si, mi.Point2f(0.5, 0.5), hit)
                light_range = self.ranges.get(emitter.id())
                if light_range is not None:
                    x = ds.dist / light_range
                    weight *= dr.select(x < 1.0, dr.square(dr.clip(1.0 - dr.square(dr.square(x)), 0.0, 1.0)), 0.0)
                wo = si.to_local(ds.d)
                value = bsdf.eval(ctx, si, wo, hit)
                result += dr.select(hit & (ds.pdf > 0), value * weight, 0.0)
            if any(self.background):
                bg = (
                    mi.Spectrum(mi.Color3f(*self.background))
                    if mi.is_rgb
                    else mi.Spectrum(mi.srgb_model_eval(mi.srgb_model_fetch(mi.ScalarColor3f(*self.background)), ray.wavelengths))
                )
                result = dr.select(hit, result, bg)
            return result, hit, []

        def aov_names(self):
            return []

        def to_string(self):
            return "DirectNoShadow[]"

    mi.register_integrator(DIRECT_INTEGRATOR, lambda props: DirectNoShadow(props))
    _registered.add((variant, DIRECT_INTEGRATOR))
    return DIRECT_INTEGRATOR


#: Balance-heuristic count of the emitter's own samples against one cosine sample (:func:`_environment_estimate`):
#: a ``constant`` emitter samples the sphere uniformly, which only adds variance to a cosine-shaped integrand, so it
#: weighs little; an ``envmap`` (a sun) needs its importance sampling.
ENVIRONMENT_EMITTER_WEIGHT = {"constant": 0.05, "envmap": 1.0}


def _environment_estimate(mi, dr, emitter, bsdf, ctx, si, sampler, active):
    """One unbiased estimate of int f(w_i, l) cos L(l) dl over the whole sphere, without a visibility test.

    Two samples, combined by the balance heuristic (Veach 1997, eq. 9.10) with counts c_c = 1 and c_e
    (:data:`ENVIRONMENT_EMITTER_WEIGHT`): l_c from the cosine-weighted upper hemisphere, p_c = max(cos, 0) / pi,
    and l_e from the emitter, p_e = ``pdf_direction`` (uniform for ``constant``, luminance for ``envmap``):

        F = sum_{t in (c, e)} c_t f(l_t) cos L(l_t) / (c_c p_c(l_t) + c_e p_e(l_t)).

    The weights c_t p_t / (c_c p_c + c_e p_e) sum to 1 wherever either density is positive, and p_e > 0 wherever
    L > 0, so F is unbiased for reflection and transmission (N.L < 0) alike; the renderer, which neither
    shadows nor occludes its environment, is compared with exactly this integral.
    """
    c_e = ENVIRONMENT_EMITTER_WEIGHT["constant" if emitter.class_name().startswith("Constant") else "envmap"]

    def emitted(d):
        ds = dr.zeros(mi.DirectionSample3f)
        ds.d = d
        it = dr.zeros(mi.SurfaceInteraction3f)
        it.wi = -d
        it.wavelengths = si.wavelengths
        return emitter.eval(it, active), emitter.pdf_direction(si, ds, active)

    wo_c = mi.warp.square_to_cosine_hemisphere(sampler.next_2d(active))
    value_c, pdf_e_c = emitted(si.to_world(wo_c))
    f_c = bsdf.eval(ctx, si, wo_c, active)
    den_c = mi.warp.square_to_cosine_hemisphere_pdf(wo_c) + c_e * pdf_e_c
    ds_e, weight_e = emitter.sample_direction(si, sampler.next_2d(active), active)
    wo_e = si.to_local(ds_e.d)
    f_e = bsdf.eval(ctx, si, wo_e, active)
    den_e = mi.warp.square_to_cosine_hemisphere_pdf(wo_e) + c_e * ds_e.pdf
    part_c = dr.select(den_c > 0, f_c * value_c / den_c, 0.0)
    part_e = dr.select((den_e > 0) & (ds_e.pdf > 0), c_e * f_e * weight_e * ds_e.pdf / den_e, 0.0)
    return dr.select(active, part_c + part_e, 0.0)


def register_shadow_integrator(mi) -> str:
    """Register ``atlasgen_cast_shadow`` for the current variant; return its name.

    Per pixel (one ray through its centre) it returns 1 where the visible point is in the
    cast shadow of *another* shape for at least one emitter, else 0: what a renderer with
    shadows shows and the deferred renderer cannot. A shape's shadow on itself (a sphere's
    far side) is not counted: transport through the object is what a volumetric reference
    is for.
    """
    variant = mi.variant()
    if (variant, SHADOW_INTEGRATOR) in _registered:
        return SHADOW_INTEGRATOR
    import drjit as dr

    class CastShadow(mi.SamplingIntegrator):
        def sample(self, scene, sampler, ray, medium=None, active=True):
            si = scene.ray_intersect(ray, active)
            hit = si.is_valid()
            shadowed = mi.Bool(False)
            for emitter in scene.emitters():
                ds, _ = emitter.sample_direction(si, mi.Point2f(0.5, 0.5), hit)
                blocker = scene.ray_intersect(si.spawn_ray_to(ds.p), hit & (ds.pdf > 0))
                shadowed |= blocker.is_valid() & (blocker.shape != si.shape)
            return mi.Spectrum(dr.select(hit & shadowed, 1.0, 0.0)), hit, []

        def aov_names(self):
            return []

        def to_string(self):
            return "CastShadow[]"

    mi.register_integrator(SHADOW_INTEGRATOR, lambda props: CastShadow(props))
    _registered.add((variant, SHADOW_INTEGRATOR))
    return SHADOW_INTEGRATOR


def cast_shadow_mask(mi, scene) -> np.ndarray:
    """``(h, w)`` bool: pixels in another object's cast shadow (:func:`register_shadow_integrator`).

    Rendered in ``llvm_ad_rgb`` with diffuse stand-ins (shadows do not depend on the BSDFs).
    """
    mi.set_variant("llvm_ad_rgb")
    integrator = {"type": register_shadow_integrator(mi)}
    mi_scene = build_mitsuba_scene(mi, scene, [{"type": "diffuse"}] * len(scene.objects), 1, integrator)
    image, _ = render_mitsuba(mi, mi_scene, 1, python_plugins=False)
    return image[..., 0] > 0.5


def object_mask(mi, scene, indices) -> np.ndarray:
    """``(h, w)`` bool: pixels whose pixel-centre ray first meets one of the objects ``indices``.

    Those objects glow (a unit ``area`` emitter), every object is black, and a one-bounce
    ``path`` render at pixel centres sees the glow exactly where they are visible.
    """
    mi.set_variant("llvm_ad_rgb")
    black = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}
    d = {"type": "scene", "integrator": {"type": "path", "max_depth": 1}, "sensor": sensor_dict(mi, scene, 1)}
    for obj in scene.objects:
        emitter = {"type": "area", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}} if obj.index in indices else None
        d[f"object_{obj.index:04d}"] = mitsuba_mesh(mi, obj, black, emitter=emitter)
    image, _ = render_mitsuba(mi, mi.load_dict(d), 1, python_plugins=False)
    return image[..., 0] > 0.5


#: Depth of a plane's slab, and its margin beyond the plane's edges, in the medium's longest
#: diffusion length (:func:`diffusion_length`): the fluence falls as exp(-z / L), so light that
#: reaches the slab's bottom or sides carries exp(-10), about 5e-5, of what entered.
SLAB_DIFFUSION_LENGTHS = 10.0


def diffusion_length(medium: dict) -> float:
    """The longest diffusion length L = 1 / sigma_tr of a ``homogeneous`` medium dict (as
    :func:`atlasgen.models.sss.skin_medium` writes it), over the RGB channels, in scene units.

    sigma_tr = sqrt(3 sigma_a sigma_t') is the diffusion approximation's effective attenuation
    (Jensen et al., "A Practical Model for Subsurface Light Transport", SIGGRAPH 2001, eq. 7),
    with sigma_t' = sigma_t for the isotropic phase function and sigma_a = sigma_t (1 - albedo).
    A channel that absorbs nothing (albedo 1) has no finite L; every channel's L is capped at
    100 mean free paths, 100 / sigma_t.
    """
    sigma_t = np.asarray(medium["sigma_t"]["value"], dtype=np.float64) * float(medium.get("scale", 1.0))
    albedo = np.asarray(medium["albedo"]["value"], dtype=np.float64)
    sigma_a = sigma_t * np.clip(1.0 - albedo, 0.0, 1.0)
    with np.errstate(divide="ignore"):
        length = 1.0 / np.sqrt(3.0 * sigma_a * sigma_t)
    return float(np.max(np.minimum(length, 100.0 / sigma_t)))


def slab_object(plane, depth: float):
    """A ``box`` :class:`~atlasgen.materials.scene.SceneObject` whose top face holds ``plane`` (a
    ``plane`` object: the square [-1, 1]^2 of the xz plane facing +y, under its transform), grown by
    ``depth`` beyond each of the plane's edges and ``depth`` deep below it, along its normal.

    In the plane's frame the box is [-(s_x + d), s_x + d] x [-d, 0] x [-(s_z + d), s_z + d]: the
    box [-1, 1]^3 scaled by (s_x + d, d / 2, s_z + d), in the plane's rotation, and moved down by d / 2
    along the plane's normal, so that its top face lies exactly in the plane. A medium inside it
    is a flat part of skin as far as light inside it can tell (:data:`SLAB_DIFFUSION_LENGTHS`)."""
    sx, _, sz = (float(c) for c in plane.scale)
    d = float(depth)
    box = replace(plane, shape="box", scale=(sx + math.copysign(d, sx), 0.5 * d, sz + math.copysign(d, sz)),
                  translate=(0.0, 0.0, 0.0))  # fmt: skip
    down = object_matrix(replace(box, scale=(1.0, 1.0, 1.0)))[:3, :3] @ np.array([0.0, -0.5 * d, 0.0])
    return replace(box, translate=tuple(float(a) for a in np.asarray(plane.translate, dtype=np.float64) + down))


def sensor_dict(mi, scene, spp: int = 1, stochastic: bool = False) -> dict:
    """Mitsuba ``perspective`` sensor matching the renderer's camera and image size.

    ``stochastic`` picks the ``independent`` sampler (random samples, a seed per render)
    instead of the pixel-centre grid."""
    cam = scene.camera
    return {
        "type": "perspective",
        "fov": float(cam.fov),
        "fov_axis": "x",
        "near_clip": float(cam.near),
        "far_clip": float(cam.far),
        "to_world": mi.ScalarTransform4f().look_at(
            origin=[float(c) for c in cam.position], target=[float(c) for c in cam.target], up=[float(c) for c in cam.up]
        ),
        "film": {
            "type": "hdrfilm",
            "width": int(scene.width),
            "height": int(scene.height),
            "rfilter": {"type": "box"},
            "pixel_format": "rgb",
            "component_format": "float32",
        },
        "sampler": {"type": "independent", "sample_count": int(spp)}
        if stochastic
        else {"type": "stratified", "sample_count": int(spp), "jitter": False},
    }


def emitter_dicts(scene) -> dict:
    """The scene's lights as Mitsuba emitter dicts, in the renderer's units, and its environment
    (:func:`atlasgen.materials.environment.mitsuba_emitter`, a sky at the renderer's image size, so
    both light with the same image)."""
    out = {}
    if getattr(scene, "environment", None) is not None:
        out["environment"] = mitsuba_emitter(scene.environment, IMAGE_HEIGHT)
    for i, light in enumerate(scene.lights):
        value = {"type": "rgb", "value": [float(c) * float(light.intensity) for c in light.colour]}
        if light.type == "point":
            out[f"light_{i:04d}"] = {"type": "point", "position": [float(c) for c in light.position], "intensity": value}
        elif light.type == "spot":
            position = np.asarray(light.position, dtype=np.float64)
            axis = np.asarray(light.direction, dtype=np.float64)
            up = [0.0, 1.0, 0.0] if abs(axis[1]) < 0.9 else [1.0, 0.0, 0.0]
            out[f"light_{i:04d}"] = {
                "type": "spot",
                "to_world": look_at_transform(position, position + axis, up),
                "cutoff_angle": float(light.outer_angle),
                "beam_width": float(light.inner_angle),
                "intensity": value,
            }
        else:
            out[f"light_{i:04d}"] = {
                "type": "directional",
                "direction": [float(c) for c in light.direction],
                "irradiance": value,
            }
    return out


def look_at_transform(origin, target, up):
    """Mitsuba's ``ScalarTransform4f().look_at``, with the variant already set by the caller."""
    import mitsuba as mi

    return mi.ScalarTransform4f().look_at(
        origin=[float(c) for c in origin], target=[float(c) for c in target], up=[float(c) for c in up]
    )


def light_ranges(scene) -> str:
    """``atlasgen_direct``'s ``light_ranges`` property: ``light_NNNN=range`` for each light with a range, ``;``-separated
    (the emitters' names in :func:`emitter_dicts`)."""
    return ";".join(f"light_{i:04d}={float(light.range)!r}" for i, light in enumerate(scene.lights) if light.bounded)


def world_mesh_arrays(obj):
    """World-space positions, normals (inverse transpose, not renormalised) and faces of ``obj``."""
    mesh = build_mesh(obj)
    m = object_matrix(obj)
    normal_matrix = np.linalg.inv(m[:3, :3]).T
    positions = mesh.positions.astype(np.float64) @ m[:3, :3].T + m[:3, 3]
    normals = mesh.normals.astype(np.float64) @ normal_matrix.T
    return positions, normals, mesh.indices


def mitsuba_mesh(mi, obj, bsdf=None, interior=None, name=None, emitter=None):
    """A Mitsuba ``Mesh`` holding exactly the renderer's triangles for ``obj``.

    ``bsdf`` is a BSDF instance or dict; ``interior`` an optional medium (instance or
    dict), for volumetric references.
    """
    import drjit as dr

    positions, normals, faces = world_mesh_arrays(obj)
    props = mi.Properties()
    if bsdf is not None:
        props["bsdf"] = bsdf if not isinstance(bsdf, dict) else mi.load_dict(bsdf)
    if interior is not None:
        props["interior"] = interior if not isinstance(interior, dict) else mi.load_dict(interior)
    if emitter is not None:
        props["emitter"] = mi.load_dict(emitter)
    mesh = mi.Mesh(name or f"object_{obj.index}", len(positions), len(faces), props, has_vertex_normals=True)
    params = mi.traverse(mesh)
    f32 = [np.ascontiguousarray(positions[:, k], dtype=np.float32) for k in range(3)]
    n32 = [np.ascontiguousarray(normals[:, k], dtype=np.float32) for k in range(3)]
    idx = [np.ascontiguousarray(faces[:, k], dtype=np.uint32) for k in range(3)]
    params["vertex_positions"] = dr.ravel(mi.Point3f(*[mi.Float(a) for a in f32]))
    params["vertex_normals"] = dr.ravel(mi.Normal3f(*[mi.Float(a) for a in n32]))
    params["faces"] = dr.ravel(mi.Vector3u(*[mi.UInt32(a) for a in idx]))
    params.update()
    return mesh


def build_mitsuba_scene(mi, scene, bsdfs, spp: int = 1, integrator: dict | None = None, interiors=None, stochastic: bool = False):
    """Load the Mitsuba twin of ``scene``.

    Parameters
    ----------
    mi
        The ``mitsuba`` module with a variant set (:func:`atlasgen.validate.backend.load_mitsuba`).
    scene
        A :class:`atlasgen.materials.scene.Scene`.
    bsdfs
        One BSDF (dict or instance) per object, in object order.
    integrator
        Defaults to ``atlasgen_direct`` with the scene's background.
    interiors
        Optional per-object interior media (``None`` entries for none).
    stochastic
        Sample with the ``independent`` sampler (:func:`sensor_dict`).
    """
    if integrator is None:
        register_direct_integrator(mi)
        bg = [float(c) for c in scene.background]
        integrator = {"type": DIRECT_INTEGRATOR, "background_r": bg[0], "background_g": bg[1], "background_b": bg[2],
                      "light_ranges": light_ranges(scene)}  # fmt: skip
    elif integrator.get("type") != SHADOW_INTEGRATOR:
        # Only atlasgen_direct windows a range: any other integrator would light beyond it.
        bounded = [i for i, light in enumerate(scene.lights) if light.bounded]
        if bounded:
            raise SceneError(scene.path, f"lights[{bounded[0]}].range",
                             f"the {integrator.get('type')!r} reference cannot apply a light's range; expected lights without one")  # fmt: skip
    d = {"type": "scene", "integrator": integrator, "sensor": sensor_dict(mi, scene, spp, stochastic)}
    d.update(emitter_dicts(scene))
    interiors = interiors or [None] * len(scene.objects)
    for obj, bsdf, interior in zip(scene.objects, bsdfs, interiors):
        d[f"object_{obj.index:04d}"] = mitsuba_mesh(mi, obj, bsdf, interior)
    return mi.load_dict(d)


def render_mitsuba(mi, mi_scene, spp: int = 1, seed: int = 0, python_plugins: bool = True) -> tuple[np.ndarray, float]:
    """Render and return ``(linear RGB (h, w, 3) float32, wall seconds)``.

    With ``python_plugins`` virtual function calls are evaluated in wavefront mode
    (``SymbolicCalls`` off), so atlasgen's Python BSDFs receive concrete arrays they
    can hand to NumPy; scenes of built-in plugins only keep Mitsuba's default.
    """
    import drjit as dr

    t0 = time.perf_counter()
    with dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, not python_plugins):
        image = mi.render(mi_scene, spp=int(spp), seed=int(seed))
        rgb = np.array(image, dtype=np.float32)
    seconds = time.perf_counter() - t0
    if rgb.ndim == 3 and rgb.shape[2] > 3:
        rgb = rgb[..., :3]
    return rgb, seconds


#: Samples per pixel traced in one pass of :func:`render_pixel_centres` (bounds its memory).
CENTRE_PASS_SPP = 64


def render_pixel_centres(
    mi, mi_scene, spp: int, seed: int = 0, python_plugins: bool = True, first_sample: int = 0, pixels=None
) -> tuple[np.ndarray, float]:
    """Render with every sample's camera ray through its pixel's centre: ``(linear RGB (h, w, 3), seconds)``.

    A stochastic reference needs many samples per pixel (paths, wavelengths), but the
    deferred renderer shades one point per pixel, its centre. ``mi.render`` spreads the
    samples over the pixel's footprint, which antialiases silhouettes and thin highlights
    the atlas image cannot: that difference would count as the material's error. So the
    scene's integrator is called directly here, ``spp`` times per pixel, on rays through
    the pixel centres; only the rest of each path (and the wavelengths, in a spectral
    variant) is random. Samples are averaged with equal weights, as the box filter does
    within a pixel; a spectral variant converts each sample to linear sRGB with its
    wavelengths (``mi.spectrum_to_srgb``), as the film does.

    ``first_sample`` numbers the first of the ``spp`` samples: a render of samples
    [n, n + m) draws none of [0, n)'s random numbers, so the two average, weighted n : m,
    to the render of n + m samples.

    ``pixels`` (``(h, w)`` bool) traces only those pixels and leaves the others 0: a reference
    composed of renders of one object each (:func:`atlasgen.validate.run.render_physical`)
    traces each object's render where that object is seen, not across the frame.
    """
    import drjit as dr

    t0 = time.perf_counter()
    sensor = mi_scene.sensors()[0]
    width, height = (int(c) for c in sensor.film().crop_size())
    integrator = mi_scene.integrator()
    total = np.zeros((height * width, 3), dtype=np.float64)
    traced = None if pixels is None else np.flatnonzero(np.asarray(pixels, dtype=bool).reshape(-1)).astype(np.uint32)
    n_pixels = width * height if traced is None else len(traced)
    done, end = int(first_sample), int(first_sample) + int(spp)
    if n_pixels == 0:
        done = end
    with dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, not python_plugins):
        while done < end:
            batch = min(CENTRE_PASS_SPP, end - done)
            count = n_pixels * batch
            sampler = sensor.sampler().clone()
            sampler.set_sample_count(batch)
            # One seed per pass and render: passes must not repeat each other's samples.
            sampler.seed(int(seed) * 1_000_003 + done, count)
            pixel = dr.arange(mi.UInt32, count) // batch
            if traced is not None:
                pixel = dr.gather(mi.UInt32, mi.UInt32(traced), pixel)
            centre = mi.Point2f((mi.Float(pixel % width) + 0.5) / width, (mi.Float(pixel // width) + 0.5) / height)
            ray, weight = sensor.sample_ray_differential(0.0, sampler.next_1d(), centre, mi.Point2f(0.5, 0.5))
            radiance, _, _ = integrator.sample(mi_scene, sampler, ray, None, True)
            value = weight * radiance
            rgb = mi.spectrum_to_srgb(value, ray.wavelengths) if mi.is_spectral else value
            samples = np.stack([np.array(rgb[k], dtype=np.float64) for k in range(3)], axis=-1)
            summed = samples.reshape(n_pixels, batch, 3).sum(axis=1)
            if traced is None:
                total += summed
            else:
                total[traced] += summed
            done += batch
    image = (total / spp).reshape(height, width, 3).astype(np.float32)
    return image, time.perf_counter() - t0


#: Halton coordinates in the order render_environment_qmc uses them under an ``envmap``: the emitter's last.
_EMITTER_FIRST = [2, 3, 4, 5, 6, 0, 1]


def render_environment_qmc(mi, mi_scene, spp: int, seed: int = 0, first_sample: int = 0) -> tuple[np.ndarray, float]:
    """A scene lit by its environment alone, as :func:`render_pixel_centres` renders it, by importance sampling
    the BSDF (and the emitter) on randomised quasi-Monte Carlo points: ``(linear RGB (h, w, 3), seconds)``.

    Per pixel (its centre's ray, as the g-buffer samples it), sample k of the integral of f cos L over the whole
    sphere, without a visibility test (as :class:`DirectNoShadow`), takes point k of the 7-D Halton sequence
    shifted by ``seed`` (:func:`atlasgen.optics.low_discrepancy.halton_points`) and draws three directions:
    w_b from ``bsdf.sample`` (coordinates 1-3: the BSDF's own lobe choice and direction, on w_i's side),
    w_o cosine-distributed on the other side (4-5: light through the surface, N.L < 0) and, for an
    ``envmap``, w_e from the emitter (6-7; then the emitter takes coordinates 1-2, bases 2 and 3, whose
    points spread best: half the error of the sun's samples on bases 13 and 17). They are combined by the balance heuristic (Veach 1997, eq. 9.10)
    with counts 1, 1 and c_e (:data:`ENVIRONMENT_EMITTER_WEIGHT`'s for an ``envmap``; 0 for a ``constant``
    emitter, whose own sampling adds only variance):

        F = sum_{t in (b, o, e)} c_t f(w_t) cos L(w_t) / (p_b(w_t) + p_o(w_t) + c_e p_e(w_t)).

    p_b + p_o is positive wherever f is, so F is unbiased. Under a ``constant`` emitter F is f cos / p_b
    on w_i's side: exact for a BSDF that samples its own f cos (``diffuse``), and for a glossy lobe its
    error falls about as 1/N on these points, where ``atlasgen_direct``'s cosine and emitter samples
    converge as 1/sqrt(N) from far higher. ``seed`` 0 and 1 give independent estimates (their noise
    floor); ``first_sample`` continues the sequence, so [0, n) and [n, n + m) average, weighted n : m, to
    [0, n + m).

    Raises ValueError for a scene with emitters besides one environment (infinite, not a delta light).
    """
    import drjit as dr

    t0 = time.perf_counter()
    emitters = list(mi_scene.emitters())
    environment = [e for e in emitters if mi.has_flag(e.flags(), mi.EmitterFlags.Infinite)
                   and not mi.has_flag(e.flags(), mi.EmitterFlags.Delta)]  # fmt: skip
    if len(environment) != 1 or len(emitters) != 1:
        raise ValueError(f"render_environment_qmc needs an environment as the only emitter, got {len(emitters)} emitter(s)")
    emitter = environment[0]
    # A constant emitter's own samples only add variance here: the BSDF's and the cosine ones cover the sphere.
    c_e = 0.0 if emitter.class_name().startswith("Constant") else ENVIRONMENT_EMITTER_WEIGHT["envmap"]
    sensor = mi_scene.sensors()[0]
    width, height = (int(c) for c in sensor.film().crop_size())
    total = np.zeros((height * width, 3), dtype=np.float64)
    ctx = mi.BSDFContext()
    done, end = int(first_sample), int(first_sample) + int(spp)
    with dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, False):
        while done < end:
            batch = min(CENTRE_PASS_SPP, end - done)
            count = width * height * batch
            # The same points for every pixel; the sky's emitter samples (the sun) take the two best-spread bases, 2 and 3.
            u = np.tile(halton_points(done, batch, 7, seed)[:, _EMITTER_FIRST if c_e else slice(None)], (width * height, 1))
            pixel = dr.arange(mi.UInt32, count) // batch
            centre = mi.Point2f((mi.Float(pixel % width) + 0.5) / width, (mi.Float(pixel // width) + 0.5) / height)
            ray, weight = sensor.sample_ray_differential(0.0, mi.Float(0.5), centre, mi.Point2f(0.5, 0.5))
            si = mi_scene.ray_intersect(ray)
            hit = si.is_valid()
            bsdf = si.bsdf(ray)

            def term(wo, count_t):
                """c_t f cos L / (p_b + p_o + c_e p_e) at the local direction ``wo``."""
                d = si.to_world(wo)
                it = dr.zeros(mi.SurfaceInteraction3f)
                it.wi = -d
                it.wavelengths = si.wavelengths
                ds = dr.zeros(mi.DirectionSample3f)
                ds.d = d
                f, p_b = bsdf.eval_pdf(ctx, si, wo, hit)
                p_o = dr.select(wo.z * si.wi.z < 0, dr.abs(wo.z) / dr.pi, 0.0)
                den = p_b + p_o + (c_e * emitter.pdf_direction(si, ds, hit) if c_e else 0.0)
                return dr.select(hit & (den > 0), count_t * f * emitter.eval(it, hit) / dr.maximum(den, 1e-30), 0.0)

            bs, _ = bsdf.sample(ctx, si, mi.Float(u[:, 0]), mi.Point2f(u[:, 1], u[:, 2]), hit)
            result = dr.select(bs.pdf > 0, term(bs.wo, 1.0), 0.0)
            c = mi.warp.square_to_cosine_hemisphere(mi.Point2f(u[:, 3], u[:, 4]))
            result += term(mi.Vector3f(c.x, c.y, dr.select(si.wi.z < 0, c.z, -c.z)), 1.0)
            if c_e:
                ds_e, _ = emitter.sample_direction(si, mi.Point2f(u[:, 5], u[:, 6]), hit)
                result += dr.select(ds_e.pdf > 0, term(si.to_local(ds_e.d), c_e), 0.0)
            value = weight * result
            rgb = mi.spectrum_to_srgb(value, ray.wavelengths) if mi.is_spectral else value
            samples = np.stack([np.array(rgb[k], dtype=np.float64) for k in range(3)], axis=-1)
            total += samples.reshape(height * width, batch, 3).sum(axis=1)
            done += batch
    image = (total / spp).reshape(height, width, 3).astype(np.float32)
    return image, time.perf_counter() - t0
