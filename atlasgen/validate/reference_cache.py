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
the default folder is ``build/cache/references/`` (``atlasgen validate --reference-cache``). An
entry that cannot be read is as good as absent: the reference renders again and replaces it.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import json
from pathlib import Path

import numpy as np

from atlasgen.bake.cache import tool_fingerprint
from atlasgen.io.atomic import write_file_atomically

__all__ = ["ReferenceCache", "render_key", "reference_code_fingerprint", "REFERENCE_CODE", "DEFAULT_REFERENCE_CACHE"]

#: Where ``atlasgen validate`` keeps reference renders unless told otherwise.
DEFAULT_REFERENCE_CACHE = Path("build/cache/references")
_PACKAGE = Path(__file__).resolve().parents[1]
#: Code above the bake's layers that decides a reference image: the Mitsuba scene, its renders and the
#: references' assembly (the models, their plugins and the optics are in the bake's fingerprint).
REFERENCE_CODE = ("validate/mitsuba_scene.py", "validate/references.py", "validate/backend.py", "validate/run.py",
                  "validate/scenes.py", "validate/reference_cache.py", "render/meshes.py", "render/environment.py")  # fmt: skip
#: Arrays of a render, each stored where present.
_ARRAYS = ("image", "second_image", "mask")


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
    ``loaded`` (hits read from disk) and ``stored`` count what happened, for the report.
    """

    def __init__(self, folder=None):
        self.folder = None if folder is None else Path(folder)
        self._memory: dict[str, dict] = {}
        self.hits = self.loaded = self.stored = 0

    def _path(self, key: str) -> Path:
        assert self.folder is not None
        return self.folder / f"{key}.npz"

    def get(self, key: str | None) -> dict | None:
        if key is None:
            return None
        fields = self._memory.get(key)
        if fields is None and self.folder is not None:
            fields = self._load(key)
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
        buffer = io.BytesIO()
        np.savez(buffer, record=np.array(json.dumps({"key": key, **record})), **arrays)
        write_file_atomically(self._path(key), buffer.getvalue())
        self.stored += 1

    def _load(self, key: str) -> dict | None:
        path = self._path(key)
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as data:
                record = json.loads(str(data["record"]))
                if not isinstance(record, dict) or record.pop("key", None) != key:
                    return None
                arrays = {k: (np.array(data[k]) if k in data.files else None) for k in _ARRAYS}
        except Exception:  # noqa: BLE001 - a damaged entry (zipfile, numpy, json errors) is as good as absent
            return None
        if arrays["image"] is None:
            return None
        return {**record, **arrays}


def _copy(fields: dict) -> dict:
    return {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in fields.items()}
