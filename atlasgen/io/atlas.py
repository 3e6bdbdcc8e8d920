"""Reading a baked atlas back: the DDS, its manifest, and linear slices as a renderer sees them."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from atlasgen.io.dds import DDSImage, describe_dds, read_dds
from atlasgen.errors import InputError
from atlasgen.optics.quantize import dequantize_rgba

__all__ = ["Atlas", "read_atlas", "summarize_atlas"]


@dataclass
class Atlas:
    """A baked atlas: its DDS image and its manifest (``None`` if there is none beside it)."""

    path: Path
    image: DDSImage
    manifest: dict | None

    @property
    def srgb(self) -> bool:
        return self.image.dxgi_format == 29

    def material(self, name: str) -> dict:
        """The manifest entry of ``name``; InputError listing the known names otherwise."""
        for entry in (self.manifest or {}).get("materials", []):
            if entry["name"] == name:
                return entry
        known = ", ".join(sorted(e["name"] for e in (self.manifest or {}).get("materials", []))) or "none"
        raise InputError(f"{self.path.as_posix()}: no material {name!r}; known: {known}")

    def decode_slice(self, slice_index: int, level: int = 0, apply_scale: bool = True) -> np.ndarray:
        """Linear RGBA ``(h, w, 4)`` of one array slice: what the include's ``atlas_sample`` returns."""
        if self.image.layout != "array":
            raise InputError(f"{self.path.as_posix()}: decode_slice needs a 2D-array atlas")
        rgba = dequantize_rgba(self.image.levels[level][slice_index], self.srgb)
        if apply_scale and self.manifest is not None:
            entry = next(
                e for e in self.manifest["materials"]
                if e["first_slice"] <= slice_index < e["first_slice"] + e["slice_count"]
            )  # fmt: skip
            k = slice_index - entry["first_slice"]
            scale, bias = entry["scale"][k], entry["bias"][k]
            rgba[..., :3] = rgba[..., :3] * scale[0] + bias[0]
            rgba[..., 3] = rgba[..., 3] * scale[1] + bias[1]
        return rgba


def read_atlas(path) -> Atlas:
    """Read ``X.dds`` and, if present, its manifest ``X.json``."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"{path.as_posix()}: no such atlas")
    image = read_dds(path)
    manifest_path = path.with_suffix(".json")
    manifest = None
    if manifest_path.exists():
        try:
            manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
        except ValueError as exc:
            raise InputError(f"{manifest_path.as_posix()}: malformed manifest JSON ({exc})") from None
    return Atlas(path, image, manifest)


def summarize_atlas(path) -> dict:
    """Header fields and a manifest summary, for ``atlasgen info``."""
    atlas = read_atlas(path)
    img = atlas.image
    out = {
        "line": describe_dds(img, path),
        "header": {
            "width": img.width, "height": img.height, "layers": img.layers, "mip_count": img.mip_count,
            "dxgi_format": img.dxgi_format, "format_name": img.format_name, "layout": img.layout,
            "bytes": Path(path).stat().st_size,
        },
    }  # fmt: skip
    if atlas.manifest is not None:
        m = atlas.manifest
        out["manifest"] = {
            "format_version": m.get("format_version"),
            "encoding": m.get("encoding"),
            "slices_used": sum(e["slice_count"] for e in m["materials"]),
            "materials": [
                {
                    "name": e["name"], "type": e["type"], "first_slice": e["first_slice"],
                    "slice_count": e["slice_count"],
                    "scale": "/".join(f"{s[0]:.3g},{s[1]:.3g}" for s in e["scale"][:1]),
                    "qerr_max": e["quantization_error"]["max"],
                    "description": e.get("description", ""), "source": e.get("source", ""),
                }
                for e in m["materials"]
            ],
        }  # fmt: skip
    return out
