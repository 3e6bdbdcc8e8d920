"""The include as the renderer compiles it: the tables a bake changes read from storage buffers.

The bake's include (:func:`atlasgen.shaders.include.render_include`, what an engine loads) holds each
slice's scale and bias, and a separable material's factor table, as constants, so that the shader
needs nothing else bound. Compiled into the renderer's lighting shader, that makes every new scale a
new shader, and on lavapipe a compile (1.6 s) costs more than the rest of a preview's update. The
renderer therefore compiles the same functions with those two tables in buffers
(:func:`atlasgen.shaders.include.render_buffered_include`): its text changes only with what the
materials' code depends on (their names, slots, flags and types), and a re-bake that keeps those
rewrites two buffers. The values come from the manifest, as the bake's own include does.

The scale and bias table is a uniform buffer of one row per slice, the factor table (its length
changes with the bake) a read-only storage buffer: lavapipe gathers a storage read lane by lane,
and the lighting pass reads a pixel's scale and bias for every pixel it shades.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from atlasgen.io.manifest import Manifest
from atlasgen.models import get_model
from atlasgen.shaders.include import manifest_scale_bias, render_buffered_include

__all__ = ["STORAGE", "BUFFER_TYPES", "RendererInclude", "manifest_scale_bias", "upload_tables"]

#: The buffered tables and their (group, binding, address space) in the lighting pass (atlasgen/render/lighting.py).
STORAGE = {"ATLAS_SCALE_BIAS": (0, 20, "uniform"), "SEPARABLE_TABLE": (0, 21, "storage")}
#: The bind group layout's buffer type of each address space.
BUFFER_TYPES = {"uniform": "uniform", "storage": "read-only-storage"}


@dataclass(frozen=True)
class RendererInclude:
    """The renderer's WGSL include of an atlas and the values of its storage tables (name -> ``(n, 4)``)."""

    text: str
    tables: dict

    @classmethod
    def of(cls, manifest: Manifest) -> RendererInclude:
        scales, biases = manifest_scale_bias(manifest)
        text, tables = render_buffered_include(manifest, scales, biases, STORAGE, models=get_model)
        return cls(text, tables)


def upload_tables(device, include: RendererInclude) -> dict:
    """A buffer per :data:`STORAGE` table, name -> buffer: its rows as float32, or one row of zeros for a
    storage table this include lacks (the pass binds every one; a shader without it never reads it).
    Every include has the uniform one, the scale and bias of each slice."""
    import wgpu

    usages = {"uniform": wgpu.BufferUsage.UNIFORM, "storage": wgpu.BufferUsage.STORAGE}
    buffers = {}
    for name, (_, _, space) in STORAGE.items():
        rows = include.tables.get(name)
        data = np.zeros((1, 4), np.float32) if rows is None else np.asarray(rows, dtype=np.float32)
        buffers[name] = device.create_buffer_with_data(data=data.tobytes(), usage=usages[space])
    return buffers
