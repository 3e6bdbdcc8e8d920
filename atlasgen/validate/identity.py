"""What identifies a material in the atlas it was validated on, so that a report's figures can be told current.

``atlasgen validate`` records per result (``atlas_identity`` in report.json) the manifest's SHA-256 (the whole
atlas's generation), the material file's content hash (the manifest's ``content_hash``) and
:func:`material_sha256`: the SHA-256 of what validation renders of that material, its manifest entry and its
texels. A reader of the report (``atlasgen report library``) compares it with the atlas it is given
(:func:`identity_problem`): figures whose material differs were measured on another bake of it.

The material's hash leaves out what moves when another material changes (its slot: ``id``, ``first_slice``,
``constant``; and ``source``, the file's path relative to the manifest), so that ``make validate``, which
validates each material once and re-assembles the atlas around it, keeps every other material's figures current.
"""

from __future__ import annotations

import hashlib
import json

import numpy as np

from atlasgen.io.digest import update_with_array

__all__ = ["material_sha256", "atlas_identity", "identity_problem", "IDENTITY_VERSION"]

#: Bumped whenever :func:`material_sha256` hashes other things: an older figure then reads as changed.
IDENTITY_VERSION = 2
#: Entry fields that say where the material sits in this atlas, not what it is.
_PLACEMENT = ("id", "first_slice", "constant", "source")


def _texel_ranges(layout: str, first: int, count: int, levels) -> list:
    """Per mip level, the texels a lookup of the material may read: its own slices of a 2D array; of a volume,
    the depth slices its ids fall in at each level and one on either side (a coarser level blends neighbours)."""
    out = []
    last = first + count - 1
    for k, level in enumerate(levels):
        if layout == "array":
            out.append(level[first : last + 1])
        else:
            lo, hi = (first, last) if k == 0 else ((first >> k) - 1, (last >> k) + 1)
            out.append(level[max(lo, 0) : min(hi, len(level) - 1) + 1])
    return out


def material_sha256(atlas, entry) -> str:
    """SHA-256 of what the atlas holds of ``entry``: its manifest entry without its placement (:data:`_PLACEMENT`),
    the manifest's format and encoding, and the texels a lookup of it may read (:func:`_texel_ranges`)."""
    manifest = atlas.manifest
    record = {k: v for k, v in entry.to_json().items() if k not in _PLACEMENT}
    head = {"identity": IDENTITY_VERSION, "format_version": manifest.format_version, "encoding": manifest.encoding,
            "layout": manifest.layout, "entry": record}  # fmt: skip
    digest = hashlib.sha256(json.dumps(head, sort_keys=True, allow_nan=True).encode())
    for texels in _texel_ranges(atlas.image.layout, entry.first_slice, entry.slice_count, atlas.image.levels):
        update_with_array(digest, np.asarray(texels, dtype=np.uint8))
    return digest.hexdigest()


def atlas_identity(atlas, entry) -> dict:
    """What report.json records of the material ``entry`` of ``atlas`` (an :class:`~atlasgen.io.atlas.Atlas`)."""
    return {"manifest_sha256": atlas.manifest_sha256, "content_hash": entry.content_hash,
            "material_sha256": material_sha256(atlas, entry)}  # fmt: skip


def identity_problem(recorded, current: dict) -> str | None:
    """Why a result's recorded ``atlas_identity`` is not the material ``current`` (:func:`atlas_identity`) is, or None.

    >>> now = {"manifest_sha256": "m2", "content_hash": "c", "material_sha256": "s"}
    >>> identity_problem({"manifest_sha256": "m1", "content_hash": "c", "material_sha256": "s"}, now) is None
    True
    >>> identity_problem({"manifest_sha256": "m1", "content_hash": "b", "material_sha256": "t"}, now)
    'its material file has changed since: another content hash'
    >>> identity_problem({"manifest_sha256": "m1", "content_hash": "c", "material_sha256": "t"}, now)
    'it was baked differently since: its manifest entry or texels differ'
    """
    if not isinstance(recorded, dict) or not isinstance(recorded.get("material_sha256"), str):
        return "the report records no identity of the atlas it validated"
    if recorded["material_sha256"] == current["material_sha256"]:
        return None
    if recorded.get("content_hash") != current["content_hash"]:
        return "its material file has changed since: another content hash"
    return "it was baked differently since: its manifest entry or texels differ"
