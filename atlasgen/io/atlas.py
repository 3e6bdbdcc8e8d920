"""Reading a baked atlas back: the DDS or KTX2, its manifest, and linear slices as a renderer sees them.

A bake's files are one generation, tied by hashes: the manifest records the texture's
SHA-256 (``atlas_sha256``), every include (and the separable side-car) the manifest's.
:func:`read_atlas` is the one reader of the pair; it refuses a texture that does not hash
to what its manifest records, or whose header disagrees with what the manifest claims
(size, layers, mip count, layout, encoding), with one line naming both files and saying
to re-run the bake::

    build/atlas.json: field 'atlas_sha256': does not match build/atlas.dds (the two are from different bakes); re-run atlasgen bake
"""

from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from atlasgen.contract import HEIGHT, LAYERS, WIDTH
from atlasgen.errors import InputError
from atlasgen.io.dds import DDSImage, describe_dds, read_dds
from atlasgen.io.fields import counted
from atlasgen.io.ktx2 import KTX2Image, describe_ktx2, read_ktx2
from atlasgen.io.manifest import Manifest, MaterialEntry, parse_manifest, read_manifest_text, with_absolute_files
from atlasgen.io.sidecar import SIDECAR_HEADER_SIZE, sidecar_manifest_sha256
from atlasgen.io.text import MISSING, path_kind, read_input_bytes
from atlasgen.optics.quantize import dequantize_rgba

__all__ = [
    "Atlas",
    "MAX_INCLUDE_BYTES",
    "apply_slice_scale",
    "read_atlas",
    "as_atlas",
    "check_include",
    "companion_states",
    "COMPANIONS",
    "include_manifest_sha256",
    "texel_sha256",
    "KTX2_MANIFEST_KEY",
    "summarize_atlas",
    "describe_atlas",
    "INCLUDE_HASH_PREFIX",
    "RERUN",
]

#: The first line of every include: this, then the SHA-256 (hex) of the manifest written with it.
INCLUDE_HASH_PREFIX = "// atlasgen manifest sha256: "
#: The KTX2 key/value entry that records the SHA-256 of the manifest written beside it.
KTX2_MANIFEST_KEY = "atlasgen.manifest_sha256"
#: How every refusal of a mismatched generation ends.
RERUN = "re-run atlasgen bake"


@dataclass
class Atlas:
    """A baked atlas: its DDS or KTX2 image and its manifest (``None`` if there is none beside it)."""

    path: Path
    image: DDSImage | KTX2Image
    manifest: Manifest | None
    #: SHA-256 (hex) of the manifest's bytes as read ("" without a manifest): what an include must record.
    manifest_sha256: str = ""

    @property
    def srgb(self) -> bool:
        return self.image.dxgi_format == 29

    @property
    def manifest_path(self) -> Path:
        return self.path.with_suffix(".json")

    def source_path(self, entry: MaterialEntry) -> Path:
        """The material file of ``entry``: its ``source`` is relative to the manifest's folder, from
        that folder's real place (a ``..`` out of a symlinked folder leaves its target). Spelled
        from the path the atlas was opened by where that reaches the same file."""
        spelled = Path(os.path.normpath(self.manifest_path.parent / entry.source))
        real = Path(os.path.normpath(Path(os.path.realpath(self.manifest_path.parent)) / entry.source))
        return spelled if os.path.realpath(spelled) == os.path.realpath(real) else real

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
        if not 0 <= level < len(self.image.levels):
            raise InputError(f"{self.path.as_posix()}: no mip level {level}; the atlas has {len(self.image.levels)}")
        if not 0 <= slice_index < self.image.layers:
            raise InputError(f"{self.path.as_posix()}: no slice {slice_index}; the atlas has slices 0..{self.image.layers - 1}")
        rgba = dequantize_rgba(self.image.levels[level][slice_index], self.srgb)
        entry = self.manifest.by_slice(slice_index) if apply_scale and self.manifest is not None else None
        if entry is not None:
            k = slice_index - entry.first_slice
            rgba = apply_slice_scale(rgba, entry.scale[k], entry.bias[k])
        return rgba


def apply_slice_scale(rgba: np.ndarray, scale, bias) -> np.ndarray:
    """Decoded texels ``(..., 4)`` in the slice's units: RGB * scale[0] + bias[0], A * scale[1] + bias[1]
    (docs/atlas-format.md, the manifest's ``value`` mapping), in place; returns ``rgba``."""
    rgba[..., :3] = rgba[..., :3] * scale[0] + bias[0]
    rgba[..., 3] = rgba[..., 3] * scale[1] + bias[1]
    return rgba


def as_atlas(atlas) -> Atlas:
    """``atlas`` itself if it is an :class:`Atlas` already read, else :func:`read_atlas` of the path: a caller
    that reads the pair once hands the same one to every reader below it."""
    return atlas if isinstance(atlas, Atlas) else read_atlas(atlas)


#: Bytes an atlas file may have: the whole 64x32x256 RGBA8 mip chain is 2.8 MB uncompressed, so this leaves
#: room for any header and key/value data, and a device, or a file that is no atlas, is refused before it is read.
MAX_ATLAS_BYTES = 16 * 2**20
#: Bytes a shader include beside an atlas may have: a 256-slice library's is under 1 MB; a larger file (3 GB read
#: whole ended render in a MemoryError) is refused before it is read.
MAX_INCLUDE_BYTES = 64 << 20


def read_atlas(path) -> Atlas:
    """Read ``X.dds`` (or ``X.ktx2``) and, if present, its manifest ``X.json``, checked as a pair.

    The manifest is checked field by field (:func:`atlasgen.io.manifest.parse_manifest`),
    then against the texture: the header's width, height, layers, mip count, layout and
    encoding must be what the manifest claims (and the atlas contract's 64x32x256), and
    the texture's texels must hash to the manifest's ``atlas_sha256`` (:func:`texel_sha256`),
    and a KTX2's recorded manifest hash must be this manifest's. Each file is read once.

    Raises
    ------
    InputError
        The texture is missing, unreadable or malformed; or the pair does not match (one
        line naming both files, ending "re-run atlasgen bake").
    ManifestError
        The manifest is not a valid manifest.
    """
    path = Path(path)
    if path_kind(path) == "a directory":  # path.is_dir() raised on a name too long (ENAMETOOLONG), an internal error
        raise InputError(f"{path.as_posix()}: expected an atlas texture (DDS or KTX2), got a directory")
    if path.suffix.lower() == ".json":  # the manifest, which a first user may take for the atlas
        raise InputError(f"{path.as_posix()}: expected the atlas texture (.dds or .ktx2) beside this manifest, "
                         "not the manifest")  # fmt: skip
    # A first user in a fresh folder is told what makes one: `atlasgen bake -o X` alone reads ./materials.
    missing = f"no such atlas; bake one first (atlasgen bake MATERIAL_FILES_OR_FOLDERS -o {path.as_posix()})"
    data = read_input_bytes(path, missing, (MAX_ATLAS_BYTES, "an atlas texture (DDS or KTX2)"))
    image = read_ktx2(path, data) if path.suffix.lower() == ".ktx2" else read_dds(path, data)
    manifest_path = path.with_suffix(".json")
    # A link beside the atlas that loops is a broken manifest, refused by the reader below on one line, not an atlas
    # without one (exists() is False for it, and info said "no manifest"). So is one that points nowhere: bake writes
    # its outputs as links into a generation folder (atlasgen.io.output_paths), and a link left dangling there means
    # that folder was damaged, not that the atlas never had a manifest.
    if path_kind(manifest_path) == MISSING:
        if manifest_path.is_symlink():
            raise InputError(f"{manifest_path.as_posix()}: a symbolic link to {os.readlink(manifest_path)!r}, which does "
                             f"not exist; expected the atlas's manifest there; {RERUN}")  # fmt: skip
        return Atlas(path, image, None)
    text = read_manifest_text(manifest_path)
    manifest = with_absolute_files(parse_manifest(text, manifest_path.as_posix()), manifest_path.parent)
    manifest_sha256 = hashlib.sha256(text.encode("utf-8")).hexdigest()
    _check_pair(path, image, manifest_path, manifest, manifest_sha256)
    return Atlas(path, image, manifest, manifest_sha256)


def texel_sha256(levels) -> str:
    """SHA-256 of an atlas's texels: every mip level's uint8 RGBA, level 0 first, each as
    ``(layers or depth, height, width, 4)`` in C order. The same for the DDS and the KTX2
    (plain or supercompressed) of one bake, so a KTX2 can also carry the manifest's hash."""
    digest = hashlib.sha256()
    for level in levels:
        digest.update(np.ascontiguousarray(level, dtype=np.uint8).tobytes())
    return digest.hexdigest()


def _check_pair(path: Path, image, manifest_path: Path, manifest: Manifest, manifest_sha256: str) -> None:
    """Refuse a texture whose header or texels are not what its manifest says (or, for a KTX2,
    whose recorded manifest hash is another manifest's)."""
    shown, shown_manifest = path.as_posix(), manifest_path.as_posix()

    def refuse(key: str, problem: str):
        raise InputError(f"{shown_manifest}: field {key!r}: {problem}; {RERUN}")

    dims = manifest.dimensions
    for key, claimed, contract in (
        ("width", dims.width, WIDTH),
        ("height", dims.height, HEIGHT),
        ("layers", dims.layers, LAYERS),
    ):
        if claimed != contract:
            refuse(f"dimensions.{key}", f"expected the atlas contract's {contract}, got {claimed}")
    claims: list[tuple[str, object, object]] = [("dimensions.width", dims.width, image.width), ("dimensions.height", dims.height, image.height),
              ("dimensions.layers", dims.layers, image.layers), ("dimensions.mip_count", dims.mip_count, image.mip_count),
              ("layout", manifest.layout, image.layout),
              ("encoding", manifest.encoding, "srgb" if image.dxgi_format == 29 else "linear")]  # fmt: skip
    for key, said, actual in claims:
        if said != actual:
            refuse(key, f"says {said}, but {shown} has {actual} (the two are from different bakes)")
    if manifest.atlas_sha256 != texel_sha256(image.levels):
        refuse("atlas_sha256", f"does not match {shown} (the two are from different bakes)")
    recorded = getattr(image, "key_values", {}).get(KTX2_MANIFEST_KEY)
    if isinstance(image, KTX2Image) and recorded is None:
        # Every KTX2 the bake writes records it: without it, an edited manifest would pass as this atlas's.
        raise InputError(f"{shown}: KTX2 key {KTX2_MANIFEST_KEY!r}: missing; expected the SHA-256 of {shown_manifest}, "
                         f"which atlasgen bake records; {RERUN}")  # fmt: skip
    if recorded is not None and recorded.rstrip(b"\0").decode("ascii", "replace") != manifest_sha256:
        raise InputError(
            f"{shown}: KTX2 key {KTX2_MANIFEST_KEY!r}: does not match {shown_manifest} "
            f"(the two are from different bakes); {RERUN}"
        )


def include_manifest_sha256(text: str) -> str | None:
    """The manifest SHA-256 an include's first line records (``// atlasgen manifest sha256: ...``), or ``None``."""
    first = text.split("\n", 1)[0].strip()
    return first[len(INCLUDE_HASH_PREFIX) :].strip() if first.startswith(INCLUDE_HASH_PREFIX.strip()) else None


def check_include(atlas: Atlas, include_path, text: str) -> None:
    """Refuse an include (WGSL, GLSL or HLSL text read from ``include_path``) that was not
    written with ``atlas``'s manifest: its first line must record the manifest's SHA-256."""
    include_path = Path(include_path)
    recorded = include_manifest_sha256(text)
    if recorded is None:
        raise InputError(f"{include_path.as_posix()}: expected a first line '{INCLUDE_HASH_PREFIX}...' "
                         f"(an include written by atlasgen bake); {RERUN}")  # fmt: skip
    if recorded != atlas.manifest_sha256:
        raise InputError(f"{include_path.as_posix()}: its manifest sha256 does not match {atlas.manifest_path.as_posix()} "
                         f"(the two are from different bakes); {RERUN}")  # fmt: skip


#: The files a bake writes beside the atlas that record its manifest's SHA-256: the includes (their first line) and
#: the separable side-car (its header), by the suffix that replaces the atlas's.
COMPANIONS = (".wgsl", ".glsl", ".hlsl", ".separable.bin")
#: Bytes read of an include for its first line.
_FIRST_LINE_BYTES = 256


def _recorded_sha256(path: Path, suffix: str) -> str | None:
    """The manifest SHA-256 the companion at ``path`` records, or None (OSError where it cannot be read)."""
    with open(path, "rb") as f:
        head = f.read(max(_FIRST_LINE_BYTES, SIDECAR_HEADER_SIZE))
    if suffix == ".separable.bin":
        return sidecar_manifest_sha256(head)
    return include_manifest_sha256(head.decode("utf-8", errors="replace"))


def companion_states(atlas: Atlas, expected: dict[str, bytes] | None = None) -> dict[str, str]:
    """``suffix -> state`` of each of :data:`COMPANIONS` beside ``atlas``: ``"this bake"`` where it records the
    manifest's SHA-256, ``"another bake"`` where it records another, ``"not atlasgen's"`` where it records none (or
    is no file), ``"none"`` where there is nothing by that name (a bake writes only the languages asked for, and a
    side-car only for separable materials). What ``atlasgen info`` shows: a renderer or an engine loading an include
    of another bake than its atlas reads other slices and scales than the include declares.

    With ``expected`` (``suffix -> bytes`` a bake of this manifest writes, :func:`atlasgen.bake.companions.
    expected_companions`), a file that records this manifest but differs from them is ``"edited since its bake"``."""
    return {suffix: _companion_state(atlas, suffix, expected) for suffix in COMPANIONS}


def _companion_state(atlas: Atlas, suffix: str, expected: dict[str, bytes] | None) -> str:
    path = atlas.path.with_suffix(suffix)
    kind = path_kind(path)
    if kind == MISSING:
        return "none"
    try:
        recorded = _recorded_sha256(path, suffix) if kind is None else None  # a folder or a device records nothing
    except OSError:
        recorded = None
    if recorded is None:
        return "not atlasgen's"
    if recorded != atlas.manifest_sha256:
        return "another bake"
    if expected is not None and not _holds(path, expected.get(suffix)):
        return "edited since its bake"
    return "this bake"


def _holds(path: Path, wanted: bytes | None) -> bool:
    """Whether the file at ``path`` holds exactly ``wanted`` (read only up to one byte past its length)."""
    if wanted is None:
        return False
    try:
        with open(path, "rb") as f:
            return f.read(len(wanted) + 1) == wanted
    except OSError:
        return False


#: Control characters: a line break, a carriage return, NUL, the escape that starts a terminal's colour codes.
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


def _printable(text: str) -> str:
    r"""``text`` with each control character written as its escape, so that a manifest's own strings (a material's
    description, its type) keep ``info``'s lines one line each and leave the terminal as it was.

    >>> print(_printable("line one\nline two\x1b[31m red\x00"))
    line one\nline two\x1b[31m red\x00
    """
    return _CONTROL.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), text)


def _scale_text(entry: MaterialEntry) -> str:
    """The first slice's ``rgb_scale,alpha_scale``, for ``atlasgen info``."""
    return "/".join(f"{s[0]:.3g},{s[1]:.3g}" for s in entry.scale[:1])


def describe_atlas(path, verbose: bool = False, quiet: bool = False, expected=None) -> str:
    """What ``atlasgen info`` prints: the texconv-style line (alone when ``quiet``), the header, one
    line per material (and, when ``verbose``, its description and file). ``expected``: a function of the atlas
    giving the bytes a bake of its manifest writes beside it (:func:`companion_states`), called where it has one."""
    atlas = read_atlas(path)
    img = atlas.image
    if isinstance(img, KTX2Image):
        first = describe_ktx2(
            path, img.width, img.height, img.layers, img.mip_count, img.vk_format, img.layout, img.supercompression
        )
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
    lines.append(f"  manifest v{manifest.format_version}, encoding {manifest.encoding}, "
                 f"{counted(len(manifest.materials), 'material')}, {counted(manifest.slices_used, 'slice')} used")  # fmt: skip
    states = companion_states(atlas, expected(atlas) if expected else None)
    found = [
        f"{_printable(atlas.path.with_suffix(suffix).name)} ({state})" for suffix, state in states.items() if state != "none"
    ]
    # Absent ones named too: a deleted include was not mentioned, where the docs promise "absent".
    absent = [_printable(atlas.path.with_suffix(suffix).name) for suffix, state in states.items() if state == "none"]
    lines.append(f"  beside it: {', '.join(found) or 'no include'}" + (f"; absent: {', '.join(absent)}" if absent else ""))
    for e in manifest.materials:
        lines.append(
            f"  {e.first_slice:>3}+{e.slice_count:<2} {e.name:<24} {_printable(e.type):<11} "
            f"scale {_scale_text(e):<18} qerr max {e.quantization_error.max:.4f}"
        )
        if verbose:
            described = _printable(e.description or "(no description)")
            lines.append(f"         {described}; from {_printable(atlas.source_path(e).as_posix())}")
    return "\n".join(lines)


def summarize_atlas(path, expected=None) -> dict:
    """Header fields and a manifest summary: ``atlasgen info --format json``
    (``atlasgen/schemas/info.schema.json``); ``expected`` as :func:`describe_atlas`'s."""
    atlas = read_atlas(path)
    img = atlas.image
    out: dict[str, Any] = {
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
        states = companion_states(atlas, expected(atlas) if expected else None)
        out["companions"] = {suffix.lstrip("."): state for suffix, state in states.items()}
    return out
