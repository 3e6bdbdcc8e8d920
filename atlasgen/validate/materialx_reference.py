"""The model reference of a MaterialX material: its scene forward-rendered with MaterialX's own shader.

:func:`atlasgen.separable.materialx_forward.render_materialx_forward` shades the validation
scene's triangles (the renderer's meshes, world transforms and camera, handed down as arrays)
with MaterialX's generated GLSL under the scene's own point and directional lights, one sample
at each pixel centre. The atlas image and this one then differ only in the BRDF: the atlas's
factors or slice against MaterialX's shading code, with the lighting identical.

Beside it stays the older route, the oracle evaluated at Mitsuba's pixel-centre intersections
through the ``atlasgen_brdf`` plugin (:func:`atlasgen.validate.run._model_render`). The two agree
to float precision (126 dB PSNR on ``front``) but where the shading point or normal differs, found
by rasterising (perspective-correct interpolation) or by ray tracing (barycentric interpolation at
the hit), and at silhouette pixels whose interpolated normal faces away from the camera (N.V < 0):
the source zeroes them, since the table holds reflection only, while MaterialX's shader shades them.
The forward render keeps MaterialX's own answer there: it is what a MaterialX viewer shows.
"""

from __future__ import annotations

import time

import numpy as np

from atlasgen.models.materialx import materialx_mitsuba_bsdf
from atlasgen.models.physical_fit import mitsuba_f_cos
from atlasgen.render.camera import projection_matrix, view_matrix
from atlasgen.separable.materialx_forward import ForwardDraw, ForwardLight, render_materialx_forward, vertex_tangents
from atlasgen.separable.source import make_source
from atlasgen.validate.mitsuba_scene import world_mesh_arrays

__all__ = ["FORWARD_DESCRIPTION", "PROBE_RATIO_RANGE", "RATIO_PAIRS", "forward_lights", "gl_view_projection", "is_materialx_entry",
           "oracle_over_physical_bsdf", "render_forward_reference"]  # fmt: skip

#: Its first clause is what the look's summary names ("against the forward render of MaterialX's GLSL it was factored from").
FORWARD_DESCRIPTION = ("forward render of MaterialX's GLSL (moderngl on llvmpipe): the scene's meshes and lights, "
                       "one sample per pixel centre, inverse-square falloff")  # fmt: skip


def is_materialx_entry(entry) -> bool:
    """Whether a manifest entry was baked from a MaterialX document (``source = "materialx"``)."""
    return entry.params.get("source") == "materialx" and isinstance(entry.params.get("materialx"), dict)


def forward_lights(scene) -> list[ForwardLight] | None:
    """The scene's lights as the forward render binds them (each one is a :class:`ForwardLight`),
    or ``None`` where one has no MaterialX light shader here (the Mitsuba route then stays the reference)."""
    if any(light.type not in ("point", "spot", "directional") for light in scene.lights):
        return None
    return list(scene.lights)


def gl_view_projection(camera, width: int, height: int) -> np.ndarray:
    """World to OpenGL clip space: the renderer's WebGPU projection (depth in [0, 1]) with its depth
    remapped to [-1, 1] (z' = 2 z - w); x, y and so the pixel centres are the same."""
    remap = np.eye(4)
    remap[2, 2], remap[2, 3] = 2.0, -1.0
    return remap @ projection_matrix(camera, width, height) @ view_matrix(camera)


def render_forward_reference(scene, entry):
    """``(image (h, w, 3) float32, seconds, ForwardImage)`` of ``entry`` (a MaterialX manifest entry) on the
    bound ``scene``: the objects showing it shaded by MaterialX times their albedo, the others drawn
    black (they only occlude); ``None`` where the scene has a light the forward render cannot bind."""
    lights = forward_lights(scene)
    if lights is None:
        return None
    spec = entry.params["materialx"]
    draws = []
    for obj in scene.objects:
        positions, normals, indices = world_mesh_arrays(obj)
        albedo = tuple(obj.albedo) if obj.material == entry.name else (0.0, 0.0, 0.0)
        unit = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        draws.append(ForwardDraw(positions, normals, vertex_tangents(unit), indices, albedo))
    t0 = time.perf_counter()
    forward = render_materialx_forward(spec["category"], spec.get("oracle_inputs", spec.get("inputs", {})), draws,
                                       gl_view_projection(scene.camera, scene.width, scene.height), scene.camera.position,
                                       lights, scene.width, scene.height)  # fmt: skip
    return forward.radiance.astype(np.float32), time.perf_counter() - t0, forward


#: What issue 23's probe measured for MaterialX's gold over Mitsuba's roughconductor (same n, k and alpha,
#: roughness 0.25): the range a faithful pairing falls in, which the report sets the measured ratio beside.
PROBE_RATIO_RANGE = (0.998, 1.049)
#: (l, v) pairs of :func:`oracle_over_physical_bsdf`: uniform directions with N.L, N.V in [0.2, 1].
RATIO_PAIRS = 20_000


def oracle_over_physical_bsdf(entry, pairs: int = RATIO_PAIRS, seed: int = 23) -> dict:
    """MaterialX's f cos over its faithful Mitsuba BSDF's (:func:`atlasgen.models.materialx.materialx_mitsuba_bsdf`,
    ``roughconductor`` for the gold) at ``pairs`` uniform (l, v) pairs with N.L, N.V >= 0.2, every channel where
    Mitsuba's exceeds 1e-3: ``{"pairs", "bsdf_p1_p50_p99", "bsdf_min_max"}`` (empty where there is no such BSDF).
    Issue 23's probe measured :data:`PROBE_RATIO_RANGE` for gold at roughness 0.25 (``within_probe_range`` says
    whether the pairs' whole range lies in it): MaterialX's height-correlated G2 and its energy compensation
    against Mitsuba's separable G1 G1 and none."""
    found = materialx_mitsuba_bsdf(entry.params["materialx"])
    if found is None:
        return {}
    rng = np.random.default_rng(seed)

    def directions():
        z = rng.uniform(0.2, 1.0, pairs)
        phi = 2.0 * np.pi * rng.random(pairs)
        s = np.sqrt(1.0 - z * z)
        return np.stack([s * np.cos(phi), s * np.sin(phi), z], -1)

    l, v = directions(), directions()
    a, b = make_source(entry.params).f_cos(l, v), mitsuba_f_cos(found[0])(l, v)
    keep = b > 1e-3
    ratio = a[keep] / b[keep]
    return {"pairs": int(keep.all(axis=1).sum()), "bsdf_p1_p50_p99": [float(x) for x in np.percentile(ratio, [1, 50, 99])],
            "bsdf_min_max": [float(ratio.min()), float(ratio.max())], "probe_range": list(PROBE_RATIO_RANGE),
            "within_probe_range": bool(PROBE_RATIO_RANGE[0] <= ratio.min() and ratio.max() <= PROBE_RATIO_RANGE[1])}  # fmt: skip
