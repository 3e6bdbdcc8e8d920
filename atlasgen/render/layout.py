"""The renderer's CPU/GPU shared declarations: uniform and storage structs, constants.

Each struct a pass binds is declared here once (:class:`atlasgen.shaders.structs.Struct`); the
shader files name it with a ``// @declare NAME`` line, which
:func:`atlasgen.shaders.passes.assemble_shader` replaces with :func:`declaration_wgsl`'s WGSL, and
the ``pack_*`` functions of the passes fill it through the same declaration.
"""

from __future__ import annotations

import enum

from atlasgen.materials.scene import MAX_LIGHTS
from atlasgen.optics.falloff import DISTANCE_SQUARED_FLOOR
from atlasgen.render.camera import FAR_PLANE_DEPTH
from atlasgen.shaders.structs import (
    F32,
    U32,
    Array,
    Field,
    Struct,
    mat4x4,
    round_up,
    vec2,
    vec3,
    vec4,
    wgsl_constant,
    wgsl_constants,
)

__all__ = [
    "FRAME",
    "OBJECT",
    "LIGHT",
    "CULL",
    "TILE_SIZE",
    "COARSE_TILES",
    "CULL_GROUP_TILES",
    "ENTRY_TEXELS",
    "LIGHT_MASK_WORDS",
    "ENVIRONMENT",
    "LightType",
    "NO_MATERIAL",
    "UNIFORM_OFFSET_ALIGNMENT",
    "OBJECT_UNIFORM_STRIDE",
    "declaration_wgsl",
]

#: Material-ID target value of pixels that no object covers (cleared, never written).
NO_MATERIAL = 0xFFFF

#: WebGPU's default ``minUniformBufferOffsetAlignment``: dynamic uniform offsets are multiples of it.
UNIFORM_OFFSET_ALIGNMENT = 256


class LightType(enum.IntEnum):
    """``Light.kind``: how ``Light.position`` is read."""

    DIRECTIONAL = 0  # direction is the direction the light travels; radiant is an irradiance E
    POINT = 1  # position is a point; radiant is a radiant intensity I
    SPOT = 2  # a point light whose intensity falls off about its axis, direction (cone)


FRAME = Struct(
    "Frame",
    [
        Field("view_proj", mat4x4),
        Field("eye", vec4(), "camera position; w unused"),
        Field("forward", vec4(), "unit view direction; w = tan(horizontal half field of view)"),
        Field("right", vec4(), "unit image-x direction; w = tan(vertical half field of view)"),
        Field("up", vec4(), "unit image-up direction (image y runs along -up)"),
        Field("viewport", vec4(), "width, height, 1 / width, 1 / height"),
        Field("background", vec4(), "radiance of pixels no object covers"),
        Field("mip", vec4(), "x: bias, y: reference distance, z: last mip level"),
        Field(
            "counts", vec4(U32), "x: number of lights, y: 1 where lighting reads tile lists, z: tiles per row, w: list capacity"
        ),
        Field(
            "lists",
            vec4(U32),
            "tile-list texture: x: the layer of every light's row, y: log2 of its width in texels, z, w unused",
        ),
        Field("outline_colour", vec4(), "radiance written on outline pixels"),
        Field("outline", vec4(), "x: relative inverse-depth threshold, y: cos(normal threshold)"),
    ],
    address_space="uniform",
    doc="Per frame, bound by every pass (pack_frame in atlasgen/render/renderer.py).",
)

OBJECT = Struct(
    "Object",
    [
        Field("model", mat4x4),
        Field("normal_matrix", mat4x4, "inverse transpose of the model matrix's 3x3 part"),
        Field("albedo_gloss", vec4(), "linear albedo, gloss in [0, 1]"),
        Field("material", vec4(U32), "x: atlas slice (material ID)"),
    ],
    address_space="uniform",
    doc="Per object, at a dynamic offset (pack_object in atlasgen/render/gbuffer.py).",
)

#: Bytes per object in the dynamic-offset uniform buffer.
OBJECT_UNIFORM_STRIDE = round_up(UNIFORM_OFFSET_ALIGNMENT, OBJECT.size)

LIGHT = Struct(
    "Light",
    [
        Field("position", vec3(), "LIGHT_POINT, LIGHT_SPOT: the position"),
        Field("range", F32, "distance at which the windowed falloff reaches 0; 0: unbounded"),
        Field("radiant", vec3(), "colour * intensity: I in W/sr (point, spot: on the axis) or E in W/m^2 (directional)"),
        Field("index", U32, "the light's place in the scene's list: a tile list's copy of these texels names it"),
        Field("direction", vec3(), "LIGHT_DIRECTIONAL: the direction of travel; LIGHT_SPOT: the unit axis"),
        Field("cos_outer", F32, "LIGHT_SPOT: cos(outer angle); beyond it the light sends nothing"),
        Field("cone", vec2(), "LIGHT_SPOT: x: outer angle (rad), y: 1 / (outer - inner angle) (1/rad)"),
        Field("kind", U32, "a LIGHT_* constant"),
    ],
    doc="One light: 16 bytes a texel, in a row of the cull pass's light texture and of the tile-list texture's last "
    "layer (pack_lights in atlasgen/render/lighting.py).",
)

#: Texels of a :data:`LIGHT` that a tile list copies per entry: everything a point light is shaded
#: with (position, range, radiant) and the index that names it. The rest (a spot or directional
#: light's axis, cone and kind) is read through the index from the lights' own rows.
ENTRY_TEXELS = 2

#: Pixels along each side of a culling tile (16 x 16 tiles, as Andersson 2011); the culling pass's workgroup size.
TILE_SIZE = 16

#: Tiles along each side of a block of the coarse culling step (4 x 4 tiles, 64 x 64 pixels): a few
#: hundred blocks at 720p, few enough that testing every light against each block costs little.
COARSE_TILES = 4

#: Tiles along each side of the square of tiles one culling workgroup takes (4 x 4, a coarse block
#: when aligned to one): lavapipe spends more on a workgroup's set-up and barriers than on culling one tile.
CULL_GROUP_TILES = 4

#: u32 words of the culling pass's per-tile bit mask of lights: one bit per light the renderer takes.
LIGHT_MASK_WORDS = MAX_LIGHTS // 32

CULL = Struct(
    "Cull",
    [Field("origin", vec4(U32), "x, y: the first tile of the rectangle this dispatch culls; z, w: one past its last")],
    address_space="uniform",
    doc="One culling dispatch, at a dynamic offset (pack_cull in atlasgen/render/culling.py).",
)

ENVIRONMENT = Struct(
    "Environment",
    [
        Field("sh", Array(vec4(), 25), "order-4 SH coefficients L_k of the radiance (rgb), k = l*l + l + m"),
        Field("params", vec4(), "x: prefiltered levels (mips), y: rows of level 0, z: 1 where the background shows it"),
    ],
    address_space="uniform",
    doc="The scene's environment (pack_environment in atlasgen/render/environment.py).",
)


def _light_texel_wgsl(i: int) -> str:
    """lighting.wgsl's read of texel ``i`` of the ``k``-th light of a tile's list (``listed``) or of the
    scene: from the list's entry for the texels it copies, else from the light's own row, by its index."""
    if i < ENTRY_TEXELS:
        return f"light_texel(k, {i}u, listed, tile)"
    texel, component = LIGHT.texel_of("index")
    if texel >= ENTRY_TEXELS:
        raise ValueError("a tile list's entry must hold the light's index")
    return f"light_texel(t{texel}.{'xyzw'[component]}, {i}u, false, tile)"


_DECLARATIONS = {
    "Frame": FRAME.wgsl,
    "Object": OBJECT.wgsl,
    "Light": LIGHT.wgsl,
    "read_light": lambda: LIGHT.texel_reader_wgsl(
        "read_light", fetch=_light_texel_wgsl, params="k: u32, listed: bool, tile: vec2<u32>"
    ),
    "LIGHT_TEXELS": lambda: wgsl_constant("LIGHT_TEXELS", U32, LIGHT.size // 16, "16-byte texels of a Light."),
    "ENTRY_TEXELS": lambda: wgsl_constant("ENTRY_TEXELS", U32, ENTRY_TEXELS, "Texels of a Light a tile list copies per entry."),
    "Environment": ENVIRONMENT.wgsl,
    "Cull": CULL.wgsl,
    "TILE_SIZE": lambda: wgsl_constant("TILE_SIZE", U32, TILE_SIZE, "Pixels along each side of a light-culling tile."),
    "CULL_GROUP_TILES": lambda: wgsl_constant(
        "CULL_GROUP_TILES", U32, CULL_GROUP_TILES, "Tiles along each side of the square one culling workgroup takes."
    ),
    "COARSE_TILES": lambda: wgsl_constant(
        "COARSE_TILES", U32, COARSE_TILES, "Tiles along each side of a block of the coarse culling step."
    ),
    "LIGHT_MASK_WORDS": lambda: wgsl_constant(
        "LIGHT_MASK_WORDS", U32, LIGHT_MASK_WORDS, "u32 words of a tile's bit mask of lights (one bit per light)."
    ),
    "LightType": lambda: wgsl_constants(LightType, "LIGHT_"),
    "DISTANCE_SQUARED_FLOOR": lambda: wgsl_constant(
        "DISTANCE_SQUARED_FLOOR", F32, DISTANCE_SQUARED_FLOOR, "The falloff's floor on d^2, for 1/d^2 alone (falloff.py)."
    ),
    "FAR_PLANE_DEPTH": lambda: wgsl_constant(
        "FAR_PLANE_DEPTH", F32, FAR_PLANE_DEPTH, "The far plane's depth, the g-buffer depth's clear value (camera.py)."
    ),
    "NO_MATERIAL": lambda: wgsl_constant(
        "NO_MATERIAL", U32, NO_MATERIAL, "Material-ID target value of pixels that no object covers (cleared, never written)."
    ),
}


def declaration_wgsl(name: str) -> str:
    """The generated WGSL of a shared declaration, by the name shader files give it."""
    try:
        return _DECLARATIONS[name]()
    except KeyError:
        raise ValueError(f"no shared WGSL declaration {name!r}; known: {', '.join(sorted(_DECLARATIONS))}") from None
