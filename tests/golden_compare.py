"""Comparing a bake with its golden files: byte-exact where the bytes are NumPy's, within a stated
tolerance where they passed through Mitsuba's JIT.

Dr.Jit compiles Mitsuba's BSDF evaluations with LLVM for the host CPU, so another Mitsuba, Dr.Jit
or LLVM build, or another instruction set, may round a value differently. A value on an 8-bit
rounding boundary then moves by one code, and the figures measured from it move in their last
digits. The goldens record what they were generated with (``VERSIONS.json``); under those
versions the whole output is compared byte for byte, and elsewhere the JIT's part is compared
within :data:`CODE_TOLERANCE` codes and :data:`RELATIVE_TOLERANCE`, its figures within their
standard errors.

Every texel NumPy computes is byte-exact everywhere. NumPy's float *figures* (an RMS, a fit's
error) are not quite: NumPy picks its SIMD kernels for the CPU at run time (AVX-512 where the CPU
has it, else AVX2), and a reduction over another vector width sums in another order, so a figure
may move in its last digits (seen: 0.00029971184300223993 on AVX2, ...2399 on AVX-512; up to
3e-12 relative for an RMS with cancellation).
Those figures are compared within :data:`NUMPY_RELATIVE_TOLERANCE`, eight orders of magnitude
below any real change. The digests that follow such figures (the manifest's SHA-256 on each
include's first line, in the side-car) are checked against the produced files (:func:`check_links`).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
import struct
from pathlib import Path

import numpy as np

from atlasgen.io.atlas import INCLUDE_HASH_PREFIX
from tests import dds_reader

#: Largest difference, in 8-bit codes, of a texel whose slice went through the JIT.
CODE_TOLERANCE = 1
#: Largest relative difference of a JIT-derived float (a slice's scale, a fit's error): rounding
#: moves them by ~1e-7; a real change of a slice (twice as bright) moves them by far more.
RELATIVE_TOLERANCE = 1e-4
#: Smallest absolute difference a JIT-derived float may have: a slice's float32 texels moved by
#: rounding move its quantization error (~1e-4..1e-3) by ~1e-7.
JIT_ABSOLUTE_TOLERANCE = 5e-7
#: Largest relative difference of a float figure NumPy computes from byte-exact inputs: another
#: SIMD width's summation order (see the module's text).
NUMPY_RELATIVE_TOLERANCE = 1e-9
#: A figure with a standard error (``<name>_se`` beside it) may move by this many SEs.
SE_MULTIPLE = 3.0

#: What decides the JIT's rounding: the Python packages and the LLVM it runs on, and the CPU's
#: vector instruction sets LLVM compiles for.
_CPU_FLAGS = ("avx512f", "avx2", "fma", "sse4_2")
_PACKAGES = ("mitsuba", "drjit", "numpy", "scipy")


def jit_environment() -> dict:
    """The versions and CPU features the JIT's bytes depend on, as recorded in ``VERSIONS.json``."""
    from importlib.metadata import PackageNotFoundError, version

    packages = {}
    for name in _PACKAGES:
        try:
            packages[name] = version(name)
        except PackageNotFoundError:
            packages[name] = None
    try:
        flags = set(re.search(r"^flags\s*:(.*)$", Path("/proc/cpuinfo").read_text(), re.M).group(1).split())
    except (OSError, AttributeError):
        flags = set()
    return {"packages": packages, "libllvm": _libllvm_version(), "cpu": sorted(f for f in _CPU_FLAGS if f in flags)}


def _libllvm_version() -> str | None:
    import subprocess

    try:
        out = subprocess.run(["dpkg-query", "-W", "-f", "${Version}", "libllvm19"], capture_output=True, text=True)
    except OSError:
        return None
    return out.stdout.strip() or None


def describe(environment: dict) -> str:
    packages = ", ".join(f"{k} {v}" for k, v in sorted(environment["packages"].items()))
    return f"{packages}, libllvm19 {environment['libllvm']}, CPU {'+'.join(environment['cpu']) or 'baseline'}"


# ---- DDS -------------------------------------------------------------------------------------


def jit_slices(manifest: dict, jit_materials) -> set[int]:
    """Level-0 slice indices of the materials whose slices went through the JIT."""
    out = set()
    for entry in manifest["materials"]:
        if entry["name"] in jit_materials:
            out.update(range(entry["first_slice"], entry["first_slice"] + entry["slice_count"]))
    return out


def compare_dds(produced: bytes, expected: bytes, tolerant_slices: set[int]) -> list[str]:
    """Differences between two DDS atlases, one line each: headers must match exactly, texels of
    ``tolerant_slices`` (and of the mips built from them) within :data:`CODE_TOLERANCE`, the rest exactly."""
    mine, ref = dds_reader.parse(produced), dds_reader.parse(expected)
    problems = []
    for part in ("header", "dx10"):
        if mine[part] != ref[part]:
            problems.append(f"the {part} differs: {mine[part]} != {ref[part]}")
    if problems or len(mine["levels"]) != len(ref["levels"]) or mine["size"] != ref["size"]:
        return problems or ["the level chain differs"]
    volume = ref["dx10"]["resourceDimension"] == 4
    for k, (a, b) in enumerate(zip(mine["levels"], ref["levels"])):
        diff = np.abs(a.astype(np.int16) - b.astype(np.int16)).reshape(a.shape[0], -1).max(axis=1)
        for j in np.flatnonzero(diff):
            # A volume's level k blends 2^k neighbouring level-0 slices along depth.
            covered = range(j << k, (j + 1) << k) if volume else (j,)
            limit = CODE_TOLERANCE if tolerant_slices.intersection(covered) else 0
            if diff[j] > limit:
                problems.append(f"level {k} slice {j}: texels differ by up to {diff[j]} codes (allowed {limit})")
    return problems


# ---- numbers in text and JSON ------------------------------------------------------------------

_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def _close(a: float, b: float, rel: float, absolute: float = 0.0) -> bool:
    return a == b or abs(a - b) <= max(rel * max(abs(a), abs(b)), absolute)


def _without_stamp(text: str) -> str:
    """An include without its first line, the manifest's digest (checked by :func:`check_links`)."""
    return text.split("\n", 1)[1] if text.startswith(INCLUDE_HASH_PREFIX) else text


def compare_text(produced: str, expected: str, rel: float = RELATIVE_TOLERANCE) -> list[str]:
    """The text between numbers must match exactly; each number within ``rel`` of the golden's.
    An include's first line, the manifest's digest, is left to :func:`check_links`."""
    produced, expected = _without_stamp(produced), _without_stamp(expected)
    a_parts, b_parts = _NUMBER.split(produced), _NUMBER.split(expected)
    if a_parts != b_parts:
        pairs = itertools.zip_longest(produced.splitlines(), expected.splitlines(), fillvalue="")
        line = next((i for i, (x, y) in enumerate(pairs) if _NUMBER.split(x) != _NUMBER.split(y)), 0)
        return [f"line {line + 1} differs in more than its numbers"]
    problems = []
    for x, y in zip(_NUMBER.findall(produced), _NUMBER.findall(expected)):
        if not _close(float(x), float(y), rel):
            problems.append(f"{x} != {y} (allowed relative {rel:g})")
    return problems


#: Fields that are digests of other outputs: they follow those outputs' bytes, and are checked
#: against the produced files themselves (:func:`check_links`).
DIGEST_FIELDS = {"atlas_sha256"}


def compare_manifest(produced: dict, expected: dict, jit_materials) -> list[str]:
    """Field by field: exact, except the numbers of JIT entries (within their SE where one is
    recorded beside them, else within :data:`RELATIVE_TOLERANCE`) and the digests."""
    problems: list[str] = []
    top_a = {k: v for k, v in produced.items() if k not in DIGEST_FIELDS and k != "materials"}
    top_b = {k: v for k, v in expected.items() if k not in DIGEST_FIELDS and k != "materials"}
    # The top level's figures span every slice (a volume's bleed between neighbours), the JIT's too.
    _compare(top_a, top_b, "", bool(jit_materials), problems)
    names_a = [e["name"] for e in produced["materials"]]
    names_b = [e["name"] for e in expected["materials"]]
    if names_a != names_b:
        return problems + [f"materials {names_a} != {names_b}"]
    for a, b in zip(produced["materials"], expected["materials"]):
        _compare(a, b, a["name"], a["name"] in jit_materials, problems)
    return problems


def _compare(a, b, where: str, tolerant: bool, problems: list[str], se=None) -> None:
    """Append to ``problems`` where ``a`` differs from ``b``; ``se`` is the standard error recorded
    beside a figure (a list of them beside a list of figures), which widens a tolerant comparison."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            problems.append(f"{where}: keys {sorted(a)} != {sorted(b)}")
            return
        for k in a:
            _compare(a[k], b[k], f"{where}.{k}", tolerant, problems, _recorded_se(a, k))
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            problems.append(f"{where}: {len(a)} items != {len(b)}")
            return
        for i, (x, y) in enumerate(zip(a, b)):
            item_se = se[i] if isinstance(se, list) and i < len(se) else None
            _compare(x, y, f"{where}[{i}]", tolerant, problems, item_se)
    elif tolerant and isinstance(a, float | int) and isinstance(b, float | int) and not isinstance(a, bool):
        allowed = SE_MULTIPLE * math.sqrt(2) * se if isinstance(se, float | int) and se else 0.0
        if not _close(float(a), float(b), RELATIVE_TOLERANCE, max(allowed, JIT_ABSOLUTE_TOLERANCE)):
            problems.append(
                f"{where}: {a} != {b} (allowed relative {RELATIVE_TOLERANCE:g}"
                + (f" or {allowed:.3g}, {SE_MULTIPLE:g} SE)" if allowed else f" or {JIT_ABSOLUTE_TOLERANCE:g})")
            )
    elif isinstance(a, float) and isinstance(b, float) and a != b:
        if not _close(a, b, NUMPY_RELATIVE_TOLERANCE):
            problems.append(f"{where}: {a!r} != {b!r} (allowed relative {NUMPY_RELATIVE_TOLERANCE:g})")
    elif a != b:
        problems.append(f"{where}: {a!r} != {b!r}")


def _recorded_se(record: dict, key: str):
    """The standard error a record gives beside its field ``key``: ``key_se``, or ``x_se_by_terms``
    beside ``x_by_terms`` (a list beside a list); ``None`` where it gives none."""
    names = [f"{key}_se"] + ([key.replace("_by_terms", "_se_by_terms")] if key.endswith("_by_terms") else [])
    return next((record[n] for n in names if n in record), None)


# ---- the side-car ------------------------------------------------------------------------------


def compare_sidecar(produced: bytes, expected: bytes) -> list[str]:
    """The header's counts exactly (its manifest digest is checked by :func:`check_links`); the
    float32 rows within :data:`RELATIVE_TOLERANCE` (separable-gold's factors are the JIT's)."""
    if produced[:16] != expected[:16] or len(produced) != len(expected):
        return ["the side-car's header or length differs"]
    a = np.frombuffer(produced, "<f4", offset=48).astype(np.float64)
    b = np.frombuffer(expected, "<f4", offset=48).astype(np.float64)
    bad = np.flatnonzero(~((a == b) | (np.abs(a - b) <= RELATIVE_TOLERANCE * np.maximum(np.abs(a), np.abs(b)) + 1e-7)))
    return [f"{bad.size} side-car floats differ (first at row float {bad[0]}: {a[bad[0]]} != {b[bad[0]]})"] if bad.size else []


def check_links(outputs: dict[str, bytes]) -> list[str]:
    """The digests that tie a set together, recomputed from the produced files."""
    manifest = json.loads(outputs[".json"])
    problems = []
    # docs/atlas-format.md: the SHA-256 of every level's RGBA8 texels, level 0 first, C order.
    texels = hashlib.sha256()
    for level in dds_reader.parse(outputs[".dds"])["levels"]:
        texels.update(np.ascontiguousarray(level).tobytes())
    if manifest["atlas_sha256"] != texels.hexdigest():
        problems.append("the manifest's atlas_sha256 is not the produced atlas's texels'")
    digest = hashlib.sha256(outputs[".json"]).hexdigest()
    for suffix in (".wgsl", ".glsl", ".hlsl"):
        if suffix in outputs and not outputs[suffix].decode().startswith(f"{INCLUDE_HASH_PREFIX}{digest}\n"):
            problems.append(f"the {suffix} include does not record the produced manifest's SHA-256 on its first line")
    sidecar = outputs.get(".separable.bin")
    if sidecar is not None:
        _version, _rows, length = struct.unpack_from("<3I", sidecar, 4)
        if sidecar[16 : 16 + length] != hashlib.sha256(outputs[".json"]).digest():
            problems.append("the side-car does not record the produced manifest's SHA-256")
    return problems
