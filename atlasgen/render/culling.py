"""Tiled light culling on the GPU (cull.wgsl), its CPU reference and its read-back.

The screen is cut into :data:`~atlasgen.render.layout.TILE_SIZE` x ``TILE_SIZE`` tiles (Andersson 2011;
Olsson & Assarsson 2011). After a g-buffer pass, one compute workgroup per tile takes the min and max
view depth of the tile's covered pixels and keeps each light whose sphere (position, range) is not
wholly outside one of the tile's four side planes, nor outside the box that bounds the tile's frustum
between those depths; unbounded lights are always kept. The lighting pass then loops over its tile's list only.

A coarse step runs first, once per frame: per block of ``COARSE_TILES`` x ``COARSE_TILES`` tiles, a bit
mask of the lights not wholly outside the block's side planes; each
tile then tests only its block's lights. No depths enter it, so the translucent layers' culls reuse it.

Lists live in one ``rgba32uint`` texture array (:func:`create_tile_texture`): row tx of layer ty is tile
(tx, ty)'s list, its count first, then for each light, in light order, a copy of the light's first
``ENTRY_TEXELS`` texels (position, range, radiant and its index), so the lighting pass reads a listed light
in two fetches and no dependent one. A texture, not a storage buffer: lavapipe reads a storage buffer at a
per-pixel index lane by lane, each with a bounds check, and a texel fetch as one vector gather. The
texture's last layer holds every light's texels, for the full loop. The count is the true one: a tile with
more lights than ``capacity`` keeps its first ``capacity`` and the lighting pass loops over every light there
instead, so a list is never silently truncated (:func:`overflowing_tiles` counts such tiles).

Each translucent layer is culled again after its own g-buffer pass, over the tiles of its screen
rectangle, so its lists hold the lights that reach its depths, not the opaque layer's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from atlasgen.render.camera import camera_basis, pixel_rays, tangents
from atlasgen.render.layout import (
    COARSE_TILES,
    CULL,
    CULL_GROUP_TILES,
    ENTRY_TEXELS,
    LIGHT,
    LIGHT_MASK_WORDS,
    TILE_SIZE,
    UNIFORM_OFFSET_ALIGNMENT,
    declaration_wgsl,
)
from atlasgen.shaders.passes import assemble_shader
from atlasgen.shaders.structs import round_up

__all__ = [
    "DEFAULT_TILE_CAPACITY",
    "CULL_STRIDE",
    "CullingPass",
    "CullBindings",
    "TileLists",
    "tile_grid",
    "block_grid",
    "tile_rectangle",
    "pack_cull",
    "pack_light_spheres",
    "decode_tile_lists",
    "create_tile_texture",
    "fitting_capacity",
    "TILE_TEXTURE_BUDGET",
    "list_width",
    "tile_texture_size",
    "upload_light_spheres",
    "overflowing_tiles",
    "cull_tiles_reference",
    "lights_reaching",
]

#: Light indices a tile's list holds before the tile falls back to the full loop.
DEFAULT_TILE_CAPACITY = 255

#: Bytes between the culling dispatches' uniforms (dynamic offsets are multiples of 256).
CULL_STRIDE = round_up(UNIFORM_OFFSET_ALIGNMENT, CULL.size)


def tile_grid(width: int, height: int) -> tuple[int, int]:
    """``(tiles per row, rows of tiles)`` covering ``width`` x ``height`` pixels.

    >>> tile_grid(1280, 720)
    (80, 45)
    >>> tile_grid(17, 16)
    (2, 1)
    """
    return -(-width // TILE_SIZE), -(-height // TILE_SIZE)


def tile_rectangle(rectangle, width: int, height: int) -> tuple[int, int, int, int]:
    """``(first tile x, first tile y, tiles across, tiles down)`` covering the pixel rectangle ``(x, y, w, h)``;
    ``None`` is the whole screen.

    >>> tile_rectangle((20, 5, 20, 40), 1280, 720)
    (1, 0, 2, 3)
    >>> tile_rectangle(None, 100, 40)
    (0, 0, 7, 3)
    """
    if rectangle is None:
        return (0, 0, *tile_grid(width, height))
    x, y, w, h = rectangle
    x0, y0 = x // TILE_SIZE, y // TILE_SIZE
    x1, y1 = -(-(x + w) // TILE_SIZE), -(-(y + h) // TILE_SIZE)
    return x0, y0, x1 - x0, y1 - y0


def pack_cull(rectangles) -> bytes:
    """The ``Cull`` uniforms (:data:`~atlasgen.render.layout.CULL`) of each tile rectangle, ``CULL_STRIDE`` apart."""
    out = bytearray()
    for x0, y0, nx, ny in rectangles:
        data = CULL.pack(origin=[x0, y0, x0 + nx, y0 + ny])
        out += data + bytes(CULL_STRIDE - len(data))
    return bytes(out)


def pack_light_spheres(scene) -> bytes:
    """cull.wgsl's ``light_spheres``: per light, float32 (x, y, z, range) with the centre in camera space
    (x along right, y along up, z along forward, from the eye) and range 0 for an unbounded light.

    Done once per frame here in float64, rather than once per light in each of the screen's tiles.
    Never empty (WebGPU rejects zero-size buffers).
    """
    right, up, forward = camera_basis(scene.camera)
    eye = np.asarray(scene.camera.position, dtype=np.float64)
    out = np.zeros((max(len(scene.lights), 1), 4), dtype=np.float64)
    for i, light in enumerate(scene.lights):
        if light.bounded:
            c = np.asarray(light.position, dtype=np.float64) - eye
            out[i] = (c @ right, c @ up, c @ forward, light.range)
    return out.astype("<f4").tobytes()


@dataclass
class TileLists:
    """Light lists read back from the GPU: ``counts`` (rows, tiles per row), the true number of lights per tile,
    and ``lists[ty][tx]`` the indices it holds (at most ``capacity``)."""

    counts: np.ndarray
    lists: list
    capacity: int

    def overflowed(self) -> np.ndarray:
        """(rows, tiles per row) bool: tiles whose count exceeds the capacity (lit by the full loop)."""
        return self.counts > self.capacity


def upload_light_spheres(device, scene):
    """cull.wgsl's ``light_spheres``: :func:`pack_light_spheres` as an ``rgba32float`` texture, one texel a
    light (a texture, as the tile lists are: per-invocation storage reads are slow on lavapipe)."""
    import wgpu

    data = pack_light_spheres(scene)
    count = len(data) // 16
    texture = device.create_texture(
        label="light spheres",
        size=(count, 1, 1),
        format=wgpu.TextureFormat.rgba32float,
        usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST,
    )
    device.queue.write_texture(
        {"texture": texture, "mip_level": 0, "origin": (0, 0, 0)},
        data,
        {"offset": 0, "bytes_per_row": len(data), "rows_per_image": 1},
        (count, 1, 1),
    )
    return texture


def list_width(capacity: int) -> int:
    """Texels along a row of the tile-list texture: a tile's count, then :data:`~atlasgen.render.layout.ENTRY_TEXELS`
    per light it lists, rounded up to a power of two (lighting.wgsl finds a light's own texels with a mask and a
    shift), and at least one light's row.

    >>> list_width(255), list_width(4), list_width(0)
    (512, 16, 4)
    """
    return max(LIGHT.size // 16, 1 << (ENTRY_TEXELS * capacity).bit_length())


def tile_texture_size(width: int, height: int, capacity: int, lights: int, culled: bool = True) -> tuple[int, int, int]:
    """``(texels per row, rows, layers)`` of the tile-list texture of a ``width`` x ``height`` frame of ``lights``
    lights: a row per tile of a row of tiles and a layer per row of tiles (none where the frame is not culled), then
    one last layer holding every light's texels in light order, :func:`list_width` to a row.

    >>> tile_texture_size(1280, 720, 255, 1024)
    (512, 80, 46)
    >>> tile_texture_size(1280, 720, 255, 1024, culled=False)
    (4, 1024, 1)
    """
    texels = list_width(capacity if culled else 0)
    nx, ny = tile_grid(width, height) if culled else (0, 0)
    return texels, max(nx, -(-max(lights, 1) * (LIGHT.size // 16) // texels)), ny + 1


#: The most bytes a frame's tile-list texture may take. An 8192 x 8192 frame's lists of 255 lights asked 2.1 GB, which
#: lavapipe refused ("Not enough memory left": an internal error where the same frame without ranges rendered).
TILE_TEXTURE_BUDGET = 256 * 2**20


def fitting_capacity(width: int, height: int, capacity: int, lights: int, budget: int | None = None) -> int:
    """The most lights a tile list of a ``width`` x ``height`` frame of ``lights`` lights holds: ``capacity``, or
    less where its texture (:func:`tile_texture_size`, 16 bytes a texel) would pass ``budget`` bytes (default
    :data:`TILE_TEXTURE_BUDGET`), halving the list's row each time. A tile with more lights than that falls back to
    the full loop, as every overflowing one does.

    >>> fitting_capacity(1280, 720, 255, 1024)
    255
    >>> fitting_capacity(8192, 8192, 255, 1)
    15
    """
    budget = TILE_TEXTURE_BUDGET if budget is None else budget
    while capacity > 1 and 16 * math.prod(tile_texture_size(width, height, capacity, lights)) > budget:
        capacity = max(1, (list_width(capacity) // 2 - 1) // ENTRY_TEXELS)  # the next power-of-two row down
    return capacity


def create_tile_texture(device, width: int, height: int, capacity: int, lights: bytes, culled: bool = True):
    """The ``rgba32uint`` texture array of a frame's tile lists (:func:`tile_texture_size`), its last layer
    filled with ``lights`` (:func:`atlasgen.render.lighting.pack_lights`), which the full loop and a tile
    that overflowed read.

    Texel 0 of tile (tx, ty)'s list is row tx of layer ty, its x the count; entry k is the ``ENTRY_TEXELS``
    texels from 1 + k ``ENTRY_TEXELS``, copies of the light's own first texels: the lighting pass reads a
    listed light without first reading its index (a dependent fetch, a tenth of the pass on lavapipe)."""
    import wgpu

    texels, rows, layers = tile_texture_size(width, height, capacity, len(lights) // LIGHT.size, culled)
    texture = device.create_texture(
        label="tile lights",
        size=(texels, rows, layers),
        format=wgpu.TextureFormat.rgba32uint,
        usage=wgpu.TextureUsage.STORAGE_BINDING
        | wgpu.TextureUsage.TEXTURE_BINDING
        | wgpu.TextureUsage.COPY_SRC
        | wgpu.TextureUsage.COPY_DST,
    )
    data = lights + bytes(-len(lights) % (16 * texels))
    device.queue.write_texture(
        {"texture": texture, "mip_level": 0, "origin": (0, 0, layers - 1)},
        data,
        {"offset": 0, "bytes_per_row": 16 * texels, "rows_per_image": len(data) // (16 * texels)},
        (texels, len(data) // (16 * texels), 1),
    )
    return texture


def read_tile_texture(device, texture, width: int, height: int, capacity: int) -> TileLists:
    """The tile lists the texture of :func:`create_tile_texture` holds."""
    nx, ny = tile_grid(width, height)
    texels = list_width(capacity)
    row = round_up(256, 16 * texels)  # WebGPU copies rows at multiples of 256 bytes
    data = device.queue.read_texture(
        {"texture": texture, "mip_level": 0, "origin": (0, 0, 0)},
        {"offset": 0, "bytes_per_row": row, "rows_per_image": nx},
        (texels, nx, ny),
    )
    words = np.frombuffer(data, dtype=np.uint32).reshape(ny, nx, row // 4)[..., : 4 * texels]
    return decode_tile_lists(np.ascontiguousarray(words).tobytes(), width, height, capacity)


def decode_tile_lists(data: bytes, width: int, height: int, capacity: int) -> TileLists:
    """The tile lists of a ``width`` x ``height`` frame from their texels (four words each), :func:`list_width`
    to a tile, tile by tile in rows of tiles: the count, then each entry's copy of its light's texels, which
    name it by its ``index``."""
    nx, ny = tile_grid(width, height)
    texels = list_width(capacity)
    words = np.frombuffer(data, dtype=np.uint32)[: nx * ny * texels * 4].reshape(ny, nx, texels, 4)
    counts = words[..., 0, 0].astype(np.int64)
    texel, component = LIGHT.texel_of("index")
    names = words[:, :, 1 + texel : 1 + ENTRY_TEXELS * capacity : ENTRY_TEXELS, component]
    lists = [[names[ty, tx, : min(int(counts[ty, tx]), capacity)].tolist() for tx in range(nx)] for ty in range(ny)]
    return TileLists(counts, lists, capacity)


def overflowing_tiles(lists: TileLists) -> int:
    """How many tiles hold more lights than their list: each is lit by the full loop."""
    return int(lists.overflowed().sum())


def cull_tiles_reference(scene, depth: np.ndarray, slack: float = 1.0, tiles=None) -> dict:
    """``{(tx, ty): set of light indices}``: the lights whose sphere meets each tile's frustum and depth range.

    The CPU statement of cull.wgsl's test, in float64: for the tile's covered pixels (finite
    ``depth``, view depth along the camera's forward axis) with depth range [z_min, z_max], a
    light of centre c (camera space x, y, z) and radius r = ``slack`` * range is kept unless
    c lies more than r outside one of the four planes through the eye and the tile's pixel
    edges (distance (x - a z) / sqrt(1 + a^2) for an edge of slope a), or farther than r from
    the box [min a z, max a z] x [min b z, max b z] x [z_min, z_max] over the tile's x slopes a,
    y slopes b and z in {z_min, z_max}, which holds every covered point of the tile; nor is it kept
    when c lies more than r outside one of the four planes of the tile's block of ``COARSE_TILES`` x
    ``COARSE_TILES`` tiles (the coarse step). Unbounded lights
    are kept in every covered tile; a tile no object covers gets none. ``tiles`` (a ``(x0, y0, nx, ny)``
    tile rectangle) limits the tiles.
    """
    width, height = scene.width, scene.height
    right, up, forward = camera_basis(scene.camera)
    tan_x, tan_y = tangents(scene.camera, width, height)
    eye = np.asarray(scene.camera.position, dtype=np.float64)
    x0, y0, nx, ny = tiles if tiles is not None else tile_rectangle(None, width, height)
    bounded = [i for i, light in enumerate(scene.lights) if light.bounded]
    unbounded = {i for i, light in enumerate(scene.lights) if not light.bounded}
    centres = np.array([scene.lights[i].position for i in bounded], dtype=np.float64).reshape(-1, 3) - eye
    cx, cy, cz = centres @ right, centres @ up, centres @ forward
    radius = np.array([scene.lights[i].range for i in bounded], dtype=np.float64) * slack

    def outside(s, z, a):
        return (s - a * z) / math.sqrt(1.0 + a * a)

    def edge_slopes(px0, py0, px1, py1):
        """x / z of the rectangle's left and right edges, y / z of its top and bottom ones."""
        return ((px0 / width * 2 - 1) * tan_x, (px1 / width * 2 - 1) * tan_x,
                -(py0 / height * 2 - 1) * tan_y, -(py1 / height * 2 - 1) * tan_y)  # fmt: skip

    def within_planes(left, right_, top, bottom):
        return (
            (outside(cx, cz, left) >= -radius)
            & (-outside(cx, cz, right_) >= -radius)
            & (outside(cy, cz, bottom) >= -radius)
            & (-outside(cy, cz, top) >= -radius)
        )

    block = COARSE_TILES * TILE_SIZE

    out = {}
    for ty in range(y0, y0 + ny):
        for tx in range(x0, x0 + nx):
            px0, py0 = tx * TILE_SIZE, ty * TILE_SIZE
            px1, py1 = min(px0 + TILE_SIZE, width), min(py0 + TILE_SIZE, height)
            d = depth[py0:py1, px0:px1]
            d = d[np.isfinite(d)]
            if d.size == 0:
                out[(tx, ty)] = set()
                continue
            left, right_, top, bottom = slopes = edge_slopes(px0, py0, px1, py1)
            z = np.array([d.min(), d.max()])
            xs, ys = np.outer([left, right_], z), np.outer([bottom, top], z)
            gap = [c - np.clip(c, lo, hi) for c, lo, hi in ((cx, xs.min(), xs.max()), (cy, ys.min(), ys.max()), (cz, *z))]
            bx0, by0 = (px0 // block) * block, (py0 // block) * block
            keep = (
                (gap[0] ** 2 + gap[1] ** 2 + gap[2] ** 2 <= radius**2)
                & within_planes(*slopes)
                & within_planes(*edge_slopes(bx0, by0, min(bx0 + block, width), min(by0 + block, height)))
            )
            out[(tx, ty)] = unbounded | {bounded[k] for k in np.flatnonzero(keep)}
    return out


def lights_reaching(scene, depth: np.ndarray, candidates=None) -> np.ndarray:
    """``(h, w)`` int: how many lights reach each covered pixel's surface point (0 where nothing is drawn).

    A bounded light reaches a point closer than its range (and, for a spot light, inside its
    outer cone); an unbounded one reaches every point. ``candidates``, a :class:`TileLists`
    or the reference's dict, restricts each tile to the lights listed for it (a tile that
    overflowed tests every light), which makes this cheap enough for 1024 lights at 720p.
    """
    width, height = scene.width, scene.height
    rays = pixel_rays(scene.camera, width, height)
    world = np.asarray(scene.camera.position, dtype=np.float64) + rays * np.where(np.isfinite(depth), depth, 0.0)[..., None]
    covered = np.isfinite(depth)
    out = np.zeros((height, width), dtype=np.int64)
    nx, ny = tile_grid(width, height)
    everything = list(range(len(scene.lights)))
    for ty in range(ny):
        for tx in range(nx):
            if candidates is None:
                chosen = everything
            elif isinstance(candidates, TileLists):
                chosen = everything if candidates.overflowed()[ty, tx] else candidates.lists[ty][tx]
            else:
                chosen = sorted(candidates.get((tx, ty), ()))
            sl = (slice(ty * TILE_SIZE, (ty + 1) * TILE_SIZE), slice(tx * TILE_SIZE, (tx + 1) * TILE_SIZE))
            points, mask = world[sl], covered[sl]
            count = np.zeros(mask.shape, dtype=np.int64)
            for i in chosen:
                light = scene.lights[i]
                if not light.bounded:
                    count += 1
                    continue
                d = points - np.asarray(light.position, dtype=np.float64)
                dist2 = (d * d).sum(-1)
                reach = dist2 < light.range**2
                if light.type == "spot":
                    cos_theta = (d @ np.asarray(light.direction)) / np.sqrt(np.maximum(dist2, 1e-300))
                    reach &= cos_theta > math.cos(math.radians(light.outer_angle))
                count += reach
            out[sl] = np.where(mask, count, 0)
    return out


@dataclass
class CullBindings:
    """What one frame's culling binds: the coarse step's and the tiles' bind groups, and the blocks' masks."""

    coarse: object
    fine: object
    masks: object  # the r32uint texture array of the blocks' light masks (kept alive with the groups)
    blocks: tuple[int, int]  # (blocks per row, rows of blocks)


def block_grid(width: int, height: int) -> tuple[int, int]:
    """``(blocks per row, rows of blocks)`` of the coarse step over ``width`` x ``height`` pixels.

    >>> block_grid(1280, 720)
    (20, 12)
    """
    nx, ny = tile_grid(width, height)
    return -(-nx // COARSE_TILES), -(-ny // COARSE_TILES)


class CullingPass:
    """The compute pipelines of cull.wgsl (the coarse step and the tiles) and the bindings they read."""

    def __init__(self, device):
        import wgpu

        self.device = device
        module = device.create_shader_module(
            label="cull", code=assemble_shader("common.wgsl", "cull.wgsl", declare=declaration_wgsl)
        )
        compute = wgpu.ShaderStage.COMPUTE
        frame = {"binding": 0, "visibility": compute, "buffer": {"type": "uniform"}}
        spheres = {"binding": 1, "visibility": compute, "texture": {"sample_type": "unfilterable-float"}}
        self.layout = device.create_bind_group_layout(
            label="cull",
            entries=[
                frame,
                spheres,
                {"binding": 2, "visibility": compute, "texture": {"sample_type": "uint"}},
                {
                    "binding": 3,
                    "visibility": compute,
                    "storage_texture": {"access": "write-only", "format": "rgba32uint", "view_dimension": "2d-array"},
                },
                {
                    "binding": 4,
                    "visibility": compute,
                    "buffer": {"type": "uniform", "has_dynamic_offset": True, "min_binding_size": CULL.size},
                },
                {"binding": 5, "visibility": compute, "texture": {"sample_type": "uint", "view_dimension": "2d-array"}},
                {"binding": 7, "visibility": compute, "texture": {"sample_type": "uint"}},
            ],
        )
        self.coarse_layout = device.create_bind_group_layout(
            label="cull coarse",
            entries=[
                frame,
                spheres,
                {
                    "binding": 6,
                    "visibility": compute,
                    "storage_texture": {"access": "write-only", "format": "r32uint", "view_dimension": "2d-array"},
                },
            ],
        )
        self.pipeline = device.create_compute_pipeline(
            label="cull",
            layout=device.create_pipeline_layout(bind_group_layouts=[self.layout]),
            compute={"module": module, "entry_point": "cs_cull"},
        )
        self.coarse_pipeline = device.create_compute_pipeline(
            label="cull coarse",
            layout=device.create_pipeline_layout(bind_group_layouts=[self.coarse_layout]),
            compute={"module": module, "entry_point": "cs_coarse"},
        )

    def bind_group(self, frame_buffer, sphere_texture, light_texture, gbuffer, tile_texture, cull_buffer) -> CullBindings:
        """``sphere_texture`` (:func:`upload_light_spheres`) holds the lights' spheres and ``light_texture``
        (:func:`atlasgen.render.lighting.upload_lights`) their rows, which the lists copy; ``tile_texture``
        (:func:`create_tile_texture`) receives the lists."""
        import wgpu

        blocks = block_grid(gbuffer.width, gbuffer.height)
        masks = self.device.create_texture(
            label="cull block masks",
            size=(LIGHT_MASK_WORDS, *blocks),
            format=wgpu.TextureFormat.r32uint,
            usage=wgpu.TextureUsage.STORAGE_BINDING | wgpu.TextureUsage.TEXTURE_BINDING,
        )
        frame = {"binding": 0, "resource": {"buffer": frame_buffer}}
        spheres = {"binding": 1, "resource": sphere_texture.create_view()}
        fine = self.device.create_bind_group(
            layout=self.layout,
            entries=[
                frame,
                spheres,
                {"binding": 2, "resource": gbuffer.normal_depth.create_view()},
                {"binding": 3, "resource": tile_texture.create_view(dimension="2d-array")},
                {"binding": 4, "resource": {"buffer": cull_buffer, "offset": 0, "size": CULL.size}},
                {"binding": 5, "resource": masks.create_view(dimension="2d-array")},
                {"binding": 7, "resource": light_texture.create_view()},
            ],
        )
        coarse = self.device.create_bind_group(
            layout=self.coarse_layout,
            entries=[frame, spheres, {"binding": 6, "resource": masks.create_view(dimension="2d-array")}],
        )
        return CullBindings(coarse, fine, masks, blocks)

    def encode(self, encoder, bindings: CullBindings, step: int, tiles, timestamps=None) -> None:
        """Record the dispatch culling the tile rectangle ``tiles`` = (x0, y0, nx, ny) with the
        ``step``-th ``Cull`` uniform (0: the opaque layer, after the coarse step over the whole
        screen; k: the k-th translucent object, which reuses the blocks' masks)."""
        pass_ = encoder.begin_compute_pass(timestamp_writes=timestamps)
        if step == 0:
            pass_.set_pipeline(self.coarse_pipeline)
            pass_.set_bind_group(0, bindings.coarse)
            pass_.dispatch_workgroups(*bindings.blocks, 1)
        pass_.set_pipeline(self.pipeline)
        pass_.set_bind_group(0, bindings.fine, [step * CULL_STRIDE])
        pass_.dispatch_workgroups(-(-int(tiles[2]) // CULL_GROUP_TILES), -(-int(tiles[3]) // CULL_GROUP_TILES), 1)
        pass_.end()
