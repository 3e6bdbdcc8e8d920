"""Reference renders kept by what decides them: for the run in memory, and across runs on disk.

A Mitsuba reference render is decided by the scene as shown (camera, lights, geometry, image
size), every object's BSDF and medium, the integrator, the sample count and the first sample, the
seeds (fixed: 0 and 1), the variant, the pinned Mitsuba version and the code that builds and
renders the reference. :func:`render_key` is the SHA-256 of all of it, as canonical JSON (sorted
keys, no ``pickle``, so the key is the same in every process). A stochastic reference grows by
whole passes that continue the last (``first_sample``): each pass is one entry, so a second run
of the same validation replays the convergence from the cache and renders nothing, and a run
whose error asks for more samples reuses every pass it shares with an earlier one.

On disk an entry is ``<folder>/<key>.npz`` (images, masks and a JSON record), written atomically;
the default folder is ``build/cache/references/`` (``atlasgen validate --reference-cache``). The record
holds the SHA-256 of every array (dtype, shape and bytes). An entry that cannot be read, or whose
contents are not a render of the size asked for (an image not float32 ``(h, w, 3)`` or not finite, a
mask not bool ``(h, w)``, a record of other fields or types, an array that does not hash to its
record's digest) is as good as absent: the reference renders again and replaces it, and
:attr:`ReferenceCache.rejected` says which entry and why (``atlasgen validate`` warns).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import json
import math
from pathlib import Path

import numpy as np

from atlasgen.bake.cache import tool_fingerprint
from atlasgen.errors import describe_failure
from atlasgen.io.atomic import write_file_atomically
from atlasgen.io.digest import array_digest
from atlasgen.io.npz import read_npz_arrays

__all__ = [
    "ReferenceCache",
    "render_key",
    "reference_code_fingerprint",
    "REFERENCE_CODE",
    "DEFAULT_REFERENCE_CACHE",
]

#: Where ``atlasgen validate`` keeps reference renders unless told otherwise.
DEFAULT_REFERENCE_CACHE = Path("build/cache/references")
_PACKAGE = Path(__file__).resolve().parents[1]
#: Code above the bake's layers that decides a reference image: the Mitsuba scene, its renders and the
#: references' assembly (the models, their plugins and the optics are in the bake's fingerprint).
REFERENCE_CODE = ("validate/mitsuba_scene.py", "validate/references.py", "validate/backend.py", "validate/run.py",
                  "validate/scenes.py", "validate/reference_cache.py", "render/meshes.py", "render/environment.py")  # fmt: skip
#: Arrays of a render, each stored where present.
_ARRAYS = ("image", "second_image", "mask")
#: The record's fields of a render (:func:`atlasgen.validate.run._render_fields`) and what each must be.
_RECORD = {"kind": (str,), "description": (str,), "seconds": (int, float), "spp": (int,), "variant": (str,),
           "masked": (str, type(None))}  # fmt: skip


@functools.cache
def reference_code_fingerprint() -> str:
    """SHA-256 over the bake's code fingerprint (:func:`atlasgen.bake.cache.tool_fingerprint`: models,
    plugins, optics, materials) and :data:`REFERENCE_CODE`."""
    digest = hashlib.sha256(tool_fingerprint().encode())
    for rel in REFERENCE_CODE:
        digest.update(rel.encode())
        digest.update((_PACKAGE / rel).read_bytes())
    return digest.hexdigest()


def _canonical(value):
    """A JSON value for what :func:`json.dumps` cannot write itself."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {"__type__": type(value).__name__, **{f.name: getattr(value, f.name) for f in dataclasses.fields(value)}}
    if isinstance(value, np.ndarray):
        return {"__array__": str(value.dtype), "shape": list(value.shape), "values": value.tolist()}
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (set, frozenset)):
        return sorted(value, key=repr)
    if isinstance(value, Path):
        return value.as_posix()
    raise TypeError(f"cannot key a {type(value).__name__}")


def render_key(mitsuba_version, *decides) -> str | None:
    """SHA-256 of the Mitsuba version, the reference code (:func:`reference_code_fingerprint`) and
    ``decides``, as canonical JSON; ``None`` when some part has no canonical form (then nothing is kept).

    >>> render_key("3.9.1", {"b": 1, "a": [1.0, 2]}) == render_key("3.9.1", {"a": [1.0, 2], "b": 1})
    True
    >>> render_key("3.9.1", 1) == render_key("3.9.2", 1)
    False
    """
    try:
        blob = json.dumps([mitsuba_version, reference_code_fingerprint(), decides], sort_keys=True, default=_canonical,
                          allow_nan=True)  # fmt: skip
    except (TypeError, ValueError):
        return None
    return hashlib.sha256(blob.encode()).hexdigest()


class ReferenceCache:
    """Reference renders by :func:`render_key`: a dict for the run, backed by ``folder`` when one is given.

    Values are dicts of a render's fields (``image``, ``second_image``, ``mask``: arrays or None; the
    rest JSON); :meth:`get` returns a copy, so the caller may grow and measure it. ``hits``,
    ``loaded`` (hits read from disk) and ``stored`` count what happened, for the report; ``rejected``
    lists the entries on disk that were there but not used (``"<path>: <why>; rendered again"``).
    """

    def __init__(self, folder=None):
        self.folder = None if folder is None else Path(folder)
        self._memory: dict[str, dict] = {}
        self.hits = self.loaded = self.stored = 0
        self.rejected: list[str] = []

    def _path(self, key: str) -> Path:
        assert self.folder is not None
        return self.folder / f"{key}.npz"

    def get(self, key: str | None, size: tuple[int, int] | None = None) -> dict | None:
        """The render kept under ``key`` (a copy), or None. ``size`` = ``(height, width)``: the frame the render
        must have (an entry on disk of another size, or whose contents do not check out, is a miss)."""
        if key is None:
            return None
        fields = self._memory.get(key)
        if fields is None and self.folder is not None:
            fields = self._load(key, size)
            if fields is not None:
                self._memory[key] = fields
                self.loaded += 1
        if fields is None:
            return None
        self.hits += 1
        return _copy(fields)

    def put(self, key: str | None, fields: dict) -> None:
        if key is None:
            return
        self._memory[key] = _copy(fields)
        if self.folder is None:
            return
        arrays = {k: np.asarray(fields[k]) for k in _ARRAYS if fields.get(k) is not None}
        record = {k: v for k, v in fields.items() if k not in _ARRAYS}
        digests = {k: array_digest(a) for k, a in arrays.items()}
        buffer = io.BytesIO()
        np.savez(buffer, record=np.array(json.dumps({"key": key, "digests": digests, **record})), **arrays)
        write_file_atomically(self._path(key), buffer.getvalue())
        self.stored += 1

    def _load(self, key: str, size=None) -> dict | None:
        path = self._path(key)
        if not path.is_file():
            return None
        try:
            # Read within what a render of its size holds: a 0.78 MB compressed entry inflated to 805 MB in np.load,
            # before its shape was checked.
            data = read_npz_arrays(path, _entry_bytes(size))
            record = json.loads(str(data["record"]))
            if not isinstance(record, dict) or record.pop("key", None) != key:
                return self._reject(path, "its record is not this entry's (another key)")
            arrays = {k: data.get(k) for k in _ARRAYS}
            why = _entry_problem(record, arrays, size)
        except Exception as exc:  # noqa: BLE001 - a damaged entry (zipfile, numpy, json errors) is as good as absent
            return self._reject(path, f"unreadable ({describe_failure(exc)})")
        if why is not None:
            return self._reject(path, why)
        record.pop("digests")
        return {**record, **arrays}

    def _reject(self, path: Path, why: str) -> None:
        self.rejected.append(f"{path.as_posix()}: {why}; rendered again")
        return None


#: Bytes of an entry's record: a description and a few numbers.
_RECORD_BYTES = 1 << 20


def _entry_bytes(size=None) -> int:
    """The most bytes an entry's arrays may inflate to: its images at ``size`` = ``(height, width)``, or a 4096 x 4096
    render's where the size is not known."""
    height, width = (4096, 4096) if size is None else (int(size[0]), int(size[1]))
    return _RECORD_BYTES + len(_ARRAYS) * height * width * 3 * 4


def _entry_problem(record: dict, arrays: dict, size=None) -> str | None:
    """What is wrong with a cache entry read from disk (its JSON ``record`` without the key, its ``arrays``),
    for a render of ``size`` = ``(height, width)`` where given; None where it is a render as stored."""
    digests = record.get("digests")
    if not isinstance(digests, dict):
        return "its record has no digests of its images (an entry of another atlasgen)"
    fields = {k: v for k, v in record.items() if k != "digests"}
    if set(fields) != set(_RECORD):
        return f"its record has fields {sorted(fields)}; expected {sorted(_RECORD)}"
    for name, kinds in _RECORD.items():
        value = fields[name]
        if not isinstance(value, kinds) or isinstance(value, bool):
            return f"its record's {name!r} is {type(value).__name__}; expected {' or '.join(k.__name__ for k in kinds)}"
    # An integer beyond a double (10**400, valid JSON) is no render's time either: math.isfinite raised on it.
    seconds_ok = not isinstance(fields["seconds"], int) or abs(fields["seconds"]) <= 1e300
    if fields["spp"] < 1 or not (seconds_ok and math.isfinite(fields["seconds"]) and fields["seconds"] >= 0):
        return "its record's sample count or seconds are not a render's"
    image = arrays["image"]
    if image is None:
        return "no image"
    frame = image.shape[:2] if size is None else tuple(int(x) for x in size)
    for name, array in arrays.items():
        if array is None:
            continue
        is_mask = name == "mask"
        shape, dtype = (frame, np.dtype(bool)) if is_mask else ((*frame, 3), np.dtype(np.float32))
        if array.shape != shape or array.dtype != dtype:
            return f"{name} is {array.dtype} {'x'.join(map(str, array.shape))}; expected {dtype} {'x'.join(map(str, shape))}"
        if not is_mask and not np.isfinite(array).all():
            return f"{name} has {int(np.count_nonzero(~np.isfinite(array)))} values that are not finite"
        if digests.get(name) != array_digest(array):
            return f"{name} does not match its record's digest (changed since it was stored)"
    if set(digests) != {k for k, a in arrays.items() if a is not None}:
        return "its arrays are not the ones its record's digests name"
    return None


def _copy(fields: dict) -> dict:
    return {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in fields.items()}
