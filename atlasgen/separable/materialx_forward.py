"""MaterialX's own shader forward-rendered over a scene's triangles, under its point, spot and directional lights.

The reference ``atlasgen validate`` compares a MaterialX material's atlas image with
(:mod:`atlasgen.validate.materialx_reference` hands the scene down as arrays): the same
meshes, camera and lights as the deferred renderer, shaded by MaterialX 1.39.5's generated GLSL
(:func:`~atlasgen.separable.materialx_oracle.generate_surface_stages`, every input a uniform, no
environment light) in moderngl's headless EGL context (llvmpipe), one sample at each pixel
centre into an RGBA32F target, depth-tested, nothing blended. The lights are MaterialX light
shaders bound with ``bindLightShader`` (``ND_directional_light`` as type 1, ``ND_point_light`` as
type 2, ``ND_spot_light`` as type 3) and set through its ``u_lightData`` array and
``u_numActiveLightSources``.

The vertex stage is MaterialX's, unchanged. The pixel stage's BSDF code is MaterialX's, unchanged;
four edits make it shade as the deferred renderer does, where the two differ:

- the point light's falloff: MaterialX's ``mx_point_light`` divides by (d + 1)^decay_rate, which is
  not the inverse square even at decay_rate 2. atlasgen's lights give E = I W(d, r) / d^2 with the
  range window W (:func:`atlasgen.optics.falloff.windowed_irradiance`; 1 without a range), so
  its body is replaced by that, and ``LightData`` gains a ``range`` member (0: none). The spot
  light's, which blends cosines by a smoothstep, becomes that falloff times atlasgen's cone
  (:func:`atlasgen.optics.falloff.spot_factor`, linear in the angle; its angles in radians);
- two-sided shading: the renderer shades a back face with the flipped normal, MaterialX's
  stage does not, so ``vd`` becomes a global filled from the interpolated block with
  ``normalWorld`` flipped where ``gl_FrontFacing`` is false;
- the object's albedo: the renderer adds L += E albedo f cos, so the output is times
  ``atlasgen_albedo`` (0 for the objects of other materials: they occlude, and are left black);
- ``u_refractionTwoSided`` is declared (as the oracle's: MaterialX 1.39.5 uses it undeclared).

Two more outputs carry the interpolated world position and (flipped) unit normal per pixel, so
that a caller can check the shading against the oracle at the same (n, l, v).
MaterialX and moderngl are imported inside functions only (the ``materialx`` extra).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import cache
from typing import Any, Protocol

import numpy as np

from atlasgen.errors import BackendError
from atlasgen.optics.falloff import DISTANCE_SQUARED_FLOOR
from atlasgen.separable.materialx_oracle import (
    GL_LOCK,
    SURFACE_MODELS,
    compile_program,
    declare_refraction_two_sided,
    generate_surface_stages,
    gl_context,
    park_framebuffer,
    set_surface_inputs,
    varyings_of,
)

__all__ = [
    "MAX_LIGHTS",
    "LIGHT_TYPES",
    "ForwardLight",
    "ForwardDraw",
    "ForwardImage",
    "adapt_forward_pixel_stage",
    "forward_program",
    "render_materialx_forward",
    "vertex_tangents",
]

#: The most lights one forward render binds (MaterialX's ``hwMaxActiveLightSources``).
MAX_LIGHTS = 16
#: atlasgen light type -> (MaterialX light node, the id it is bound with: ``u_lightData[i].type``).
LIGHT_TYPES = {"directional": ("directional_light", 1), "point": ("point_light", 2), "spot": ("spot_light", 3)}

_POINT_LIGHT = re.compile(r"void mx_point_light\(LightData light, vec3 position, out lightshader result\)\n\{.*?\n\}\n", re.S)
_POINT_LIGHT_BODY = """void mx_point_light(LightData light, vec3 position, out lightshader result)
{
    // atlasgen's falloff (atlasgen.optics.falloff.windowed_irradiance): E = I W(d, r) / d^2,
    // W = saturate(1 - (d/r)^4)^2, 1 without a range; MaterialX's own is I / (d + 1)^decay_rate.
    // d^2 held above float32's least normal number for 1/d^2 alone; the window and the direction at the true
    // distance, formed so that nothing underflows in a small scene (as the renderer's lighting.wgsl).
    vec3 d = light.position - position;
    float d2 = max(dot(d, d), DISTANCE_SQUARED_FLOOR);
    float window = 1.0;
    if (light.range > 0.0)
    {
        vec3 q = d / light.range;
        float x = dot(q, q);
        window = x >= 1.0 ? 0.0 : mx_square(clamp(1.0 - x * x, 0.0, 1.0));
    }
    float m = max(max(abs(d.x), abs(d.y)), abs(d.z));
    vec3 u = m > 0.0 ? d / m : vec3(0.0);
    result.direction = u * inversesqrt(max(dot(u, u), 1.0));
    result.intensity = min(light.color * light.intensity / d2, vec3(3.4028234e38)) * window;
}
""".replace("DISTANCE_SQUARED_FLOOR", repr(DISTANCE_SQUARED_FLOOR))  # 1.1754943508222875e-38: GLSL reads it
_SPOT_LIGHT = re.compile(r"void mx_spot_light\(LightData light, vec3 position, out lightshader result\)\n\{.*?\n\}\n", re.S)
_SPOT_LIGHT_BODY = """void mx_point_light(LightData light, vec3 position, out lightshader result);  // generated after it

void mx_spot_light(LightData light, vec3 position, out lightshader result)
{
    // atlasgen's spot (atlasgen.optics.falloff.spot_factor, Mitsuba's spot): the point light's falloff times
    // S = saturate((outer - theta) / (outer - inner)), 0 from the outer cone on; inner_angle and outer_angle
    // hold the half-angles in radians here (MaterialX's own are cosines, blended by a smoothstep).
    mx_point_light(light, position, result);
    float c = clamp(dot(result.direction, -light.direction), -1.0, 1.0);
    float s = clamp((light.outer_angle - acos(c)) / (light.outer_angle - light.inner_angle), 0.0, 1.0);
    result.intensity *= c > cos(light.outer_angle) ? s : 0.0;
}
"""
_OUTPUT = re.compile(r"^out\s+vec4\s+(?P<name>\w+)\s*;", re.M)
_BLOCK = re.compile(r"in\s+VertexData\s*\{(?P<body>[^}]*)\}\s*vd\s*;")


class ForwardLight(Protocol):
    """What the forward render reads of a light: the renderer's own scene light
    (:class:`atlasgen.materials.scene.Light`, which ``separable/`` must not import), as a protocol so
    that its fields are declared once. ``type`` ``"point"`` (``position``, radiant intensity
    ``intensity`` x ``colour``, ``range``: ``inf`` for none), ``"spot"`` (a point light with an axis
    ``direction`` and cone half-angles ``inner_angle`` < ``outer_angle`` in degrees) or ``"directional"``
    (``direction`` it travels, irradiance ``intensity`` x ``colour``)."""

    type: str
    colour: tuple
    intensity: float
    position: tuple | None
    direction: tuple | None
    range: float
    inner_angle: float
    outer_angle: float


@dataclass
class ForwardDraw:
    """One object's triangles in world space: ``positions``, ``normals`` and ``tangents`` ``(n, 3)``,
    ``indices`` ``(m, 3)``, and the ``albedo`` its shading is multiplied by (0: it only occludes)."""

    positions: np.ndarray
    normals: np.ndarray
    tangents: np.ndarray
    indices: np.ndarray
    albedo: tuple = (1.0, 1.0, 1.0)


@dataclass
class ForwardImage:
    """``radiance`` ``(h, w, 3)``; ``position`` and ``normal`` ``(h, w, 3)`` (world space, the normal as
    shaded); ``covered`` ``(h, w)`` True where a triangle was drawn. Row 0 is the image's top."""

    radiance: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    covered: np.ndarray


def vertex_tangents(normals) -> np.ndarray:
    """A unit tangent per unit normal ``(n, 3)``: the world y axis crossed with it, or x where the normal is
    near y. Only anisotropic inputs read the tangent; the meshes have none of their own."""
    n = np.asarray(normals, dtype=np.float64)
    axis = np.where(np.abs(n[:, 1:2]) > 0.99, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = np.cross(axis, n)
    length = np.linalg.norm(t, axis=1, keepdims=True)
    return np.where(length > 1e-12, t / np.maximum(length, 1e-12), [[1.0, 0.0, 0.0]]).astype(np.float32)


def adapt_forward_pixel_stage(pixel_source: str) -> str:
    """MaterialX's pixel stage with the four edits of the module's docstring (falloff, two sides, albedo,
    the missing uniform) and the position and normal outputs; its BSDF code untouched."""
    block = _BLOCK.search(pixel_source)
    output = _OUTPUT.search(pixel_source)
    if block is None or output is None or "struct LightData\n{" not in pixel_source or "\nvoid main()\n{" not in pixel_source:
        raise BackendError(
            "MaterialX's pixel stage does not have the layout of MaterialX 1.39's GLSL (VertexData, LightData, main)"
        )
    if _POINT_LIGHT.search(pixel_source) is None or _SPOT_LIGHT.search(pixel_source) is None:
        raise BackendError(
            "MaterialX's pixel stage has no mx_point_light and mx_spot_light of MaterialX 1.39's form; expected both bound"
        )
    out = output["name"]
    members = varyings_of(pixel_source)
    src = (pixel_source[: block.start()] + "in VertexData\n{" + block["body"] + "} atlasgen_vd;\n\nstruct AtlasgenVertexData\n{"
           + block["body"] + "};\nAtlasgenVertexData vd;\nuniform vec3 atlasgen_albedo = vec3(1.0);\n"
           + pixel_source[block.end() :])  # fmt: skip
    src = src.replace("struct LightData\n{", "struct LightData\n{\n    float range;", 1)
    src = _POINT_LIGHT.sub(lambda _: _POINT_LIGHT_BODY, src, count=1)
    src = _SPOT_LIGHT.sub(lambda _: _SPOT_LIGHT_BODY, src, count=1)
    src = _OUTPUT.sub(f"layout(location = 0) out vec4 {out};\nlayout(location = 1) out vec4 atlasgen_position;\n"
                      "layout(location = 2) out vec4 atlasgen_normal;", src, count=1)  # fmt: skip
    src = declare_refraction_two_sided(src)
    head, _, tail = src.rpartition("\nvoid main()\n{")
    fill = "\n".join(
        f"    vd.{name} = gl_FrontFacing ? atlasgen_vd.{name} : -atlasgen_vd.{name};"
        if name == "normalWorld"
        else f"    vd.{name} = atlasgen_vd.{name};"
        for _, name in members
    )
    wrapper = f"""
void main()
{{
{fill}
    atlasgen_materialx_main();
    {out} = vec4({out}.rgb * atlasgen_albedo, 1.0);
    atlasgen_position = vec4(vd.positionWorld, 1.0);
    atlasgen_normal = vec4(normalize(vd.normalWorld), 1.0);
}}
"""
    return head + "\nvoid atlasgen_materialx_main()\n{" + tail + wrapper


@dataclass
class _Program:
    category: str
    program: Any
    uniforms: frozenset


@cache
def forward_program(category: str) -> _Program:
    """The compiled forward program of one surface model (generated and compiled once per process)."""
    if category not in SURFACE_MODELS:
        raise BackendError(f"no MaterialX forward render for {category!r}; expected one of {', '.join(SURFACE_MODELS)}")
    vertex, pixel = generate_surface_stages(category, tuple(LIGHT_TYPES.values()), MAX_LIGHTS)
    pixel = adapt_forward_pixel_stage(pixel)
    with GL_LOCK, gl_context() as ctx:
        program = compile_program(ctx, vertex, pixel, f"MaterialX's {category} forward shader")
    return _Program(category, program, frozenset(program))


def _set(program, uniforms, name, value) -> None:
    if name in uniforms:  # the compiler removes what changes nothing
        program[name].value = value


def _set_lights(p: _Program, lights) -> None:
    if len(lights) > MAX_LIGHTS:
        raise BackendError(f"the MaterialX forward render binds at most {MAX_LIGHTS} lights, got {len(lights)}")
    for i, light in enumerate(lights):
        if light.type not in LIGHT_TYPES:
            raise BackendError(
                f"the MaterialX forward render has no {light.type!r} light; expected one of {', '.join(LIGHT_TYPES)}"
            )
        key = f"u_lightData[{i}]"
        _set(p.program, p.uniforms, f"{key}.type", LIGHT_TYPES[light.type][1])
        _set(p.program, p.uniforms, f"{key}.color", tuple(float(c) for c in light.colour))
        _set(p.program, p.uniforms, f"{key}.intensity", float(light.intensity))
        if light.type in ("point", "spot"):
            _set(p.program, p.uniforms, f"{key}.position", tuple(float(c) for c in light.position))
            _set(p.program, p.uniforms, f"{key}.range", float(light.range) if math.isfinite(light.range) else 0.0)
        if light.type in ("directional", "spot"):
            _set(p.program, p.uniforms, f"{key}.direction", tuple(float(c) for c in light.direction))
        if light.type == "spot":
            _set(p.program, p.uniforms, f"{key}.inner_angle", math.radians(light.inner_angle))
            _set(p.program, p.uniforms, f"{key}.outer_angle", math.radians(light.outer_angle))
    _set(p.program, p.uniforms, "u_numActiveLightSources", len(lights))


def render_materialx_forward(category: str, inputs: dict, draws, view_projection, eye, lights, width: int,
                             height: int) -> ForwardImage:  # fmt: skip
    """The forward render of ``draws`` (:class:`ForwardDraw`) with a ``category`` surface of constant
    ``inputs`` (every other input at its nodedef default) under ``lights`` (:class:`ForwardLight`).

    ``view_projection``: world to OpenGL clip space ``(4, 4)`` (row-major, NDC depth in [-1, 1]);
    ``eye``: the camera position (MaterialX's ``u_viewPosition``). One sample per pixel centre,
    the nearest triangle's, no blending.

    Raises :class:`BackendError` when MaterialX, moderngl or EGL is missing, the shader does not
    compile, a light is of a kind it cannot bind, or OpenGL reports an error.
    """
    import moderngl

    p = forward_program(category)
    width, height = int(width), int(height)
    matrix = np.asarray(view_projection, dtype=np.float32)
    with GL_LOCK, gl_context() as ctx:
        ctx.error  # noqa: B018 - reading it clears an error an earlier caller left
        set_surface_inputs(p.program, p.uniforms, category, inputs)
        _set(p.program, p.uniforms, "u_viewPosition", tuple(float(c) for c in eye))
        _set(p.program, p.uniforms, "u_viewProjectionMatrix", tuple(matrix.T.ravel().tolist()))  # GLSL is column-major
        identity = tuple(np.eye(4, dtype=np.float32).ravel().tolist())
        _set(p.program, p.uniforms, "u_worldMatrix", identity)  # the draws are in world space already
        _set(p.program, p.uniforms, "u_worldInverseTransposeMatrix", identity)
        _set_lights(p, lights)
        targets = [ctx.texture((width, height), 4, dtype="f4") for _ in range(3)]
        depth = ctx.depth_renderbuffer((width, height))
        fbo = ctx.framebuffer(color_attachments=targets, depth_attachment=depth)
        released = [fbo, depth, *targets]
        try:
            fbo.use()
            ctx.viewport = (0, 0, width, height)
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
            ctx.enable(moderngl.DEPTH_TEST)
            ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
            for draw in draws:
                _set(p.program, p.uniforms, "atlasgen_albedo", tuple(float(a) for a in draw.albedo))
                columns = [np.asarray(x, dtype=np.float32).reshape(-1, 3) for x in (draw.positions, draw.normals, draw.tangents)]
                vbo = ctx.buffer(np.ascontiguousarray(np.concatenate(columns, axis=1)).tobytes())
                ibo = ctx.buffer(np.ascontiguousarray(draw.indices, dtype=np.uint32).tobytes())
                names = [n for n in ("i_position", "i_normal", "i_tangent") if n in p.program]
                layout = " ".join("3f" if n in names else "3x4" for n in ("i_position", "i_normal", "i_tangent"))
                vao = ctx.vertex_array(p.program, [(vbo, layout, *names)], index_buffer=ibo, index_element_size=4)
                vao.render(moderngl.TRIANGLES)
                released += [vao, vbo, ibo]
            planes = [np.frombuffer(fbo.read(components=4, dtype="f4", attachment=i), dtype=np.float32)
                      .reshape(height, width, 4)[::-1] for i in range(3)]  # fmt: skip
            error = ctx.error
        finally:
            ctx.disable(moderngl.DEPTH_TEST)
            park_framebuffer(ctx)
            for obj in released:
                obj.release()
    if error != "GL_NO_ERROR":
        raise BackendError(f"OpenGL reported {error} in the MaterialX forward render of {category}")
    radiance, position, normal = planes
    return ForwardImage(radiance[..., :3].copy(), position[..., :3].copy(), normal[..., :3].copy(), normal[..., 3] > 0.5)
