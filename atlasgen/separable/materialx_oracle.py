"""MaterialX's own real-time shader as a BRDF oracle: f cos(theta_l) of a surface shader at arrays of (l, v).

The shader is what MaterialX's viewers render with: ``GlslShaderGenerator`` (MaterialX 1.39.5)
with ``hwSpecularEnvironmentMethod = SPECULAR_ENVIRONMENT_NONE`` (no environment light),
``shaderInterfaceType = SHADER_INTERFACE_COMPLETE`` (every input stays a uniform, so one program
serves every material of a surface model) and one directional light bound with
``bindLightShader``. It runs headless in moderngl's standalone EGL context (Mesa's llvmpipe).

The pairs are two RGBA32F textures (v and l, one texel per pair); one full-screen pass shades
every texel into an RGBA32F target, which is read back. The pixel stage's BSDF code is
MaterialX's, unchanged; three edits make each fragment shade its own pair:

- the view: the ``VertexData`` block becomes a global that ``main`` fills, with the normal +z,
  the tangent +x and the world position P = -v; with ``u_viewPosition`` = 0 the shader's
  V = normalize(u_viewPosition - P) is v;
- the light: the ``u_lightData`` uniform array becomes a global that ``main`` fills, a
  directional light (type 1, the id it is bound with) of colour 1 and intensity E =
  :data:`LIGHT_INTENSITY` shining along -l: the output radiance is E f cos(theta_l), divided by E;
- ``u_refractionTwoSided``, which MaterialX 1.39.5 uses without declaring when there is no
  environment lighting, is declared (false).

``vd`` is filled from the pixel stage's own ``VertexData`` block, whose members differ between
surface models (:func:`vertex_data_for`). MaterialX and moderngl are imported inside functions only
(the ``materialx`` extra): nothing else in atlasgen loads them.

Cost on llvmpipe: compiling one surface model's program takes a few seconds the first time in
a process (cached per surface model); evaluating costs about 1 (standard_surface) to 15
(open_pbr_surface) microseconds per pair.
"""

from __future__ import annotations

import re
import threading
from dataclasses import dataclass
from functools import cache, lru_cache
from typing import Any

import numpy as np

from atlasgen.errors import BackendError

__all__ = [
    "SURFACE_MODELS",
    "NODE_NAME",
    "LIGHT_INTENSITY",
    "MaterialXOracle",
    "materialx_oracle",
    "evaluate_materialx_f_cos",
    "surface_defaults",
    "surface_ranges",
    "surface_inputs",
    "surface_nodedef",
    "load_materialx_libraries",
    "varyings_of",
    "vertex_data_for",
    "VERTEX_STAGE",
    "adapt_pixel_stage",
    "generate_surface_stages",
    "declare_refraction_two_sided",
    "set_surface_inputs",
    "gl_context",
    "GL_LOCK",
    "park_framebuffer",
]

#: The surface shader nodes the oracle compiles (MaterialX's bxdf library names).
SURFACE_MODELS = ("open_pbr_surface", "standard_surface", "gltf_pbr", "UsdPreviewSurface")
#: The shader node's name in the generated program: its inputs are the uniforms ``<NODE_NAME>_<input>``.
NODE_NAME = "SR"
#: The light's intensity E (colour 1): the shader returns E f cos, so f cos is the output over E.
LIGHT_INTENSITY = 1.0
#: Points per draw (a 1024-wide RGBA32F target of 256 rows: 4 MiB).
CHUNK = 1 << 18
_WIDTH = 1024

#: One thread at a time draws in the process's one context (Mitsuba calls plugins from worker threads).
GL_LOCK = threading.Lock()


def _materialx():
    try:
        import MaterialX as mx
        from MaterialX import PyMaterialXGenGlsl as mx_glsl
        from MaterialX import PyMaterialXGenShader as mx_shader
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise BackendError(f"MaterialX is not installed ({exc}); install the 'materialx' extra") from None
    return mx, mx_shader, mx_glsl


@lru_cache(maxsize=1)
def load_materialx_libraries():
    """MaterialX's standard data libraries (nodedefs and their GLSL), loaded once per process."""
    mx, _, _ = _materialx()
    stdlib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), stdlib)
    return stdlib


def _value(value):
    """A MaterialX value as a float, a tuple of floats, a bool or an int."""
    if isinstance(value, bool | int | float):
        return value
    if hasattr(value, "asTuple"):
        return tuple(float(x) for x in value.asTuple())
    try:
        return tuple(float(x) for x in value)
    except TypeError:
        return value


@cache
def _nodedef(category: str) -> tuple:
    """``(name, active inputs)`` of the nodedef MaterialX's generator picks for a surface shader node given no
    ``nodedef``, ``version`` or ``type`` of its own: each input ``(name, type, value, uimin, uimax)`` (plain
    values: MaterialX's elements die with their document)."""
    mx, _, _ = _materialx()
    doc = mx.createDocument()
    doc.importLibrary(load_materialx_libraries())
    nodedef = doc.addNode(category, NODE_NAME, "surfaceshader").getNodeDef()
    if nodedef is None:
        raise BackendError(f"MaterialX has no surfaceshader node {category!r}")
    inputs = tuple((inp.getName(), inp.getType(), _value(inp.getValue()) if inp.getValue() is not None else None,
                    *_limits(inp)) for inp in nodedef.getActiveInputs())  # fmt: skip
    return nodedef.getName(), inputs


def _limits(inp) -> tuple[str, str]:
    """An input's ``(uimin, uimax)``; for an integer input that only enumerates its values (glTF's ``alpha_mode``:
    ``enumvalues="0, 1, 2"``), the least and the greatest of them, which are its range, as each such
    enumeration of the four surface models counts up from 0 (an ``alpha_mode`` of 9 baked without a word)."""
    low, high = inp.getAttribute("uimin"), inp.getAttribute("uimax")
    values = inp.getAttribute("enumvalues")
    if inp.getType() == "integer" and not low and not high and values:
        numbers = [int(v) for v in values.split(",")]
        low, high = str(min(numbers)), str(max(numbers))
    return low, high


def _active_inputs(category: str) -> tuple:
    return _nodedef(category)[1]


def surface_nodedef(category: str) -> str:
    """The name of the nodedef the oracle shades for a surface shader node (``ND_standard_surface_surfaceshader``,
    say): the one MaterialX picks for a node with no ``nodedef``, ``version`` or ``type`` of its own."""
    return _nodedef(category)[0]


@cache
def _defaults(category: str) -> tuple:
    return tuple((name, kind, value) for name, kind, value, _, _ in _active_inputs(category) if value is not None)


def surface_defaults(category: str) -> dict:
    """``{input: (type, default)}`` of a surface shader node's nodedef: what an unset input is."""
    return {name: (kind, value) for name, kind, value in _defaults(category)}


@cache
def surface_inputs(category: str) -> dict:
    """``{input: type}`` of every input a surface shader node's nodedef declares, those without a
    default value too (the geometric ``normal`` and ``tangent``, glTF's ``attenuation_distance``)."""
    return {name: kind for name, kind, *_ in _active_inputs(category)}


def _bound(text: str):
    return tuple(float(x) for x in text.split(",")) if text.strip() else None


@cache
def surface_ranges(category: str) -> dict:
    """``{input: (low, high)}`` of a surface shader node's nodedef: its ``uimin`` and ``uimax``, each a
    tuple of floats (one per component) or None where the nodedef sets none. These are the inputs'
    hard limits (``uisoftmin``/``uisoftmax`` are the soft ones a user may pass), e.g. 0..1 for
    weights, roughnesses and colours, and ior >= 1 for glTF."""
    out = {}
    for name, _, _, uimin, uimax in _active_inputs(category):
        low, high = _bound(uimin), _bound(uimax)
        if low is not None or high is not None:
            out[name] = (low, high)
    return out


_BLOCK = re.compile(r"in\s+VertexData\s*\{(?P<body>[^}]*)\}\s*vd\s*;")
_MEMBER = re.compile(r"^\s*(?:flat\s+)?(?P<type>\w+)\s+(?P<name>\w+)\s*;", re.M)
#: Varyings the oracle sets to the local frame: the normal is +z, the tangent +x, P = -v.
_FRAME = {"normalWorld": "vec3(0.0, 0.0, 1.0)", "tangentWorld": "vec3(1.0, 0.0, 0.0)",
          "bitangentWorld": "vec3(0.0, 1.0, 0.0)", "positionWorld": "-atlasgen_view"}  # fmt: skip
#: The full-screen triangle the pass draws (one fragment per texel of the pair textures).
VERTEX_STAGE = """#version 400
in vec2 i_corner;
void main()
{
    gl_Position = vec4(i_corner, 0.0, 1.0);
}
"""


def varyings_of(pixel_source: str) -> list[tuple[str, str]]:
    """``(type, name)`` of each member of the pixel stage's ``VertexData`` block (they differ between surface models)."""
    match = _BLOCK.search(pixel_source)
    if match is None:
        raise BackendError("MaterialX's pixel stage has no VertexData block; expected MaterialX 1.39's GLSL layout")
    return [(m["type"], m["name"]) for m in _MEMBER.finditer(match["body"])]


def vertex_data_for(pixel_source: str) -> str:
    """GLSL statements that fill ``vd`` from the pixel stage's ``VertexData`` block: the local frame
    (:data:`_FRAME`) and 0.5 (texture coordinates) or 1 (colours) for the rest, which constant inputs never read."""
    lines = []
    for kind, name in varyings_of(pixel_source):
        if name in _FRAME:
            lines.append(f"    vd.{name} = {_FRAME[name]};")
        elif name.startswith("color"):
            lines.append(f"    vd.{name} = {kind}(1.0);")
        else:
            lines.append(f"    vd.{name} = {kind}(0.5);")
    return "\n".join(lines)


def adapt_pixel_stage(pixel_source: str) -> str:
    """MaterialX's pixel stage made to shade the (l, v) pair of its texel: ``vd`` and the light filled
    in ``main`` from two RGBA32F textures, and ``u_refractionTwoSided`` declared. The BSDF code is untouched."""
    declaration = "uniform LightData u_lightData[MAX_LIGHT_SOURCES];"
    if declaration not in pixel_source:
        raise BackendError("MaterialX's pixel stage declares no u_lightData array; expected MaterialX 1.39's GLSL layout")
    fill = vertex_data_for(pixel_source)
    block = _BLOCK.search(pixel_source)
    assert block is not None  # varyings_of found it
    src = (pixel_source[: block.start()] + "struct AtlasgenVertexData\n{" + block["body"] + "};\nAtlasgenVertexData vd;\n"
           "uniform sampler2D atlasgen_views;\nuniform sampler2D atlasgen_lights;\nvec3 atlasgen_view;\n"
           + pixel_source[block.end() :])  # fmt: skip
    src = src.replace(declaration, "LightData u_lightData[MAX_LIGHT_SOURCES];")
    src = declare_refraction_two_sided(src)
    head, sep, tail = src.rpartition("void main()\n{")
    if not sep:
        raise BackendError("MaterialX's pixel stage has no main(); expected MaterialX 1.39's GLSL layout")
    setup = f"""
    ivec2 atlasgen_texel = ivec2(gl_FragCoord.xy);
    atlasgen_view = texelFetch(atlasgen_views, atlasgen_texel, 0).xyz;
{fill}
    u_lightData[0].type = 1;
    u_lightData[0].direction = -texelFetch(atlasgen_lights, atlasgen_texel, 0).xyz;
    u_lightData[0].color = vec3(1.0);
    u_lightData[0].intensity = {LIGHT_INTENSITY:.1f};"""
    return head + sep + setup + tail


def generate_surface_stages(category: str, lights=(("directional_light", 1),), max_lights: int = 1) -> tuple[str, str]:
    """MaterialX's GLSL ``(vertex, pixel)`` stages for one node of ``category`` with every input a
    uniform, no environment light, and each ``(light node, id)`` of ``lights`` bound with
    ``bindLightShader`` (``u_lightData[i].type`` is the id), at most ``max_lights`` active."""
    mx, mx_shader, mx_glsl = _materialx()
    stdlib = load_materialx_libraries()
    doc = mx.createDocument()
    doc.importLibrary(stdlib)
    node = doc.addNode(category, NODE_NAME, "surfaceshader")
    material = doc.addMaterialNode("M", node)
    generator = mx_glsl.GlslShaderGenerator.create()
    context = mx_shader.GenContext(generator)
    context.registerSourceCodeSearchPath(mx.getDefaultDataSearchPath())
    options = context.getOptions()
    options.hwSpecularEnvironmentMethod = mx_shader.HwSpecularEnvironmentMethod.SPECULAR_ENVIRONMENT_NONE
    options.shaderInterfaceType = mx_shader.ShaderInterfaceType.SHADER_INTERFACE_COMPLETE
    options.hwMaxActiveLightSources = int(max_lights)
    light_doc = mx.createDocument()
    light_doc.importLibrary(stdlib)
    for kind, light_id in lights:
        light = light_doc.addNode(kind, f"L{light_id}", "lightshader")
        mx_shader.HwShaderGenerator.bindLightShader(light.getNodeDef(), int(light_id), context)
    shader = generator.generate("M", material, context)
    return shader.getSourceCode(mx_shader.VERTEX_STAGE), shader.getSourceCode(mx_shader.PIXEL_STAGE)


def compile_program(ctx, vertex: str, pixel: str, what: str):
    """``ctx.program`` of the two stages; a compile error is one line naming ``what`` (a BackendError)."""
    try:
        return ctx.program(vertex_shader=vertex, fragment_shader=pixel)
    except Exception as exc:  # moderngl raises its own error types with the driver's whole log
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise BackendError(f"{what} does not compile here: {first}") from None


def _generate(category: str) -> str:
    """MaterialX's GLSL pixel stage for one node of ``category`` with every input a uniform and one directional light (id 1)."""
    return generate_surface_stages(category)[1]


def declare_refraction_two_sided(src: str) -> str:
    """``src`` with ``u_refractionTwoSided`` declared (false) where MaterialX 1.39.5 uses it without declaring it."""
    if "u_refractionTwoSided" in src and not re.search(r"uniform\s+bool\s+u_refractionTwoSided\b", src):
        version, _, rest = src.partition("\n")
        src = f"{version}\nuniform bool u_refractionTwoSided = false;\n{rest}"
    return src


@lru_cache(maxsize=1)
def gl_context():
    """moderngl's standalone EGL context (Mesa's llvmpipe), one per process; enter it under :data:`GL_LOCK`
    (``with GL_LOCK, gl_context() as ctx``) to make it current on the calling thread."""
    try:
        import moderngl
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise BackendError(f"moderngl is not installed ({exc}); install the 'materialx' extra") from None
    try:
        return moderngl.create_context(standalone=True, backend="egl")
    except Exception as exc:  # pragma: no cover - depends on the machine
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise BackendError(
            f"no headless OpenGL context for the MaterialX oracle (EGL: {first}); install libegl1, libegl-mesa0"
        ) from None


_parking: list = []


def park_framebuffer(ctx) -> None:
    """Bind a 1x1 framebuffer kept for the process, before releasing the one in use: moderngl rebinds
    the last bound framebuffer whenever it creates one, and rebinding a deleted one is GL_INVALID_OPERATION."""
    if not _parking:
        _parking.append(ctx.framebuffer(color_attachments=[ctx.renderbuffer((1, 1))]))
    _parking[0].use()


def set_surface_inputs(program, uniforms, category: str, inputs: dict) -> None:
    """Set every input uniform ``<NODE_NAME>_<input>`` of a ``category`` program still in ``uniforms``
    (the compiler removes what changes nothing) to ``inputs[input]``, or its nodedef default."""
    for name, (kind, default) in surface_defaults(category).items():
        uniform = f"{NODE_NAME}_{name}"
        if uniform not in uniforms:
            continue
        value = inputs.get(name, default)
        if kind == "boolean":
            value = int(bool(value))
        elif kind == "integer":
            value = int(value)
        elif isinstance(value, list | tuple):
            value = tuple(float(x) for x in value)
        elif kind in ("float",):
            value = float(value)
        else:
            continue  # strings, filenames: no uniform a constant input sets
        program[uniform].value = value


@dataclass
class MaterialXOracle:
    """One surface model's program; :meth:`f_cos` evaluates any material of it."""

    category: str
    pixel_source: str
    program: Any
    uniforms: frozenset
    _triangle: Any = None

    def f_cos(self, inputs: dict, l, v) -> np.ndarray:
        """f cos(theta_l) ``(N, 3)`` at unit (l, v) ``(N, 3)`` (n = +z) for the node's ``inputs``
        (``{name: value}``; every other input at its nodedef default)."""
        import moderngl

        l = np.asarray(l, dtype=np.float32).reshape(-1, 3)
        v = np.asarray(v, dtype=np.float32).reshape(-1, 3)
        if l.shape != v.shape:
            raise ValueError(f"l and v must have the same shape, got {l.shape} and {v.shape}")
        out = np.zeros((l.shape[0], 3))
        if l.shape[0] == 0:
            return out
        with GL_LOCK, gl_context() as ctx:  # current on this thread: Mitsuba calls its plugins from worker threads
            self._set_inputs(inputs)
            self.program["u_viewPosition"].value = (0.0, 0.0, 0.0)
            self.program["u_numActiveLightSources"].value = 1
            for start in range(0, l.shape[0], CHUNK):
                count = min(CHUNK, l.shape[0] - start)
                rows = -(-count // _WIDTH)
                textures = []
                for unit, (name, pairs) in enumerate((("atlasgen_views", v), ("atlasgen_lights", l))):
                    data = np.zeros((rows * _WIDTH, 4), dtype=np.float32)
                    data[:count, :3] = pairs[start : start + count]
                    texture = ctx.texture((_WIDTH, rows), 4, data.tobytes(), dtype="f4")
                    texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
                    texture.use(unit)
                    self.program[name].value = unit
                    textures.append(texture)
                target = ctx.texture((_WIDTH, rows), 4, dtype="f4")
                fbo = ctx.framebuffer(color_attachments=[target])
                fbo.use()
                ctx.viewport = (0, 0, _WIDTH, rows)
                self._triangle.render(moderngl.TRIANGLES, vertices=3)
                pixels = np.frombuffer(fbo.read(components=4, dtype="f4"), dtype=np.float32).reshape(rows * _WIDTH, 4)
                out[start : start + count] = pixels[:count, :3] / LIGHT_INTENSITY
                park_framebuffer(ctx)
                for obj in (fbo, target, *textures):
                    obj.release()
        return out

    def _set_inputs(self, inputs: dict) -> None:
        set_surface_inputs(self.program, self.uniforms, self.category, inputs)


@cache
def materialx_oracle(category: str) -> MaterialXOracle:
    """The compiled oracle of one surface model (generated and compiled once per process)."""
    if category not in SURFACE_MODELS:
        raise BackendError(f"no MaterialX oracle for {category!r}; expected one of {', '.join(SURFACE_MODELS)}")
    pixel = adapt_pixel_stage(_generate(category))
    with GL_LOCK, gl_context() as ctx:
        program = compile_program(ctx, VERTEX_STAGE, pixel, f"MaterialX's {category} shader")
        corners = ctx.buffer(np.array([-1.0, -1.0, 3.0, -1.0, -1.0, 3.0], dtype="f4").tobytes())
        triangle = ctx.vertex_array(program, [(corners, "2f", "i_corner")])
    return MaterialXOracle(category, pixel, program, frozenset(program), triangle)


def evaluate_materialx_f_cos(category: str, inputs: dict, l, v) -> np.ndarray:
    """f cos(theta_l) ``(N, 3)`` of a ``category`` surface with constant ``inputs`` at unit (l, v) ``(N, 3)``."""
    return materialx_oracle(category).f_cos(inputs, l, v)
