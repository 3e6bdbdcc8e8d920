"""The bake: validated materials in, an 8-bit atlas with mips, manifest, include and timings out."""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from atlasgen import __version__
from atlasgen.bake.cache import load_or_draft
from atlasgen.bake.mips import build_array_mips, build_volume_mips
from atlasgen.bake.preview import render_contact_sheet
from atlasgen.bake.quality import MaterialWarning, assess_material, assess_storage
from atlasgen.bake.slots import assign_slices
from atlasgen.bake.workers import load_or_bake_all
from atlasgen.contract import FORMAT_VERSION, HEIGHT, LAYERS, MAPPING, SPECULAR_LOBE, WIDTH
from atlasgen.errors import ManifestError, MaterialError, OutputError
from atlasgen.io.atlas import KTX2_MANIFEST_KEY, texel_sha256
from atlasgen.io.atomic import write_files_atomically
from atlasgen.io.dds import DXGI_FORMAT_R8G8B8A8_UNORM, DXGI_FORMAT_R8G8B8A8_UNORM_SRGB, describe_texture, encode_dds
from atlasgen.io.fields import FLOAT32_MAX
from atlasgen.io.ktx2 import (
    SUPERCOMPRESSION_NONE,
    SUPERCOMPRESSION_ZSTD,
    VK_FORMAT_R8G8B8A8_SRGB,
    VK_FORMAT_R8G8B8A8_UNORM,
    describe_ktx2,
    encode_ktx2,
)
from atlasgen.io.manifest import Dimensions, ErrorSummary, Manifest, MaterialEntry, VolumeBleed, format_manifest, read_slots
from atlasgen.io.output_paths import check_suffix
from atlasgen.io.referenced_files import real_folder_path, relative_files
from atlasgen.io.sidecar import stamp_sidecar
from atlasgen.io.text import MISSING, path_kind
from atlasgen.models import get_model
from atlasgen.optics.quantize import dequantize_rgba, quantize_rgba
from atlasgen.shaders.include import render_include_data, render_includes, stamp_include

__all__ = [
    "BakeResult",
    "bake_atlas",
    "read_previous_slots",
    "sibling_paths",
    "other_container_path",
    "write_bake",
    "encode_atlas_texture",
    "pair_outputs",
    "relative_source",
]


@dataclass
class BakeResult:
    """Everything a bake produces, in memory, before anything touches the disk."""

    levels: list  # uint8 mip levels, as write_dds takes them
    layout: str
    dxgi_format: int
    manifest: Manifest
    include: str  # WGSL
    timings: dict
    warnings: list = field(default_factory=list)
    #: ``{"glsl": text, "hlsl": text}``: the include in the other languages (WGSL is ``include``).
    includes: dict = field(default_factory=dict)
    #: ``X.separable.bin``: the separable rebuild's data table (atlasgen.shaders.separable); b"" for none.
    separable_data: bytes = b""
    #: Per-material warnings (:mod:`atlasgen.bake.quality`): a measured error over the threshold and its
    #: cause, tolerated non-finite samples. ``warnings`` holds the bake's other notes (cache, clamping).
    material_warnings: list[MaterialWarning] = field(default_factory=list)
    #: ``bake_atlas(drafts=True)``: name -> the completion of each material baked as a draft (its
    #: entry lacks the figures the completion measures); empty for a full bake.
    drafts: dict = field(default_factory=dict)

    def describe(self, dds_path, zstd: bool = False) -> str:
        """The texconv-style line for this atlas written to ``dds_path`` (``.dds`` or ``.ktx2``)."""
        if Path(dds_path).suffix.lower() == ".ktx2":
            vk_format = (
                VK_FORMAT_R8G8B8A8_SRGB if self.dxgi_format == DXGI_FORMAT_R8G8B8A8_UNORM_SRGB else VK_FORMAT_R8G8B8A8_UNORM
            )
            scheme = SUPERCOMPRESSION_ZSTD if zstd else SUPERCOMPRESSION_NONE
            return describe_ktx2(dds_path, WIDTH, HEIGHT, LAYERS, len(self.levels), vk_format, self.layout, scheme)
        return describe_texture(dds_path, WIDTH, HEIGHT, LAYERS, len(self.levels), self.dxgi_format, self.layout)


#: The atlas containers, chosen by the output's suffix.


#: What ``-o`` may name: the atlas's container formats.
ATLAS_SUFFIXES = (".dds", ".ktx2")


def sibling_paths(dds_path) -> dict:
    """The files written beside ``X.dds`` (or ``X.ktx2``, kept under the key ``"dds"``): manifest, include and timings.

    >>> sorted(p.as_posix() for p in sibling_paths("out/hero.v2.ktx2").values())[:3]
    ['out/hero.v2.glsl', 'out/hero.v2.hlsl', 'out/hero.v2.json']
    """
    p = Path(dds_path)
    check_suffix(p, "the atlas (-o)", ATLAS_SUFFIXES)
    # Only the container's suffix is replaced: "a.b.dds" keeps "a.b", or it would write over a.dds's files.
    return {
        "dds": p,
        "manifest": p.with_suffix(".json"),
        "include": p.with_suffix(".wgsl"),
        "glsl": p.with_suffix(".glsl"),
        "hlsl": p.with_suffix(".hlsl"),
        "separable": p.with_suffix(".separable.bin"),
        "timings": p.with_suffix(".timings.json"),
    }


def other_container_path(atlas_path) -> Path:
    """``X.ktx2`` for ``X.dds`` and the reverse: the container a bake to ``atlas_path`` removes.

    The two share their side files (``X.json``, the includes, the side-car), so only one of
    them may stand beside those files.

    >>> other_container_path("build/atlas.dds").as_posix(), other_container_path("a.KTX2").as_posix()
    ('build/atlas.ktx2', 'a.dds')
    """
    p = Path(atlas_path)
    return p.with_suffix(".dds" if p.suffix.lower() == ".ktx2" else ".ktx2")


def read_previous_slots(manifest_path, missing_ok: bool = True) -> dict[str, int]:
    """``name -> first_slice`` from an existing manifest of any format version, so re-bakes
    keep IDs stable (:func:`atlasgen.io.manifest.read_slots`); ``{}`` where there is none and
    ``missing_ok`` (the atlas's own manifest before its first bake, not a named ``--ids-from``).

    Raises :class:`~atlasgen.errors.ManifestError` (naming the file and the field) for a
    manifest whose names and slices cannot be read, deleting it re-numbers every material;
    :class:`~atlasgen.errors.InputError` for a missing one unless ``missing_ok``.
    """
    path = Path(manifest_path)
    # A link that loops is read, and refused, not taken for no manifest (exists() is False for it). One that points
    # nowhere is no manifest: a first commit killed before its generation was current leaves the set's links so,
    # and refusing them left every later bake (and make) failing until they were removed by hand.
    if path_kind(path) == MISSING and missing_ok:
        return {}
    try:
        return read_slots(path)
    except ManifestError as exc:
        if not missing_ok:
            raise
        # The atlas's own manifest, damaged: refused, since baking past it would re-number what an engine holds, but
        # the line says how out (it read as if the bake could never again write this output).
        raise ManifestError(exc.path, exc.field, f"{exc.expected}; bake reads it to keep the atlas's material IDs: "
                            "mend it, or delete it to bake afresh with every ID assigned anew") from None  # fmt: skip


def _jsonable(value):
    if isinstance(value, tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, list):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, np.generic):
        return value.item()
    return value


def _measure_volume_bleed(float_levels, materials_slots, scales):
    """Per volume mip level, how far a material's texels are from its own 2D mip (linear units).

    Level k of a volume averages 2^k neighbouring slices, so material m read at level
    k sees its neighbours; the reference is m's own box-filtered 2D chain.
    """
    bleed = []
    own_chains = {}
    for k in range(1, len(float_levels)):
        worst, sq, n = 0.0, 0.0, 0
        level = float_levels[k]
        for first, count in materials_slots:
            for s in range(first, first + count):
                if s not in own_chains:
                    own_chains[s] = build_array_mips(float_levels[0][s : s + 1])
                chain = own_chains[s]
                own = chain[min(k, len(chain) - 1)][0]
                got = level[min(s >> k, level.shape[0] - 1)]
                scale = np.array([scales[s][0]] * 3 + [scales[s][1]])
                diff = np.abs(got - own) * scale
                worst = max(worst, float(diff.max()))
                sq += float((diff**2).sum())
                n += diff.size
        bleed.append(VolumeBleed(level=k, max=worst, rms=(sq / n) ** 0.5 if n else 0.0))
    return bleed


def _check_encoded(material, encoded) -> None:
    """Refuse slices whose scale, bias or stored values float32 cannot hold (the include's
    constants, the shader's arithmetic): texels too large, or infinite, for the atlas."""
    numbers = {"scale": encoded.scale, "bias": encoded.bias, "stored texels": encoded.stored}
    numbers.update({k: v for k, v in (encoded.extra or {}).items() if k.startswith("factor_")})
    for what, value in numbers.items():
        array = np.asarray(value, dtype=np.float64)
        if not (np.isfinite(array).all() and (np.abs(array) <= FLOAT32_MAX).all()):
            raise MaterialError(
                material.source,
                None,
                f"material {material.name!r}: model '{material.type}' produced a slice {what} that float32 cannot hold; "
                "expected texels within float32's range (check its parameters)",
            )


def bake_atlas(
    materials,
    layout: str = "array",
    linear: bool = False,
    previous_slots=None,
    progress=None,
    cache_dir=None,
    drafts: bool = False,
    baked=None,
    jobs: int = 1,
    pinned_slots=None,
) -> BakeResult:
    """Bake validated materials into an RGBA8 atlas.

    Parameters
    ----------
    materials
        :class:`atlasgen.materials.material.Material` records (see :func:`read_materials`).
    layout
        ``"array"`` (Texture2DArray, a mip chain per slice) or ``"volume"`` (Texture3D,
        whose mips also halve depth and so blend neighbouring materials).
    linear
        Store RGB linearly (DXGI 28) instead of sRGB-encoded (DXGI 29).
    previous_slots
        ``name -> first_slice`` of the previous bake; keeps slices stable.
    pinned_slots
        ``(manifest_path, name -> first_slice)`` of the atlas whose IDs this one shares (``--ids-from``),
        which win over ``previous_slots`` (:func:`~atlasgen.bake.slots.assign_slices`).
    progress
        Called with each material's name once it is baked.
    cache_dir
        Folder of per-material float slices (:mod:`atlasgen.bake.cache`); materials whose
        file and bake code are unchanged are loaded instead of baked.
    drafts
        Bake a material the cache lacks as its model's draft where it has one
        (:func:`~atlasgen.bake.cache.load_or_draft`): the same texels and include, the entry without
        the figures still to measure; ``BakeResult.drafts`` holds the completions. For a preview only.
    baked
        ``name -> SliceSet`` already baked (a draft's completion), used instead of the cache or a bake.
    jobs
        Bake the materials the cache lacks in up to this many processes
        (:func:`~atlasgen.bake.workers.load_or_bake_all`); the atlas is the same bytes for any number.
    """
    if layout not in ("array", "volume"):
        raise ValueError(f"layout must be 'array' or 'volume', not {layout!r}")
    t_start = time.perf_counter()
    srgb = not linear
    given = baked or {}
    baked = []
    timings = {"materials": {}}
    cache_hits, baked_names, cache_warnings = [], [], []
    completions = {}
    # Every material takes at least its fewest slices (a fixed K's K, one for the rest): more than the atlas
    # holds, or explicit ids in conflict, are refused now, not after minutes of baking (an auto material's slice
    # count is known only once baked, and assign_slices refuses with more slices whatever refuses with fewer).
    assign_slices([(m.name, m.model.fewest_slices(m.params), m.id, m.source) for m in materials], previous_slots,
                  pinned=pinned_slots)  # fmt: skip
    whole = [] if drafts else [m for m in materials if m.name not in given]
    loaded = dict(zip((m.name for m in whole), load_or_bake_all(cache_dir, whole, jobs, cache_warnings, progress), strict=True))
    for material in materials:
        model = material.model
        if material.name in given:
            slices, hit = given[material.name], False
        elif drafts:
            slices, hit, complete = load_or_draft(cache_dir, material, cache_warnings)
            if complete is not None:
                completions[material.name] = complete
        else:
            slices, hit = loaded[material.name]
        (cache_hits if hit else baked_names).append(material.name)
        values = np.asarray(slices.values, dtype=np.float64)
        if values.ndim != 4 or values.shape[1:] != (HEIGHT, WIDTH, 4) or values.shape[0] < 1:
            raise MaterialError(
                material.source, "type", f"model produced slices of shape {values.shape}; expected (n, {HEIGHT}, {WIDTH}, 4)"
            )
        bad = ~np.isfinite(values)
        if bad.any():
            raise MaterialError(
                material.source,
                None,
                f"material {material.name!r}: model '{material.type}' produced {int(bad.sum())} non-finite texels; "
                "expected finite values (check its parameters)",
            )
        t_encode = time.perf_counter()
        encoded = model.encode(material.params, slices, material.rgb_scale, material.alpha_scale)
        _check_encoded(material, encoded)
        baked.append((material, slices, values, encoded))
        # bake_s is the model's bake as measured when it ran, also for cache hits.
        timings["materials"][material.name] = {**slices.timings, "encode_s": time.perf_counter() - t_encode}
        if progress and material.name not in loaded:
            progress(material.name)

    requests = [(m.name, v.shape[0], m.id, m.source) for m, _, v, _ in baked]
    slots = assign_slices(requests, previous_slots, pinned=pinned_slots)

    # float32 is ample for 8-bit output, and halves the cost of the mips and their encoding.
    level0 = np.zeros((LAYERS, HEIGHT, WIDTH, 4), dtype=np.float32)
    scales = np.ones((LAYERS, 2))
    biases = np.zeros((LAYERS, 2))
    for material, _, values, encoded in baked:
        first = slots[material.name]
        n = values.shape[0]
        level0[first : first + n] = encoded.stored
        scales[first : first + n] = encoded.scale
        biases[first : first + n] = encoded.bias

    t0 = time.perf_counter()
    if layout == "array":
        # Each layer's chain is its own, and unused layers stay zero at every level of theirs:
        # filter and quantise only the used ones (a preview uses 2 of 256).
        used = sorted({s for m, _, v, _ in baked for s in range(slots[m.name], slots[m.name] + v.shape[0])})
        levels = []
        for fl in build_array_mips(level0[used]):
            lv = np.zeros((LAYERS, *fl.shape[1:]), np.uint8)
            lv[used] = quantize_rgba(fl, srgb)
            levels.append(lv)
    else:
        float_levels = build_volume_mips(level0)
        levels = [quantize_rgba(lv, srgb) for lv in float_levels]
    timings["mips_and_quantize_s"] = time.perf_counter() - t0

    warnings = list(cache_warnings)
    material_warnings: list[MaterialWarning] = []
    entries = []
    for material, slices, values, encoded in baked:
        first = slots[material.name]
        n = values.shape[0]
        dec = dequantize_rgba(levels[0][first : first + n], srgb)
        scale_c = np.concatenate([np.repeat(encoded.scale[:, :1], 3, 1), encoded.scale[:, 1:]], 1)[:, None, None, :]
        bias_c = np.concatenate([np.repeat(encoded.bias[:, :1], 3, 1), encoded.bias[:, 1:]], 1)[:, None, None, :]
        err = np.abs(dec * scale_c + bias_c - values)
        if encoded.clamped_fraction > 0:
            # A material warning, which --strict refuses: what was clamped is not in the atlas, as a value stored
            # as 0 ("lost to 8 bits") is not; among the bake's general warnings --strict let it through.
            material_warnings.append(MaterialWarning(
                material.source, material.name, "clamped to the scale", float(encoded.clamped_fraction),
                f"clamped {100 * encoded.clamped_fraction:.3f}% of texel channels to the slice scale "
                f"(rgb_scale={material.rgb_scale}, alpha_scale={material.alpha_scale})"))  # fmt: skip
        entry = MaterialEntry(
            name=material.name,
            id=first,
            constant=material.constant_name,
            first_slice=first,
            slice_count=n,
            type=material.type,
            source=material.source,
            content_hash=material.content_hash,
            description=material.description,
            params=_jsonable(material.params),
            scale=encoded.scale.tolist(),
            bias=encoded.bias.tolist(),
            flags=_jsonable(material.model.flags(material.params)),
            clamped_fraction=encoded.clamped_fraction,
            quantization_error=ErrorSummary(max=float(err.max()), rms=float(np.sqrt((err**2).mean()))),
            # The material's own look goal travels with its slices: validation reads the manifest, not the file.
            extra={} if material.look_goal is None else {"validate": dict(material.look_goal)},
        )
        # The model's own fields, merged in the order it produced them (a key naming a
        # common field, such as a finer quantization_error, replaces it), become the
        # entry's typed parts.
        model_fields = {}
        for extra in (slices.extra, encoded.extra, material.model.finalize(material.params, slices, encoded, dec)):
            model_fields.update(_jsonable(extra))
        material_warnings.extend(assess_material(material, model_fields))
        material_warnings.extend(assess_storage(material, values, levels[0][first : first + n], encoded))
        entries.append(entry.with_fields(model_fields, material.source))
    entries.sort(key=lambda e: e.first_slice)

    manifest = Manifest(
        format_version=FORMAT_VERSION,
        generator=f"atlasgen {__version__}",
        dimensions=Dimensions(width=WIDTH, height=HEIGHT, layers=LAYERS, mip_count=len(levels)),
        encoding="srgb" if srgb else "linear",
        dxgi_format=DXGI_FORMAT_R8G8B8A8_UNORM_SRGB if srgb else DXGI_FORMAT_R8G8B8A8_UNORM,
        layout=layout,
        mapping=dict(MAPPING),
        specular_lobe=dict(SPECULAR_LOBE),
        materials=entries,
    )
    if layout == "volume":
        bleed = _measure_volume_bleed(float_levels, [(slots[m.name], v.shape[0]) for m, _, v, _ in baked], scales)
        manifest.volume_bleed = bleed
        worst = max((b.max for b in bleed), default=0.0)
        warnings.append(
            f"volume layout: mip levels >= 1 blend neighbouring materials (worst measured bleed {worst:.3f} linear); "
            "sample level 0 only, or use --layout array"
        )

    includes = render_includes(manifest, scales, biases, models=get_model)
    include = includes.pop("wgsl")
    timings["cache"] = {"hits": cache_hits, "baked": baked_names}
    data = render_include_data(manifest, models=get_model)
    timings["total_s"] = time.perf_counter() - t_start
    return BakeResult(levels, layout, manifest.dxgi_format, manifest, include, timings, warnings, includes, data,
                      material_warnings, completions)  # fmt: skip


def encode_atlas_texture(result: BakeResult, path, manifest_bytes: bytes, zstd: bool = False) -> bytes:
    """The atlas texture in the container ``path``'s suffix names: DDS, or KTX2 (optionally Zstandard).

    The KTX2 key/value data names the writer and records the SHA-256 of the manifest
    written beside it (``atlasgen.manifest_sha256``). That is no circle: the manifest
    records the hash of the texels (:func:`atlasgen.io.atlas.texel_sha256`), not of the file.
    """
    path = Path(path)
    if path.suffix.lower() == ".ktx2":
        srgb = result.dxgi_format == DXGI_FORMAT_R8G8B8A8_UNORM_SRGB
        key_values = {"KTXwriter": f"atlasgen {__version__}", KTX2_MANIFEST_KEY: hashlib.sha256(manifest_bytes).hexdigest()}
        return encode_ktx2(result.levels, result.layout, srgb, key_values, zstd)
    if zstd:
        raise OutputError(f"{path.as_posix()}: Zstandard supercompression needs a .ktx2 atlas, not DDS")
    return encode_dds(result.levels, result.layout, result.dxgi_format)


def relative_source(source: str, manifest_dir) -> str:
    """A material file as the manifest stores it: relative to the manifest's folder, with
    forward slashes, so the manifest's bytes do not depend on the working directory (or
    leak an absolute path); :meth:`atlasgen.io.atlas.Atlas.source_path` resolves it back.

    Both folders are resolved first: a ``..`` is followed from a folder's real place, so a path
    through a symlinked folder would be wrong and would make the bytes depend on the route taken.
    The file's own name is kept, so a symlinked material file is named as the user named it."""
    return Path(os.path.relpath(real_folder_path(source), os.path.realpath(manifest_dir))).as_posix()


def pair_outputs(result: BakeResult, paths: dict, zstd: bool = False) -> tuple[bytes, Manifest, bytes]:
    """The texture, the manifest that records its hash (``atlas_sha256``, entries' ``source``
    relative to the manifest's folder) and that manifest's bytes, for the files ``paths`` names."""
    manifest_dir = paths["manifest"].parent
    # The files a material names (absolute in memory) as the manifest holds them: from its folder, as source is.
    materials = [replace(e, source=relative_source(e.source, manifest_dir), params=relative_files(e.params, manifest_dir))
                 for e in result.manifest.materials]  # fmt: skip
    manifest = replace(result.manifest, materials=materials, atlas_sha256=texel_sha256(result.levels))
    manifest_bytes = format_manifest(manifest).encode()
    return encode_atlas_texture(result, paths["dds"], manifest_bytes, zstd), manifest, manifest_bytes


def write_bake(
    result: BakeResult, dds_path, preview_path=None, zstd: bool = False, languages=("wgsl", "glsl", "hlsl"), extra_files=None
) -> dict:
    """Write the atlas (DDS or KTX2, by suffix), manifest, the include in each of ``languages``,
    the separable side-car, timings (and preview) all-or-nothing; return the paths written.

    The files are tied into one generation by hashes: the manifest records the texture's
    SHA-256, and every include and the side-car record the manifest's
    (:func:`atlasgen.io.atlas.read_atlas` and the renderer refuse a pair that does not
    match). ``result`` is left as it is (its manifest as baked: no texture hash, sources as
    given), so it can be written to other paths too.

    Every sibling this bake does not write is removed in the same commit: the other
    container (``X.ktx2`` for ``X.dds``, :func:`other_container_path`), the includes of
    languages not in ``languages``, and ``X.separable.bin`` when no material is separable.

    ``extra_files`` (``{path: bytes}``, e.g. a Make depfile) join the same commit, one rename
    of the set's ``current`` link (:func:`atlasgen.io.atomic.write_files_atomically`): a bake
    killed part-way leaves every file old, the atlas texture the Makefile's rules target
    included, so ``make`` bakes again.
    """
    paths = sibling_paths(dds_path)
    every_sibling = {**paths, "other_container": other_container_path(paths["dds"])}
    texts = {"include": result.include, "glsl": result.includes.get("glsl"), "hlsl": result.includes.get("hlsl")}
    for key, lang in (("include", "wgsl"), ("glsl", "glsl"), ("hlsl", "hlsl")):
        if lang not in languages or texts[key] is None:
            del paths[key]
    texture, _, manifest_bytes = pair_outputs(result, paths, zstd)
    manifest_sha256 = hashlib.sha256(manifest_bytes).digest()
    contents = {
        paths["dds"]: texture,
        paths["manifest"]: manifest_bytes,
        **{
            paths[key]: stamp_include(texts[key], manifest_sha256).encode() for key in ("include", "glsl", "hlsl") if key in paths
        },
        paths["timings"]: (json.dumps(result.timings, indent=2) + "\n").encode(),
    }
    if result.separable_data:
        contents[paths["separable"]] = stamp_sidecar(result.separable_data, manifest_sha256)
    else:
        del paths["separable"]
    if preview_path is not None:
        paths["preview"] = Path(preview_path)
        contents[paths["preview"]] = render_contact_sheet(result)
    for path, data in (extra_files or {}).items():
        contents[Path(path)] = data
    # The siblings this bake does not write are stale: the other container (it would share
    # this manifest and includes), includes in languages not asked for, an old side-car.
    stale = [path for path in every_sibling.values() if path not in contents]
    write_files_atomically(contents, primary=paths["dds"], remove=stale, writer=bake_writer(paths["dds"]))
    return paths


def bake_writer(dds_path) -> str:
    """The bake's writer in its output set (:func:`atlasgen.io.atomic.write_files_atomically`): one per atlas,
    whichever container it is written in, since a bake to ``X.ktx2`` replaces the one to ``X.dds``.

    >>> bake_writer("build/scenes/demo.dds")
    'bake -o demo.dds/.ktx2'
    """
    return f"bake -o {Path(dds_path).with_suffix('').name}.dds/.ktx2"
