"""Toon outlines: screen-space edges from g-buffer discontinuities (outline.wgsl).

Saito & Takahashi (1990), "Comprehensible Rendering of 3-D Shapes", the paper that
introduced the g-buffer, draw contours where the depth image is discontinuous and
creases where normals are. This pass does both on the final g-buffer, and writes the
outline colour only where the pixel or a 4-neighbour carries a material whose
manifest flags ask for outlines (``flags.outline``, ATLAS_FLAGS bit 0 in the include).
"""

from __future__ import annotations

import math

from atlasgen.render.layout import declaration_wgsl
from atlasgen.shaders.passes import assemble_shader

__all__ = ["OutlinePass", "outline_parameters"]


def outline_parameters(settings) -> tuple[float, float]:
    """(relative inverse-depth threshold, cosine of the normal-angle threshold)."""
    return settings.outline_depth, math.cos(math.radians(settings.outline_normal_degrees))


class OutlinePass:
    """Full-screen pass that overwrites outline pixels of the lit frame."""

    def __init__(self, device, include: str):
        import wgpu

        self.device = device
        module = device.create_shader_module(
            label="outline", code=assemble_shader("common.wgsl", "outline.wgsl", declare=declaration_wgsl, include=include)
        )
        frag = wgpu.ShaderStage.FRAGMENT
        self.layout = device.create_bind_group_layout(
            label="outline",
            entries=[
                {"binding": 0, "visibility": frag, "buffer": {"type": "uniform"}},
                {"binding": 1, "visibility": frag, "texture": {"sample_type": "uint"}},
                {"binding": 2, "visibility": frag, "texture": {"sample_type": "uint"}},
            ],
        )
        self.pipeline = device.create_render_pipeline(
            label="outline",
            layout=device.create_pipeline_layout(bind_group_layouts=[self.layout]),
            vertex={"module": module, "entry_point": "vs_fullscreen", "buffers": []},
            primitive={"topology": "triangle-list", "cull_mode": "none"},
            fragment={"module": module, "entry_point": "fs_main", "targets": [{"format": wgpu.TextureFormat.rgba16float}]},
        )

    def bind_group(self, frame_buffer, gbuffer):
        return self.device.create_bind_group(
            layout=self.layout,
            entries=[
                {"binding": 0, "resource": {"buffer": frame_buffer}},
                {"binding": 1, "resource": gbuffer.normal_depth.create_view()},
                {"binding": 2, "resource": gbuffer.material.create_view()},
            ],
        )

    def encode(self, encoder, target, bind_group, rectangles=None, timestamps=None):
        """Draw the pass over ``rectangles`` (``(x, y, w, h)`` scissors), or the whole target for ``None``.

        An outline pixel is a flagged object's pixel or a 4-neighbour of one, so the screen
        rectangles of the flagged objects (:func:`~atlasgen.render.translucency.screen_rectangle`,
        padded by a pixel) hold every pixel the pass can write: drawing only there gives the
        full-screen image at the cost of what is outlined. Overlaps are drawn twice, to the same colour.
        """
        pass_ = encoder.begin_render_pass(
            color_attachments=[{"view": target.create_view(), "load_op": "load", "store_op": "store"}],
            timestamp_writes=timestamps,
        )
        pass_.set_pipeline(self.pipeline)
        pass_.set_bind_group(0, bind_group)
        for rectangle in [None] if rectangles is None else rectangles:
            if rectangle is not None:
                pass_.set_scissor_rect(*rectangle)
            pass_.draw(3)
        pass_.end()
