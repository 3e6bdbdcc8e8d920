"""The baked atlas as the renderer uses it: mip levels, manifest and generated WGSL include.

The atlas is uploaded level by level exactly as baked (a 2D texture array,
``rgba8unorm-srgb`` for DXGI 29 or ``rgba8unorm`` for DXGI 28): mips are never
regenerated on the GPU, so what the bake measured is what the renderer samples.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from atlasgen.errors import FieldError, InputError
from atlasgen.io.atlas import MAX_INCLUDE_BYTES, check_include, read_atlas
from atlasgen.io.manifest import Manifest
from atlasgen.io.text import read_input_text
from atlasgen.models import check_manifest_models

__all__ = ["RenderAtlas", "read_render_atlas", "upload_atlas"]


@dataclass
class RenderAtlas:
    """``levels[k]`` is ``(layers, h_k, w_k, 4)`` uint8; ``include`` the generated WGSL text."""

    levels: list
    srgb: bool
    manifest: Manifest
    include: str
    name: str = "atlas"

    @property
    def material_names(self) -> list[str]:
        return sorted(self.manifest.names)

    def __post_init__(self):
        if not self.levels:
            raise InputError(f"{self.name}: atlas has no mip levels")
        first = self.levels[0]
        if first.ndim != 4 or first.shape[3] != 4 or first.dtype != np.uint8:
            raise InputError(f"{self.name}: expected levels of shape (layers, h, w, 4) uint8, got {first.shape} {first.dtype}")


def read_render_atlas(dds_path, atlas=None) -> RenderAtlas:
    """Read ``X.dds`` with its manifest ``X.json`` and include ``X.wgsl`` (all written by the bake);
    ``atlas``: the pair already read (:func:`~atlasgen.io.atlas.read_atlas` of ``dds_path``), not read again.

    Raises :class:`InputError` when one of the three is missing, when they are not one
    bake's files (:func:`atlasgen.io.atlas.read_atlas` checks the texture against the
    manifest, :func:`~atlasgen.io.atlas.check_include` the include), or when the atlas is a
    volume: the renderer samples a 2D texture array, whose layer is never filtered.
    """
    dds_path = Path(dds_path)
    atlas = read_atlas(dds_path) if atlas is None else atlas
    shown = dds_path.as_posix()
    if atlas.manifest is None:
        raise InputError(
            f"{shown}: no manifest {dds_path.with_suffix('.json').as_posix()} beside the atlas; re-run atlasgen bake"
        )
    if atlas.image.layout != "array":
        raise InputError(f"{shown}: the renderer needs a 2D-array atlas (bake with --layout array), got a {atlas.image.layout}")
    include_path = dds_path.with_suffix(".wgsl")
    include = read_input_text(include_path, "no shader include beside the atlas; re-run atlasgen bake",
                              "a WGSL include (UTF-8 text)", FieldError, MAX_INCLUDE_BYTES)  # fmt: skip
    check_include(atlas, include_path, include)
    check_manifest_models(atlas.manifest, dds_path.with_suffix(".json").as_posix())
    return RenderAtlas(list(atlas.image.levels), atlas.srgb, atlas.manifest, include, shown)


def upload_atlas(ctx, atlas: RenderAtlas):
    """Create the texture array and write every baked level into it; return the texture."""
    import wgpu

    layers, height, width, _ = atlas.levels[0].shape
    texture = ctx.device.create_texture(
        label="atlas",
        size=(width, height, layers),
        format=wgpu.TextureFormat.rgba8unorm_srgb if atlas.srgb else wgpu.TextureFormat.rgba8unorm,
        usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST,
        dimension="2d",
        mip_level_count=len(atlas.levels),
    )
    for k, level in enumerate(atlas.levels):
        n, h, w, _ = level.shape
        ctx.device.queue.write_texture(
            {"texture": texture, "mip_level": k, "origin": (0, 0, 0)},
            np.ascontiguousarray(level),
            {"offset": 0, "bytes_per_row": 4 * w, "rows_per_image": h},
            (w, h, n),
        )
    return texture
