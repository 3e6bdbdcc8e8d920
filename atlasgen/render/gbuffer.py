"""The g-buffer: its render targets and the pass that draws objects into it.

Targets (all at the output resolution):

==================  ====================  ===========================================
target              format                contents
==================  ====================  ===========================================
``albedo_gloss``    ``rgba16float``       linear albedo (rgb), gloss (a)
``normal_depth``    ``rg32uint``          world unit normal, octahedral, two snorm16
                                          (x); view depth's float bits (y)
``material``        ``r16uint``           atlas slice; cleared to 0xFFFF = no object
``depth_stencil``   ``depth24plus-        z-buffer; stencil marks the pixels of the
                    stencil8``            translucent object being composited
==================  ====================  ===========================================

View depth is the distance along the camera's forward axis, so the lighting pass
rebuilds the surface point as ``eye + ray * depth`` without inverting a projection.
The normal's octahedral form (Cigolle et al. 2014) loses at most about 1e-4 rad; the
shaders' ``encode_normal_depth`` / ``decode_normal`` (common.wgsl) and
:func:`encode_normals` / :func:`decode_normals` here are its two statements.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from atlasgen.render.camera import FAR_PLANE_DEPTH
from atlasgen.render.layout import NO_MATERIAL, OBJECT, OBJECT_UNIFORM_STRIDE, declaration_wgsl
from atlasgen.render.meshes import vertex_buffer_layout
from atlasgen.shaders.passes import assemble_shader

__all__ = ["GBuffer", "GBufferPass", "pack_object", "encode_normals", "decode_normals", "FAR_DEPTH"]

#: Depth cleared into ``normal_depth`` where nothing is drawn (its float32 bits: the target is ``rg32uint``).
FAR_DEPTH = 3.0e38


def _sign_not_zero(v: np.ndarray) -> np.ndarray:
    return np.where(v >= 0.0, 1.0, -1.0)


def encode_normals(n) -> np.ndarray:
    """The ``rg32uint`` x word of unit normals ``n`` (..., 3): the octahedral map (Cigolle et al. 2014),

        p = (n_x, n_y) / (|n_x| + |n_y| + |n_z|),  folded to (1 - |p_y|, 1 - |p_x|) sign(p) where n_z < 0,

    as two snorm16 (WGSL ``pack2x16snorm``: round(clamp(p, -1, 1) 32767), x in the low half).

    >>> hex(int(encode_normals([0.0, 0.0, 1.0])))
    '0x0'
    >>> hex(int(encode_normals([1.0, 0.0, 0.0])))
    '0x7fff'
    """
    n = np.asarray(n, dtype=np.float64)
    p = n[..., :2] / np.abs(n).sum(-1, keepdims=True)
    p = np.where(n[..., 2:3] < 0.0, (1.0 - np.abs(p[..., ::-1])) * _sign_not_zero(p), p)
    q = np.round(np.clip(p, -1.0, 1.0) * 32767.0).astype(np.int64) & 0xFFFF
    return (q[..., 0] | (q[..., 1] << 16)).astype(np.uint32)


def decode_normals(words) -> np.ndarray:
    """Unit normals (..., 3) from :func:`encode_normals`' words: WGSL ``unpack2x16snorm`` (max(q / 32767, -1)),
    the octahedron unfolded and the vector normalised, as ``decode_normal`` in common.wgsl does.

    >>> decode_normals(encode_normals([0.0, -0.6, -0.8])).round(4).tolist()
    [0.0, -0.6, -0.8]
    """
    w = np.asarray(words, dtype=np.uint32)
    q = np.stack([w & 0xFFFF, w >> 16], -1).astype(np.uint16).view(np.int16).astype(np.float64)
    p = np.maximum(q / 32767.0, -1.0)
    v = np.concatenate([p, 1.0 - np.abs(p).sum(-1, keepdims=True)], -1)
    folded = (1.0 - np.abs(v[..., 1::-1])) * _sign_not_zero(v[..., :2])
    v = np.where(v[..., 2:3] < 0.0, np.concatenate([folded, v[..., 2:3]], -1), v)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclass
class GBuffer:
    """The textures of one resolution; :meth:`create` makes them."""

    width: int
    height: int
    albedo_gloss: object
    normal_depth: object
    material: object
    depth_stencil: object

    @classmethod
    def create(cls, device, width: int, height: int) -> GBuffer:
        import wgpu

        usage = wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_SRC

        def make(label, fmt, use=usage):
            return device.create_texture(label=label, size=(width, height, 1), format=fmt, usage=use)

        return cls(
            width,
            height,
            make("albedo_gloss", wgpu.TextureFormat.rgba16float),
            make("normal_depth", wgpu.TextureFormat.rg32uint),
            make("material", wgpu.TextureFormat.r16uint),
            make(
                "depth_stencil",
                wgpu.TextureFormat.depth24plus_stencil8,
                wgpu.TextureUsage.RENDER_ATTACHMENT | wgpu.TextureUsage.COPY_SRC,
            ),  # fmt: skip
        )

    def colour_attachments(self, clear: bool) -> list[dict]:
        op = "clear" if clear else "load"
        return [
            {"view": self.albedo_gloss.create_view(), "load_op": op, "store_op": "store", "clear_value": (0, 0, 0, 0)},
            {
                "view": self.normal_depth.create_view(),
                "load_op": op,
                "store_op": "store",
                "clear_value": (0, int(np.float32(FAR_DEPTH).view(np.uint32)), 0, 0),
            },  # fmt: skip
            {
                "view": self.material.create_view(),
                "load_op": op,
                "store_op": "store",
                "clear_value": (NO_MATERIAL, 0, 0, 0),
            },  # fmt: skip
        ]


def pack_object(model: np.ndarray, albedo, gloss: float, material_id: int) -> bytes:
    """The ``Object`` uniform (:data:`~atlasgen.render.layout.OBJECT`), padded to its dynamic-offset stride.

    The normal matrix is the inverse transpose of the model matrix's linear part, which
    keeps normals perpendicular to surfaces under non-uniform scale, divided by its largest entry: the g-buffer
    normalises the normal, so only its direction counts, and at an object's scale of 1e18 (or 1e-20) the normals
    came out 1e-18 long, which the rasteriser's perspective interpolation (times 1/w) took below float32's
    normal range: the spheres were shaded with flat facets, and a plane from behind.
    """
    inverse_t = np.linalg.inv(model[:3, :3]).T
    normal = np.eye(4)
    normal[:3, :3] = inverse_t / np.max(np.abs(inverse_t))
    data = OBJECT.pack(model=model, normal_matrix=normal, albedo_gloss=[*albedo, gloss], material=[material_id, 0, 0, 0])
    return data + bytes(OBJECT_UNIFORM_STRIDE - len(data))


class GBufferPass:
    """Pipeline drawing meshes into the g-buffer with z-test, z-write and stencil marking.

    The stencil reference replaces the stencil value wherever a fragment passes the
    depth test: 0 for opaque objects, 1 for the translucent object being composited.
    """

    def __init__(self, device, frame_layout):
        import wgpu

        self.device = device
        module = device.create_shader_module(
            label="gbuffer", code=assemble_shader("common.wgsl", "gbuffer.wgsl", declare=declaration_wgsl)
        )
        self.object_layout = device.create_bind_group_layout(
            label="object",
            entries=[{
                "binding": 0,
                "visibility": wgpu.ShaderStage.VERTEX | wgpu.ShaderStage.FRAGMENT,
                "buffer": {"type": "uniform", "has_dynamic_offset": True, "min_binding_size": OBJECT.size},
            }],
        )  # fmt: skip
        layout = device.create_pipeline_layout(bind_group_layouts=[frame_layout, self.object_layout])
        stencil = {"compare": "always", "fail_op": "keep", "depth_fail_op": "keep", "pass_op": "replace"}
        # Two pipelines: two-sided for open meshes (a plane seen from below is shaded with the flipped
        # normal), back faces culled for closed ones, whose back faces the depth test would reject
        # anyway: half their triangles never reach set-up and binning, which on lavapipe cost a
        # finely tessellated sphere more than its pixels.
        self.pipelines = {closed: self._pipeline(device, module, layout, stencil, "back" if closed else "none")
                          for closed in (False, True)}  # fmt: skip

    @staticmethod
    def _pipeline(device, module, layout, stencil, cull_mode: str):
        import wgpu

        return device.create_render_pipeline(
            label="gbuffer",
            layout=layout,
            vertex={
                "module": module,
                "entry_point": "vs_main",
                "buffers": [vertex_buffer_layout()],
            },  # fmt: skip
            primitive={"topology": "triangle-list", "front_face": "ccw", "cull_mode": cull_mode},
            depth_stencil={
                "format": wgpu.TextureFormat.depth24plus_stencil8,
                "depth_write_enabled": True,
                "depth_compare": "less",
                "stencil_front": stencil,
                "stencil_back": stencil,
                "stencil_read_mask": 0xFF,
                "stencil_write_mask": 0xFF,
            },
            fragment={
                "module": module,
                "entry_point": "fs_main",
                "targets": [
                    {"format": wgpu.TextureFormat.rgba16float},
                    {"format": wgpu.TextureFormat.rg32uint},
                    {"format": wgpu.TextureFormat.r16uint},
                ],
            },
        )

    def encode(self, encoder, gbuffer: GBuffer, frame_group, object_group, draws, clear: bool, stencil_reference: int,
               timestamps=None):  # fmt: skip
        """Record one render pass drawing ``draws`` = [(gpu_mesh, object_slot), ...].

        ``clear`` starts a frame (all targets, depth :data:`FAR_PLANE_DEPTH`, stencil 0); otherwise colour and
        depth are kept and only the stencil is cleared, so it marks just this pass's pixels.
        ``timestamps``: the pass's ``timestamp_writes``, if timed.
        """
        pass_ = encoder.begin_render_pass(
            color_attachments=gbuffer.colour_attachments(clear),
            depth_stencil_attachment={
                "view": gbuffer.depth_stencil.create_view(),
                "depth_load_op": "clear" if clear else "load",
                "depth_store_op": "store",
                # The far plane's own depth: a fragment at or beyond it fails "less" and is not drawn. Cleared to 1,
                # everything up to depth 1 was drawn, 5% beyond far at far / near = 1e5 and the whole scene beyond
                # it from 2e6 on (1 - near / far rounds above 1 - DEPTH_HEADROOM there).
                "depth_clear_value": FAR_PLANE_DEPTH,
                "stencil_load_op": "clear",
                "stencil_store_op": "store",
                "stencil_clear_value": 0,
            },
            timestamp_writes=timestamps,
        )
        # Both pipelines share one layout: the frame's group and the stencil reference outlive a switch.
        pass_.set_bind_group(0, frame_group)
        pass_.set_stencil_reference(stencil_reference)
        current = None
        for mesh, slot in draws:
            if mesh.closed is not current:
                current = mesh.closed
                pass_.set_pipeline(self.pipelines[current])
            pass_.set_bind_group(1, object_group, [slot * OBJECT_UNIFORM_STRIDE])
            pass_.set_vertex_buffer(0, mesh.vertices)
            pass_.set_index_buffer(mesh.indices, "uint32")
            pass_.draw_indexed(mesh.index_count)
        pass_.end()
