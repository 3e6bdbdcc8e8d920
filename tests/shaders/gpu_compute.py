"""One compute dispatch for the shader tests: a storage or uniform buffer in, u32 words out."""

from __future__ import annotations

import numpy as np


def run_compute(ctx, code: str, src: bytes, uniform: bool, out_words: int) -> np.ndarray:
    """Run ``main`` of ``code`` once with ``src`` at binding 0 and return binding 1's u32 words."""
    import wgpu

    device = ctx.device
    usage = wgpu.BufferUsage.UNIFORM if uniform else wgpu.BufferUsage.STORAGE
    src_buffer = device.create_buffer_with_data(data=src, usage=usage)
    dst = device.create_buffer(size=4 * out_words, usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC)
    pipeline = device.create_compute_pipeline(
        layout="auto", compute={"module": device.create_shader_module(code=code), "entry_point": "main"}
    )
    group = device.create_bind_group(
        layout=pipeline.get_bind_group_layout(0),
        entries=[{"binding": 0, "resource": {"buffer": src_buffer}}, {"binding": 1, "resource": {"buffer": dst}}],
    )
    encoder = device.create_command_encoder()
    compute = encoder.begin_compute_pass()
    compute.set_pipeline(pipeline)
    compute.set_bind_group(0, group)
    compute.dispatch_workgroups(1)
    compute.end()
    device.queue.submit([encoder.finish()])
    return np.frombuffer(device.queue.read_buffer(dst), dtype="<u4")
