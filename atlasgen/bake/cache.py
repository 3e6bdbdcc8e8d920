"""Per-material bake cache, keyed by the material file's hash and the bake-relevant tool code."""

from __future__ import annotations

import functools
import hashlib
import io
import json
import math
import time
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from atlasgen import __version__
from atlasgen.bake.adaptive import bake_material, draft_material
from atlasgen.contract import HEIGHT, LAYERS, WIDTH
from atlasgen.errors import describe_failure
from atlasgen.io.atomic import write_file_atomically
from atlasgen.io.digest import update_with_array
from atlasgen.io.fields import FLOAT32_MAX, is_number
from atlasgen.io.npz import read_npy_header
from atlasgen.models.base import SliceSet

__all__ = [
    "bake_relevant_files",
    "tool_fingerprint",
    "cache_key",
    "cache_path",
    "load_cached",
    "store_cached",
    "load_or_bake",
    "load_or_draft",
    "load_timed",
    "bake_timed",
    "BAKE_RELEVANT",
]

_PACKAGE = Path(__file__).resolve().parents[1]
#: Code whose change can change a material's float slices: every layer below ``bake/`` (the
#: top-level modules, optics, io, separable, shaders, models, materials), and the supersampling that
#: meets an error budget. The rest of ``bake/`` (encoding, mips, file writing) runs at assembly
#: time on every bake, so it is not part of the key. The Makefile's BAKE_CODE is the same list.
BAKE_RELEVANT = ("*.py", "optics", "io", "separable", "shaders", "models", "materials", "bake/adaptive.py")


def bake_relevant_files() -> list[Path]:
    """The source files :func:`tool_fingerprint` hashes (the Makefile's BAKE_CODE lists the same)."""
    out = []
    for entry in BAKE_RELEVANT:
        path = _PACKAGE / entry
        if path.is_dir():
            out += sorted(path.rglob("*.py"))
        else:
            out += sorted(_PACKAGE.glob(entry))
    return out


@functools.cache
def tool_fingerprint() -> str:
    """SHA-256 over the atlasgen version and the bake-relevant source files."""
    digest = hashlib.sha256(__version__.encode())
    for f in bake_relevant_files():
        digest.update(f.relative_to(_PACKAGE).as_posix().encode())
        digest.update(f.read_bytes())
    return digest.hexdigest()


#: The entry's layout: part of the key, so entries an older layout wrote are stale rather than damaged.
#: 2: the metadata holds a digest of the entry (:func:`_entry_digest`).
CACHE_FORMAT = 2


def cache_key(material) -> str:
    return hashlib.sha256(f"{material.content_hash}:{tool_fingerprint()}:{CACHE_FORMAT}".encode()).hexdigest()


def _entry_digest(values: np.ndarray, meta: dict) -> str:
    """SHA-256 of the slices (float64, C order) and the metadata but its digest: a hand-edited or damaged
    entry whose zip and arrays still read (an ``extra`` of another model, 5 slices for a 1-slice lambert)
    would otherwise reach the manifest as the bake's, and be blamed on the material file."""
    digest = hashlib.sha256(json.dumps({k: v for k, v in meta.items() if k != "digest"}, sort_keys=True).encode())
    update_with_array(digest, np.asarray(values, dtype=np.float64))
    return digest.hexdigest()


def cache_path(cache_dir, material) -> Path:
    """``<cache_dir>/<source file stem>.npz``: one file per material file, so Make can name it; a
    MaterialX document's materials one each, ``<document stem>.mtlx/<material name>.npz``. In a folder of
    the document's: ``<stem>.<material>.npz`` was also the entry of a TOML file ``<stem>.<material>.toml``
    (``lib.gold.toml`` beside ``lib.mtlx``'s ``gold``), and the two re-baked each other on every bake."""
    stem = Path(material.source).stem
    if material.source.lower().endswith(".mtlx"):
        return Path(cache_dir) / f"{stem}.mtlx" / f"{material.name}.npz"
    return Path(cache_dir) / f"{stem}.npz"


#: Bytes an entry's metadata may inflate to; a bake writes a few kB.
_MAX_META_BYTES = 16 << 20


def _check_shape(shape, dtype) -> None:
    """Raise ValueError unless ``shape`` and ``dtype`` are a model's slices: (n, H, W, 4) floats, n <= LAYERS."""
    if dtype.kind != "f" or len(shape) != 4 or not 1 <= shape[0] <= LAYERS or tuple(shape[1:]) != (HEIGHT, WIDTH, 4):
        raise ValueError(f"slices of shape {tuple(shape)} {dtype}")


def _check_archive(path: Path) -> None:
    """Raise ValueError for an archive whose members would inflate beyond what a bake writes, read from its
    headers alone: a 2.5 MB entry declaring 40000 slices took 2.6 GB of memory to load."""
    with zipfile.ZipFile(path) as archive:
        meta = archive.getinfo("meta.npy")
        if meta.file_size > _MAX_META_BYTES:
            raise ValueError(f"metadata of {meta.file_size} bytes")
        with archive.open("values.npy") as member:
            shape, _, dtype = read_npy_header(member)
    _check_shape(shape, dtype)


def _all_finite(value, depth: int = 0) -> bool:
    """Whether every number in the JSON ``value`` is finite (depth-bounded: metadata nests a few levels)."""
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, (list, dict)):
        items = value.values() if isinstance(value, dict) else value
        return depth < 64 and all(_all_finite(v, depth + 1) for v in items)
    return True


def _check_entry(values: np.ndarray, meta, most_slices: int) -> None:
    """Raise ValueError unless the stored slices look like the material's model's: (n, H, W, 4) with n at most
    ``most_slices`` (what the model bakes), finite in float32 (a bake refuses a material whose slices are
    not, so no bake wrote them), with finite timings and a fit record that is a record, and the entry is the
    one the bake stored (its digest). The digest finds damage, not an entry forged with a digest of its own:
    so what the bake reads of the metadata before the manifest's typed reading checks the rest is checked here."""
    if not isinstance(meta, dict) or not isinstance(meta.get("extra"), dict) or not isinstance(meta.get("timings"), dict):
        raise ValueError("malformed metadata")
    if not all(is_number(t) and math.isfinite(t) and t >= 0 for t in meta["timings"].values()):
        raise ValueError("timings that are not seconds")
    fit = meta["extra"].get("fit")
    if fit is not None and not isinstance(fit, dict):
        raise ValueError("a fit record that is not an object")
    # The bake judges a material by these errors before the manifest is read back (a string was an internal error),
    # and the manifest cannot hold a NaN (one was written into it, which every reader then refused).
    for record in (fit or {}, meta["extra"].get("errors_8bit") or {}):
        if "relative_rms" in record and not (is_number(record["relative_rms"]) and record["relative_rms"] >= 0):
            raise ValueError(f"an error of {record['relative_rms']!r}")
    if not _all_finite(meta["extra"]):
        raise ValueError("metadata holding NaN or infinity")
    _check_shape(values.shape, values.dtype)
    if values.shape[0] > most_slices:
        raise ValueError(f"{values.shape[0]} slices where the model bakes at most {most_slices}")
    if not (np.abs(values) <= FLOAT32_MAX).all():  # NaN compares False
        raise ValueError("slices not finite in float32")
    if meta.get("digest") != _entry_digest(values, meta):
        raise ValueError("contents differ from what the bake stored")


def load_cached(cache_dir, material, warnings=None) -> SliceSet | None:
    """The cached slices of ``material`` (its ``name``, ``source``, ``content_hash``, ``slice_count``, the
    most slices its model bakes, and ``model``, which checks what it recorded beside them: :meth:`~atlasgen.models.base.
    Model.check_cached`), or None when absent, stale or unreadable.

    An entry that cannot be read (truncated, overwritten, not an ``.npz``, slices of the
    wrong shape) is as good as absent: the material is baked again and the entry
    replaced. That case, unlike an absent or stale entry, appends a line to ``warnings``.
    """
    path = cache_path(cache_dir, material)
    if not path.is_file():
        return None
    try:
        _check_archive(path)
        loaded = np.load(path, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):
            raise ValueError("not an .npz archive")
        with loaded as data:
            meta = json.loads(str(data["meta"]))
            if isinstance(meta, dict) and meta.get("key") != cache_key(material):
                return None
            values = np.array(data["values"])
        _check_entry(values, meta, material.slice_count)
        material.model.check_cached(meta["extra"])
    except Exception as exc:  # noqa: BLE001 - zipfile, numpy and json raise many types for a damaged file
        if warnings is not None:
            warnings.append(f"{path.as_posix()}: unreadable cache entry ({describe_failure(exc)}); "
                            f"baking material {material.name!r} again")  # fmt: skip
        return None
    return SliceSet(values, extra=meta["extra"], timings=meta["timings"])


def store_cached(cache_dir, material, slices: SliceSet, bake_seconds: float) -> Path:
    """Write the slices atomically (parallel ``make -j`` jobs each write their own file).

    ``bake_seconds`` is what the bake cost when it ran, so reports built from the cache
    still show the real bake time, not the time to load it.
    """
    timings = {**slices.timings, "bake_s": bake_seconds}
    meta = {"key": cache_key(material), "name": material.name, "extra": slices.extra, "timings": timings}
    values = np.asarray(slices.values, dtype=np.float64)
    meta["digest"] = _entry_digest(values, meta)
    buffer = io.BytesIO()
    np.savez(buffer, values=values, meta=np.array(json.dumps(meta)))
    path = cache_path(cache_dir, material)
    write_file_atomically(path, buffer.getvalue())
    return path


def load_timed(cache_dir, material, warnings=None) -> SliceSet | None:
    """:func:`load_cached` with the time it took in ``timings["loaded_from_cache_s"]``; None without a ``cache_dir``."""
    t0 = time.perf_counter()
    slices = load_cached(cache_dir, material, warnings) if cache_dir is not None else None
    if slices is not None:
        slices.timings["loaded_from_cache_s"] = time.perf_counter() - t0
    return slices


def bake_timed(material) -> SliceSet:
    """:func:`~atlasgen.bake.adaptive.bake_material` with its wall time in ``timings["bake_s"]``."""
    t0 = time.perf_counter()
    slices = bake_material(material)
    slices.timings["bake_s"] = time.perf_counter() - t0
    return slices


def load_or_bake(cache_dir, material, warnings=None) -> tuple[SliceSet, bool]:
    """The material's slices and whether they came from the cache.

    A missing, stale or unreadable entry is baked (``timings["bake_s"]`` set) and, with a
    ``cache_dir``, stored; ``cache_dir = None`` always bakes. An unreadable entry adds a
    line to ``warnings`` (:func:`load_cached`).
    """
    slices = load_timed(cache_dir, material, warnings)
    if slices is not None:
        return slices, True
    slices = bake_timed(material)
    if cache_dir is not None:
        store_cached(cache_dir, material, slices, slices.timings["bake_s"])
    return slices, False


def load_or_draft(cache_dir, material, warnings=None) -> tuple[SliceSet, bool, Callable[[], SliceSet] | None]:
    """:func:`load_or_bake`, except that a material the cache lacks whose model drafts
    (:func:`~atlasgen.bake.adaptive.draft_material`) comes back as its draft with the completion:
    ``(slices, hit, complete)``; ``complete()`` returns the full slices, and with a ``cache_dir`` stores
    them (``bake_s`` the draft's time plus its own). The draft is never stored. ``complete`` is None
    for a hit and for a material baked whole."""
    t0 = time.perf_counter()
    slices = load_cached(cache_dir, material, warnings) if cache_dir is not None else None
    if slices is not None:
        slices.timings["loaded_from_cache_s"] = time.perf_counter() - t0
        return slices, True, None
    draft = draft_material(material)
    if draft is None:
        slices, _ = load_or_bake(None, material)
        if cache_dir is not None:
            store_cached(cache_dir, material, slices, slices.timings["bake_s"])
        return slices, False, None
    drafted = time.perf_counter() - t0
    draft.slices.timings["bake_s"] = drafted

    def complete() -> SliceSet:
        t1 = time.perf_counter()
        full = draft.complete()
        full.timings["bake_s"] = drafted + time.perf_counter() - t1
        if cache_dir is not None:
            store_cached(cache_dir, material, full, full.timings["bake_s"])
        return full

    return draft.slices, False, complete
