"""The frame: g-buffer, deferred lighting, deferred translucency, outlines, read-back.

Order of passes in one frame (each a WebGPU render pass):

1. g-buffer, opaque objects (clear; stencil reference 0);
2. light culling (:mod:`.culling`, a compute pass): a light list per 16 x 16 tile, when some
   light has a range (without one every light reaches every pixel, and nothing is culled);
3. lighting, opaque (every pixel; background where the material ID is 0xFFFF), over each
   tile's list;
4. for each translucent object, far to near (:mod:`.translucency`): g-buffer with
   stencil marking, culling again over its screen rectangle against the depths it left,
   stencil-masked lighting blended with the object's opacity;
5. outlines (:mod:`.outline`) over the final g-buffer.

Each pass is a step labelled for timing (:meth:`Renderer.frame_steps`, :mod:`.timing`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from atlasgen.errors import BackendError, SceneError
from atlasgen.io.fields import FLOAT32_MAX
from atlasgen.materials.scene import MAX_LIGHTS, Scene, object_matrix, resolve_materials, shading_gloss
from atlasgen.models import get_model
from atlasgen.render.atlas_data import RendererInclude, upload_tables
from atlasgen.render.atlas_texture import RenderAtlas, upload_atlas
from atlasgen.render.camera import camera_basis, projection_matrix, tangents, view_matrix
from atlasgen.render.culling import (
    DEFAULT_TILE_CAPACITY,
    CullingPass,
    TileLists,
    create_tile_texture,
    fitting_capacity,
    pack_cull,
    read_tile_texture,
    tile_grid,
    tile_rectangle,
    tile_texture_size,
    upload_light_spheres,
)
from atlasgen.render.device import get_device
from atlasgen.render.environment import EnvironmentLighting, shows_environment
from atlasgen.render.gbuffer import GBuffer, GBufferPass, decode_normals, pack_object
from atlasgen.render.layout import FRAME, NO_MATERIAL, OBJECT, OBJECT_UNIFORM_STRIDE, LightType, declaration_wgsl
from atlasgen.render.lighting import LightingPass, check_light_distances, material_dispatch_wgsl, pack_lights, upload_lights
from atlasgen.render.meshes import MAX_SCENE_TRIANGLES, Mesh, build_mesh
from atlasgen.render.outline import OutlinePass, outline_parameters
from atlasgen.render.translucency import screen_rectangle, sort_back_to_front, translucent_steps
from atlasgen.shaders.passes import assemble_shader

__all__ = ["Renderer", "RenderResult", "TranslucentStep", "pack_frame", "AOVS"]

#: G-buffer layers ``--aov`` can dump.
AOVS = ("normal", "depth", "id", "albedo")


@dataclass
class TranslucentStep:
    """What one translucent object did (``trace=True``): its stencil mask and the frame after it."""

    object_index: int
    stencil: np.ndarray  # (h, w) bool: pixels it won in the g-buffer
    radiance: np.ndarray  # (h, w, 3) float32 after blending it in
    tile_lists: TileLists | None = None  # the lists it was lit with (culled frames)
    depth: np.ndarray | None = None  # (h, w) g-buffer view depth after it (inf where empty)


@dataclass
class RenderResult:
    """Linear radiance and, when read, the final g-buffer layers."""

    radiance: np.ndarray  # (h, w, 3) float32, W/(m^2 sr)
    aovs: dict = field(default_factory=dict)
    opaque_radiance: np.ndarray | None = None  # after the opaque lighting (trace only)
    opaque_tile_lists: TileLists | None = None  # the opaque layer's lists (trace of a culled frame)
    opaque_depth: np.ndarray | None = None  # (h, w) the opaque layer's view depth (trace only)
    tile_lists: TileLists | None = None  # the last lists built (culled frames, with aovs)
    steps: list = field(default_factory=list)
    draw_order: list = field(default_factory=list)  # object indices, opaque first then translucent far to near

    def aov(self, name: str) -> np.ndarray:
        """``normal`` (h, w, 3) world unit normals (0 where empty), ``depth`` (h, w) view
        depth (inf where empty), ``id`` (h, w) uint16 material slice (65535 where empty),
        ``albedo`` (h, w, 3) linear albedo (0 where empty)."""
        return self.aovs[name]


@dataclass
class _GpuMesh:
    vertices: object
    indices: object
    index_count: int
    bounds: np.ndarray  # (2, 3) object-space min, max
    closed: bool = False  # drawn with back faces culled (Mesh.closed)


def pack_frame(scene: Scene, mip_levels: int, mip_bias: float | None = None, tile_capacity: int | None = None) -> bytes:
    """The ``Frame`` uniform for ``scene`` (declared as :data:`atlasgen.render.layout.FRAME`);
    ``tile_capacity`` (lights a tile list holds) when the frame is culled, ``None`` for the full loop."""
    cam, w, h = scene.camera, scene.width, scene.height
    right, up, forward = camera_basis(cam)
    tan_x, tan_y = tangents(cam, w, h)
    view_proj = projection_matrix(cam, w, h) @ view_matrix(cam)
    s = scene.settings
    depth_threshold, normal_cos = outline_parameters(s)
    bias = s.mip_bias if mip_bias is None else mip_bias
    texels, _, layers = tile_texture_size(w, h, tile_capacity or 0, len(scene.lights), tile_capacity is not None)
    return FRAME.pack(
        view_proj=view_proj,
        eye=[*cam.position, 1.0],
        forward=[*forward, tan_x],
        right=[*right, tan_y],
        up=[*up, 0.0],
        viewport=[w, h, 1.0 / w, 1.0 / h],
        background=[*scene.background, 1.0],
        mip=[bias, s.mip_distance, mip_levels - 1, 0.0],
        counts=[len(scene.lights), 0, 0, 0]
        if tile_capacity is None
        else [len(scene.lights), 1, tile_grid(w, h)[0], tile_capacity],
        lists=[layers - 1, texels.bit_length() - 1, 0, 0],
        outline_colour=[*s.outline_colour, 1.0],
        outline=[depth_threshold, normal_cos, 0.0, 0.0],
    )


class Renderer:
    """Renders scenes with one atlas on one device.

    Parameters
    ----------
    atlas
        The baked atlas with its manifest and generated include.
    ctx
        A :class:`~atlasgen.render.device.GpuContext`; the shared one by default.
    culling
        Cull lights per tile when a scene has lights with a range; ``False`` loops over every
        light at every pixel (the brute-force baseline, same image).
    tile_capacity
        Light indices each tile's list holds; a tile with more is lit by the full loop.
    """

    def __init__(self, atlas: RenderAtlas, ctx=None, culling: bool = True, tile_capacity: int = DEFAULT_TILE_CAPACITY):
        import wgpu

        self.ctx = ctx or get_device()
        self.atlas = atlas
        device = self.ctx.device
        self.device = device
        self.atlas_texture = upload_atlas(self.ctx, atlas)
        # The include's functions with its per-bake tables in buffers (atlas_data.py): what the passes compile.
        self.include = RendererInclude.of(atlas.manifest)
        self.atlas_tables = upload_tables(device, self.include)
        self.frame_layout = device.create_bind_group_layout(
            label="frame",
            entries=[{
                "binding": 0,
                "visibility": wgpu.ShaderStage.VERTEX | wgpu.ShaderStage.FRAGMENT,
                "buffer": {"type": "uniform"},
            }],
        )  # fmt: skip
        self.gbuffer_pass = GBufferPass(device, self.frame_layout)
        self.culling = culling
        self.tile_capacity = int(tile_capacity)
        self._culling_pass: CullingPass | None = None  # compiled on the first culled frame
        self._lighting_passes: dict = {}
        self.environment = EnvironmentLighting(self.ctx, atlas)
        self.outline_pass = OutlinePass(device, self.include.text)
        self._meshes: dict = {}
        self._given_meshes: dict[str, Mesh] = {}
        self._gbuffers: dict = {}
        self._fence = None

    # ---- resources -------------------------------------------------------------------

    def set_atlas(self, atlas: RenderAtlas) -> bool:
        """Render with ``atlas`` from now on, as ``Renderer(atlas, ctx)`` would, keeping what does not
        depend on it: the device, the g-buffer pipeline, meshes and render targets.

        The texture and the include's tables (scales, biases, factor tables: :mod:`.atlas_data`) are
        uploaded again. The lighting and outline shaders hold the include's functions (and the lighting
        one each custom-lit material's call), so they are compiled again only when those changed: a
        material renamed, moved, flagged or of another type, not a new scale. On lavapipe a compile
        costs more than everything else an update does. Returns whether they were.
        """
        old, old_include = self.atlas, self.include
        self.atlas = atlas
        self.atlas_texture = upload_atlas(self.ctx, atlas)
        self.include = RendererInclude.of(atlas.manifest)
        self.atlas_tables = upload_tables(self.device, self.include)
        self.environment = self.environment.for_atlas(atlas)  # the slices' tables follow the texels
        recompile = self.include.text != old_include.text or (
            material_dispatch_wgsl(atlas.manifest) != material_dispatch_wgsl(old.manifest)
        )
        if recompile:
            self._lighting_passes = {}
            self.outline_pass = OutlinePass(self.device, self.include.text)
        return recompile

    def add_mesh(self, file, mesh: Mesh) -> None:
        """Draw ``shape = "mesh"`` objects whose ``file`` is ``file`` with ``mesh``, not with what the file holds.

        For meshes made in memory (the preview's material ball): a scene still names a file, which
        its parser checks exists, but the renderer does not read it, so trimesh (0.9 s to import)
        is never loaded.
        """
        key = str(Path(file))
        self._given_meshes[key] = mesh
        self._meshes = {k: v for k, v in self._meshes.items() if k[1] != key}

    def lighting_pass_for(self, shaded_ids=frozenset(), environment: bool = False, light_kinds=tuple(LightType)) -> LightingPass:
        """The lighting pass compiled for the materials a scene shows whose model shades them
        itself (``custom_lighting``, e.g. separable BRDFs).

        A lighting shader that merely contains the separable reconstruction runs ~9x
        slower on lavapipe at 720p even when no pixel takes that branch (measured: 3.8 s
        against 0.43 s for 16 lights and 4 translucent objects), so a model's own code is
        only compiled in for scenes that use one of its materials. The environment term likewise
        (``environment``): a scene without one runs the shader without it, and the code of directional and spot
        lights runs only where ``light_kinds`` (:class:`~atlasgen.render.layout.LightType` values) holds them.
        """
        ids = frozenset(shaded_ids)
        kinds = frozenset(LightType(k) for k in light_kinds) & {LightType.DIRECTIONAL, LightType.SPOT}
        key = (ids, environment, kinds)
        if key not in self._lighting_passes:
            self._lighting_passes[key] = LightingPass(
                self.device, self.include.text, self.atlas.manifest, ids, environment, kinds
            )
        return self._lighting_passes[key]

    @property
    def culling_pass(self) -> CullingPass:
        """The light-culling pipeline, compiled when a frame first needs it (a scene without ranges never does)."""
        if self._culling_pass is None:
            self._culling_pass = CullingPass(self.device)
        return self._culling_pass

    @staticmethod
    def _mesh_key(obj) -> tuple:
        """What makes an object's mesh: objects with one key share one."""
        return (obj.shape, str(obj.file), obj.segments, obj.minor_radius)

    def _mesh(self, obj, scene_path="<scene>") -> _GpuMesh:
        key = self._mesh_key(obj)
        if key not in self._meshes:
            import wgpu

            given = self._given_meshes.get(str(obj.file)) if obj.shape == "mesh" else None
            mesh = given if given is not None else build_mesh(obj, scene_path)
            usage = wgpu.BufferUsage.COPY_DST
            vertices = self.device.create_buffer_with_data(data=mesh.interleaved(), usage=wgpu.BufferUsage.VERTEX | usage)
            indices = self.device.create_buffer_with_data(data=mesh.indices.ravel(), usage=wgpu.BufferUsage.INDEX | usage)
            bounds = np.stack([mesh.positions.min(0), mesh.positions.max(0)]).astype(np.float64)
            self._meshes[key] = _GpuMesh(vertices, indices, int(mesh.indices.size), bounds, bool(mesh.closed))
        return self._meshes[key]

    def _gbuffer(self, width, height):
        key = (width, height)
        if key not in self._gbuffers:
            import wgpu

            hdr = self.device.create_texture(
                label="radiance",
                size=(width, height, 1),
                format=wgpu.TextureFormat.rgba16float,
                usage=wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.COPY_SRC,
            )
            self._gbuffers = {key: (GBuffer.create(self.device, width, height), hdr)}  # keep one size only
        return self._gbuffers[key]

    def prepare(self, scene: Scene, mip_bias: float | None = None, culling: bool | None = None) -> _PreparedFrame:
        """Upload everything a frame of ``scene`` needs; raise SceneError for what the atlas lacks.

        ``culling`` overrides the renderer's setting for this frame. A frame is culled only when some
        light has a range: otherwise every list would hold every light.
        """
        import wgpu

        if len(scene.lights) > MAX_LIGHTS:
            raise SceneError(scene.path, "lights", f"{len(scene.lights)} lights; expected at most {MAX_LIGHTS}")
        entries = resolve_materials(scene, self.atlas.manifest, self.atlas.name)
        gbuffer, hdr = self._gbuffer(scene.width, scene.height)
        device = self.device
        culled = (self.culling if culling is None else culling) and any(light.bounded for light in scene.lights)
        capacity = fitting_capacity(scene.width, scene.height, self.tile_capacity, len(scene.lights))
        frame_buffer = device.create_buffer_with_data(
            data=pack_frame(scene, len(self.atlas.levels), mip_bias, capacity if culled else None),
            usage=wgpu.BufferUsage.UNIFORM,
        )
        object_data = bytearray()
        draws, centres, rectangles, farthest, boxes = [], [], [], [], []
        view_proj = projection_matrix(scene.camera, scene.width, scene.height) @ view_matrix(scene.camera)
        _, _, forward = camera_basis(scene.camera)
        eye = np.asarray(scene.camera.position, dtype=np.float64)
        triangles: dict = {}
        for obj, entry in zip(scene.objects, entries):
            mesh = self._mesh(obj, scene.path)
            triangles[self._mesh_key(obj)] = mesh.index_count // 3
            total = sum(triangles.values())
            if total > MAX_SCENE_TRIANGLES:
                raise SceneError(scene.path, f"objects[{obj.index}]", f"{total} triangles in the "
                                 f"scene's meshes with this object's; expected at most {MAX_SCENE_TRIANGLES} in all "
                                 "(fewer segments, or objects sharing a mesh)")  # fmt: skip
            model = object_matrix(obj)
            object_data += pack_object(model, obj.albedo, shading_gloss(obj.gloss, entry), entry.first_slice)
            corners = np.array([[x, y, z, 1.0] for x in mesh.bounds[:, 0] for y in mesh.bounds[:, 1] for z in mesh.bounds[:, 2]])
            world = (model @ corners.T).T[:, :3]
            if not np.all(np.abs(world) <= FLOAT32_MAX):
                # Each field fits float32, but their product may not: the GPU's vertices would be inf, the object not drawn.
                raise SceneError(scene.path, f"objects[{obj.index}]", "expected the object within float32's range once "
                                 f"scaled, rotated and translated, got a bounding-box corner at {float(np.max(np.abs(world))):.3g}")  # fmt: skip
            boxes.append((world.min(0), world.max(0)))
            centres.append(0.5 * (world.min(0) + world.max(0)))
            farthest.append(float(np.max((world - eye) @ forward)))
            rectangles.append(screen_rectangle(world, view_proj, scene.width, scene.height))
            draws.append((mesh, len(draws)))
        check_light_distances(scene, boxes)
        if not object_data:
            object_data = bytearray(OBJECT_UNIFORM_STRIDE)
        object_buffer = device.create_buffer_with_data(data=bytes(object_data), usage=wgpu.BufferUsage.UNIFORM)
        frame_group = device.create_bind_group(
            layout=self.frame_layout, entries=[{"binding": 0, "resource": {"buffer": frame_buffer}}]
        )
        object_group = device.create_bind_group(
            layout=self.gbuffer_pass.object_layout,
            entries=[{"binding": 0, "resource": {"buffer": object_buffer, "offset": 0, "size": OBJECT.size}}],
        )
        custom = [get_model(e.type).custom_lighting for e in entries]
        lighting_pass = self.lighting_pass_for(
            (e.first_slice for e, c in zip(entries, custom) if c),
            scene.environment is not None,
            {LightType[light.type.upper()] for light in scene.lights},
        )
        environment = self.environment.bindings(scene, entries, custom)
        # Opaque objects nearest first, by their bounding box's farthest view depth (a floor behind
        # everything goes last): the depth test then rejects covered pixels before shading them,
        # instead of shading a floor that spheres overwrite. Only exact depth ties could tell.
        opaque = sorted((i for i, o in enumerate(scene.objects) if not o.translucent), key=lambda i: (farthest[i], i))
        translucent = sort_back_to_front(scene.objects, centres, scene.camera)
        # Culling dispatch 0 covers the screen; dispatch 1 + n the tiles of translucent object n's rectangle.
        cull_tiles = [tile_rectangle(None, scene.width, scene.height)]
        cull_tiles += [
            tile_rectangle(rectangles[i], scene.width, scene.height) if rectangles[i] else (0, 0, 0, 0) for i in translucent
        ]
        # An unculled frame reads only the texture's layer of every light; a culled one's lists copy the
        # lights' rows from their own texture (a pass cannot read the texture it writes).
        lights = pack_lights(scene.lights)
        tile_texture = create_tile_texture(device, scene.width, scene.height, capacity if culled else 0, lights, culled)
        light_texture = upload_lights(device, lights) if culled else None
        cull_buffer = device.create_buffer_with_data(data=pack_cull(cull_tiles), usage=wgpu.BufferUsage.UNIFORM)
        sphere_texture = upload_light_spheres(device, scene)
        cull_group = (
            self.culling_pass.bind_group(frame_buffer, sphere_texture, light_texture, gbuffer, tile_texture, cull_buffer)
            if culled
            else None
        )
        lighting_group = lighting_pass.bind_group(
            frame_buffer, gbuffer, self.atlas_texture, environment, tile_texture, self.atlas_tables
        )
        outline_group = self.outline_pass.bind_group(frame_buffer, gbuffer)
        # The outline pass only draws next to flagged materials: over their objects' rectangles, and
        # not at all when none is on screen.
        outline_rectangles = [r for r, entry in zip(rectangles, entries) if r is not None and entry.flag("outline")]
        return _PreparedFrame(scene, gbuffer, hdr, frame_group, object_group, lighting_pass, lighting_group, outline_group,
                              draws, opaque, translucent, rectangles, outline_rectangles,
                              (frame_buffer, light_texture, object_buffer, environment, cull_buffer, sphere_texture),
                              culled, cull_group, cull_tiles, tile_texture, capacity)  # fmt: skip

    # ---- encoding ----------------------------------------------------------------------

    def frame_steps(self, frame: _PreparedFrame, outlines: bool = True, trace=None) -> list:
        """The frame's passes in order: ``(label, encode(encoder, timestamps))`` for each, and, when
        tracing, ``(None, with_mask)`` markers where the frame is to be read (after the opaque
        lighting and after each translucent object). Labels: ``gbuffer``, ``culling``, ``lighting``,
        ``translucency`` (a translucent object's g-buffer, culling and lighting passes), ``outlines``."""
        objs = frame.scene.objects
        g = frame.gbuffer

        def opaque_gbuffer(encoder, timestamps=None):
            self.gbuffer_pass.encode(encoder, g, frame.frame_group, frame.object_group, [frame.draws[i] for i in frame.opaque],
                                     clear=True, stencil_reference=0, timestamps=timestamps)  # fmt: skip

        def cull(step):
            def encode(encoder, timestamps=None):
                self.culling_pass.encode(encoder, frame.cull_group, step, frame.cull_tiles[step], timestamps)

            return encode

        def opaque_lighting(encoder, timestamps=None):
            self._encode_opaque_lighting(encoder, frame, timestamps)

        steps = [("gbuffer", opaque_gbuffer)]
        if frame.culled:
            steps.append(("culling", cull(0)))
        steps.append(("lighting", opaque_lighting))
        for n, i in enumerate(frame.translucent):
            if trace is not None:
                steps.append((None, n > 0))
            after = None if trace is None else (lambda encoder, timestamps=None: trace.copy_stencil(encoder))
            steps += [("translucency", step) for step in translucent_steps(
                self.gbuffer_pass, frame.lighting_pass, g, frame.hdr, frame.frame_group, frame.object_group,
                frame.lighting_group, frame.draws[i], objs[i].opacity, scissor=frame.rectangles[i], after=after,
                cull=cull(1 + n) if frame.culled else None)]  # fmt: skip
        if trace is not None:
            steps.append((None, bool(frame.translucent)))
        if outlines and frame.outline_rectangles:
            steps.append(("outlines", lambda encoder, timestamps=None: self.outline_pass.encode(
                encoder, frame.hdr, frame.outline_group, frame.outline_rectangles, timestamps)))  # fmt: skip
        return steps

    def encode_frame(self, frame: _PreparedFrame, outlines: bool = True, trace=None):
        """Command buffers for one whole frame (several when tracing, to read in between)."""
        buffers = []
        encoder = self.device.create_command_encoder()
        for label, item in self.frame_steps(frame, outlines, trace):
            if label is None:
                buffers.append(encoder.finish())
                buffers.append((trace, item))  # marker: read the frame (and the last stencil mask) here
                encoder = self.device.create_command_encoder()
            else:
                item(encoder)
        buffers.append(encoder.finish())
        return buffers

    def encode_lighting(self, frame: _PreparedFrame):
        """One command buffer holding only the opaque lighting pass (for benchmarks)."""
        encoder = self.device.create_command_encoder()
        self._encode_opaque_lighting(encoder, frame)
        return encoder.finish()

    @staticmethod
    def _encode_opaque_lighting(encoder, frame: _PreparedFrame, timestamps=None) -> None:
        """The opaque lighting pass: over every pixel where the background shows the environment, else
        over the pixels some object covers, the rest cleared to the background colour."""
        frame.lighting_pass.encode(encoder, frame.hdr, frame.gbuffer, frame.lighting_group, background=frame.scene.background,
                                   timestamps=timestamps, shade_background=shows_environment(frame.scene))  # fmt: skip

    def submit(self, command_buffers) -> None:
        """Submit and wait until the GPU is done.

        Waiting maps a 4-byte buffer that the last command buffer copies into: a mapping
        completes only after the submission that wrote it (wgpu-py 0.32's
        ``on_submitted_work_done`` is broken against its wgpu-native).
        """
        import wgpu

        if self._fence is None:
            src = self.device.create_buffer(size=4, usage=wgpu.BufferUsage.COPY_SRC)
            dst = self.device.create_buffer(size=4, usage=wgpu.BufferUsage.COPY_DST | wgpu.BufferUsage.MAP_READ)
            self._fence = (src, dst)
        src, dst = self._fence
        encoder = self.device.create_command_encoder()
        encoder.copy_buffer_to_buffer(src, 0, dst, 0, 4)
        self.device.queue.submit([*command_buffers, encoder.finish()])
        dst.map_sync("READ")
        dst.unmap()

    # ---- the whole thing ------------------------------------------------------------

    def render(self, scene: Scene, mip_bias: float | None = None, outlines: bool = True,
               aovs: bool = True, trace: bool = False, culling: bool | None = None) -> RenderResult:  # fmt: skip
        """Render ``scene``; read back radiance and (``aovs``) the g-buffer layers and tile lists.

        ``trace`` records, for each translucent object, its stencil mask and the frame
        after blending it (:class:`TranslucentStep`), for tests and debugging. ``culling``
        overrides the renderer's setting (``False``: the full loop over every light).

        Raises :class:`BackendError` if the device reported a validation error.
        """
        before = len(self.ctx.errors)
        frame = self.prepare(scene, mip_bias, culling)
        tracer = _Tracer(self, frame) if trace else None
        pending = []
        for item in self.encode_frame(frame, outlines, tracer):
            if isinstance(item, tuple):
                self.submit(pending)
                pending = []
                tracer.read(with_mask=item[1])
            else:
                pending.append(item)
        self.submit(pending)
        result = RenderResult(self.read_radiance(frame))
        result.draw_order = list(frame.opaque) + list(frame.translucent)
        if tracer is not None:
            result.opaque_radiance = tracer.frames[0]
            result.opaque_tile_lists, result.opaque_depth = tracer.tiles[0], tracer.depths[0]
            result.steps = [
                TranslucentStep(i, mask, rad, tiles, depth)
                for i, mask, rad, tiles, depth in zip(
                    frame.translucent, tracer.masks, tracer.frames[1:], tracer.tiles[1:], tracer.depths[1:]
                )  # fmt: skip
            ]
        if aovs:
            result.aovs = self.read_aovs(frame)
            result.tile_lists = self.read_tile_lists(frame)
        errors = self.ctx.errors[before:]
        if errors:
            raise BackendError(f"the GPU device reported {len(errors)} error(s); first: {errors[0].splitlines()[0]}")
        return result

    # ---- read-back ------------------------------------------------------------------

    def _read(self, texture, bytes_per_pixel, dtype, channels, width, height, aspect="all"):
        data = self.device.queue.read_texture(
            {"texture": texture, "mip_level": 0, "origin": (0, 0, 0), "aspect": aspect},
            {"offset": 0, "bytes_per_row": bytes_per_pixel * width, "rows_per_image": height},
            (width, height, 1),
        )
        return np.frombuffer(data, dtype=dtype).reshape(height, width, channels).copy()

    def read_tile_lists(self, frame) -> TileLists | None:
        """The light lists the last culling pass left (``None`` for a frame that is not culled)."""
        if not frame.culled:
            return None
        g = frame.gbuffer
        return read_tile_texture(self.device, frame.tile_texture, g.width, g.height, frame.tile_capacity)

    def read_radiance(self, frame) -> np.ndarray:
        w, h = frame.gbuffer.width, frame.gbuffer.height
        return self._read(frame.hdr, 8, np.float16, 4, w, h)[..., :3].astype(np.float32)

    def read_aovs(self, frame) -> dict:
        g = frame.gbuffer
        albedo_gloss = self._read(g.albedo_gloss, 8, np.float16, 4, g.width, g.height).astype(np.float32)
        normal_depth = self._read(g.normal_depth, 8, np.uint32, 2, g.width, g.height)
        ids = self._read(g.material, 2, np.uint16, 1, g.width, g.height)[..., 0]
        empty = ids == NO_MATERIAL
        depth = np.where(empty, np.inf, normal_depth[..., 1].view(np.float32)).astype(np.float32)
        return {
            "normal": np.where(empty[..., None], 0.0, decode_normals(normal_depth[..., 0])).astype(np.float32),
            "depth": depth,
            "id": ids,
            "albedo": albedo_gloss[..., :3],
            "gloss": albedo_gloss[..., 3],
        }


@dataclass
class _PreparedFrame:
    scene: Scene
    gbuffer: GBuffer
    hdr: object
    frame_group: object
    object_group: object
    lighting_pass: LightingPass
    lighting_group: object
    outline_group: object
    draws: list
    opaque: list
    translucent: list
    rectangles: list  # per object: screen rectangle (x, y, w, h) of its bounding box, None if off screen
    outline_rectangles: list  # screen rectangles of the objects whose material has flags.outline
    keepalive: tuple
    culled: bool = False  # lit through tile light lists
    cull_group: object = None
    cull_tiles: list = field(default_factory=list)  # per culling dispatch: tile rectangle (x0, y0, nx, ny)
    tile_texture: object = None
    tile_capacity: int = 0  # lights a tile list holds (culling.fitting_capacity)


class _Tracer:
    """Reads the frame and stencil between translucent objects (``render(trace=True)``).

    The stencil is read through a pass that writes 1 to an ``r8unorm`` target wherever
    a stencil test ``== 1`` passes: that is exactly the set the lighting pass shades.
    """

    def __init__(self, renderer: Renderer, frame: _PreparedFrame):
        import wgpu

        self.renderer, self.frame = renderer, frame
        device = renderer.device
        g = frame.gbuffer
        self.mask = device.create_texture(
            label="stencil-mask", size=(g.width, g.height, 1), format=wgpu.TextureFormat.r8unorm,
            usage=wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.COPY_SRC,
        )  # fmt: skip
        module = device.create_shader_module(
            label="stencil-mask", code=assemble_shader("common.wgsl", "stencil_mask.wgsl", declare=declaration_wgsl)
        )
        stencil = {"compare": "equal", "fail_op": "keep", "depth_fail_op": "keep", "pass_op": "keep"}
        self.pipeline = device.create_render_pipeline(
            label="stencil-mask",
            layout=device.create_pipeline_layout(bind_group_layouts=[]),
            vertex={"module": module, "entry_point": "vs_fullscreen", "buffers": []},
            primitive={"topology": "triangle-list", "cull_mode": "none"},
            depth_stencil={
                "format": wgpu.TextureFormat.depth24plus_stencil8, "depth_write_enabled": False,
                "depth_compare": "always", "stencil_front": stencil, "stencil_back": stencil,
                "stencil_read_mask": 0xFF, "stencil_write_mask": 0,
            },
            fragment={"module": module, "entry_point": "fs_main", "targets": [{"format": wgpu.TextureFormat.r8unorm}]},
        )  # fmt: skip
        self.frames, self.masks, self.tiles, self.depths = [], [], [], []

    def copy_stencil(self, encoder):
        pass_ = encoder.begin_render_pass(
            color_attachments=[{"view": self.mask.create_view(), "load_op": "clear", "store_op": "store",
                                "clear_value": (0, 0, 0, 0)}],
            depth_stencil_attachment={
                "view": self.frame.gbuffer.depth_stencil.create_view(),
                "depth_read_only": True,
                "stencil_read_only": True,
            },
        )  # fmt: skip
        pass_.set_pipeline(self.pipeline)
        pass_.set_stencil_reference(1)
        pass_.draw(3)
        pass_.end()

    def read(self, with_mask: bool):
        self.frames.append(self.renderer.read_radiance(self.frame))
        self.tiles.append(self.renderer.read_tile_lists(self.frame))
        self.depths.append(self.renderer.read_aovs(self.frame)["depth"])
        if with_mask:
            g = self.frame.gbuffer
            self.masks.append(self.renderer._read(self.mask, 1, np.uint8, 1, g.width, g.height)[..., 0] == 255)
