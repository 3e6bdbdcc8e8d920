"""Reading a baked atlas back: the DDS or KTX2, its manifest, and linear slices as a renderer sees them."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from atlasgen.io.dds import DDSImage, describe_dds, read_dds
from atlasgen.io.ktx2 import KTX2Image, describe_ktx2, read_ktx2
from atlasgen.io.manifest import Manifest, MaterialEntry, read_manifest
from atlasgen.errors import InputError
from atlasgen.optics.quantize import dequantize_rgba

__all__ = ["Atlas", "read_atlas", "summarize_atlas", "describe_atlas"]


@dataclass
class Atlas:
    """A baked atlas: its DDS or KTX2 image and its manifest (``None`` if there is none beside it)."""

    path: Path
    image: DDSImage | KTX2Image
    manifest: Manifest | None

    @property
    def srgb(self) -> bool:
        return self.image.dxgi_format == 29

    def material(self, name: str) -> MaterialEntry:
        """The manifest entry of ``name``; InputError listing the known names otherwise."""
        entry = self.manifest.entry_named(name) if self.manifest is not None else None
        if entry is None:
            known = ", ".join(sorted(self.manifest.names if self.manifest is not None else [])) or "none"
            raise InputError(f"{self.path.as_posix()}: no material {name!r}; known: {known}")
        return entry

    def decode_slice(self, slice_index: int, level: int = 0, apply_scale: bool = True) -> np.ndarray:
        """Linear RGBA ``(h, w, 4)`` of one array slice: what the include's ``atlas_sample`` returns."""
        if self.image.layout != "array":
            raise InputError(f"{self.path.as_posix()}: decode_slice needs a 2D-array atlas")
        rgba = dequantize_rgba(self.image.levels[level][slice_index], self.srgb)
        entry = self.manifest.by_slice(slice_index) if apply_scale and self.manifest is not None else None
        if entry is not None:
            k = slice_index - entry.first_slice
            scale, bias = entry.scale[k], entry.bias[k]
            rgba[..., :3] = rgba[..., :3] * scale[0] + bias[0]
            rgba[..., 3] = rgba[..., 3] * scale[1] + bias[1]
        return rgba


def read_atlas(path) -> Atlas:
    """Read ``X.dds`` (or ``X.ktx2``) and, if present, its manifest ``X.json`` (checked: :func:`read_manifest`)."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path.as_posix()}: no such atlas")
    image = read_ktx2(path) if path.suffix.lower() == ".ktx2" else read_dds(path)
    manifest_path = path.with_suffix(".json")
    manifest = read_manifest(manifest_path) if manifest_path.exists() else None
    return Atlas(path, image, manifest)


def _scale_text(entry: MaterialEntry) -> str:
    """The first slice's ``rgb_scale,alpha_scale``, for ``atlasgen info``."""
    return "/".join(f"{s[0]:.3g},{s[1]:.3g}" for s in entry.scale[:1])


def describe_atlas(path, verbose: bool = False, quiet: bool = False) -> str:
    """What ``atlasgen info`` prints: the texconv-style line (alone when ``quiet``), the header, one
    line per material (and, when ``verbose``, its description and file)."""
    atlas = read_atlas(path)
    img = atlas.image
    if isinstance(img, KTX2Image):
        first = describe_ktx2(path, img.width, img.height, img.layers, img.mip_count, img.vk_format, img.layout,
                              img.supercompression)
        fmt_code = f"vkFormat {img.vk_format}"
        supercompressed = f", {img.supercompression_name} supercompressed" if img.supercompression_name != "none" else ""
    else:
        first, fmt_code, supercompressed = describe_dds(img, path), f"format {img.dxgi_format}", ""
    if quiet:
        return first
    lines = [first,
             f"  {fmt_code} ({img.format_name}){supercompressed}, layout {img.layout}, "
             f"{img.width}x{img.height}, {img.layers} layers, {img.mip_count} mips"]  # fmt: skip
    manifest = atlas.manifest
    if manifest is None:
        return "\n".join(lines + ["  no manifest beside it"])
    lines.append(f"  manifest v{manifest.format_version}, encoding {manifest.encoding}, {len(manifest.materials)} materials, "
                 f"{manifest.slices_used} slices used")  # fmt: skip
    for e in manifest.materials:
        lines.append(f"  {e.first_slice:>3}+{e.slice_count:<2} {e.name:<24} {e.type:<11} "
                     f"scale {_scale_text(e):<18} qerr max {e.quantization_error.max:.4f}")
        if verbose:
            lines.append(f"         {e.description or '(no description)'}; from {e.source}")
    return "\n".join(lines)


def summarize_atlas(path) -> dict:
    """Header fields and a manifest summary: ``atlasgen info --format json``
    (``atlasgen/schemas/info.schema.json``)."""
    atlas = read_atlas(path)
    img = atlas.image
    out = {
        "line": describe_dds(img, path) if isinstance(img, DDSImage) else describe_ktx2(
            path, img.width, img.height, img.layers, img.mip_count, img.vk_format, img.layout, img.supercompression),
        "header": {
            "width": img.width, "height": img.height, "layers": img.layers, "mip_count": img.mip_count,
            "dxgi_format": img.dxgi_format, "format_name": img.format_name, "layout": img.layout,
            "bytes": Path(path).stat().st_size,
        },
    }  # fmt: skip
    if isinstance(img, KTX2Image):
        out["header"].update(container="ktx2", vk_format=img.vk_format, supercompression=img.supercompression_name)
    if atlas.manifest is not None:
        manifest = atlas.manifest
        out["manifest"] = {
            "format_version": manifest.format_version,
            "encoding": manifest.encoding,
            "slices_used": manifest.slices_used,
            "materials": [
                {
                    "name": e.name, "type": e.type, "first_slice": e.first_slice, "slice_count": e.slice_count,
                    "scale": [list(s) for s in e.scale],
                    "qerr_max": e.quantization_error.max,
                    "description": e.description, "source": e.source,
                }
                for e in manifest.materials
            ],
        }  # fmt: skip
    return out
