"""Run-time cost against error versus the physical reference: every candidate representation of each material.

For each material of an atlas whose physical reference is one BRDF
(:func:`atlasgen.models.physical_error.physical_brdf`: a plain Mitsuba BSDF, a separable source,
or the model's own NumPy f cos such as the thin sheet and the spectral thin film), :func:`material_candidates` measures
every representation it could be baked as (:func:`atlasgen.models.physical_error.physical_candidates`:
LUT slices, separable K = 1..8, the analytic shader), each with the lighting pass's cost per
pixel per light on the device of the shipped cost table and its relative RMS of f cos against
the physical reference with its standard error. The figures are cached as JSON beside the
report, keyed by a digest of the material's parameters, the cost table, the candidates'
version and the code they come from (the bake cache's fingerprint), so a second report over
the same library recomputes nothing; missing ones are computed in up to :data:`MAX_JOBS`
worker processes (each candidate list depends only on its material, so the order of
completion changes no byte).

:func:`plot_material` draws one material's Pareto chart, :func:`plot_library` the library's:
cost (x) against error (y, log) with 1-SE error bars, the Pareto front (nothing both cheaper
and closer) as a line, the representation the material is baked as highlighted.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from atlasgen.bake.adaptive import bake_supersampled
from atlasgen.bake.cache import tool_fingerprint
from atlasgen.bake.workers import worker_pool
from atlasgen.errors import AtlasgenError
from atlasgen.io.manifest import AnalyticRepresentation, LutRepresentation, MaterialEntry
from atlasgen.models import get_model, manifest_params
from atlasgen.models.physical_error import candidates_key, physical_candidates
from atlasgen.reports.html import Chart, figure_chart, figure_png, label_points, pareto_front, plot_style

__all__ = ["MAX_JOBS", "ERROR_FLOOR", "baked_candidate", "material_candidates", "library_candidates", "cache_files", "front_flags", "short_label",
           "plot_material", "plot_library"]  # fmt: skip

#: Worker processes computing missing candidate lists (the demo machine has 2 cores).
MAX_JOBS = 2
#: Where an exact candidate (error 0) is drawn on the log error axis.
ERROR_FLOOR = 1e-4


def baked_candidate(entry: MaterialEntry, result: dict) -> str | None:
    """The candidate of ``result`` that ``entry`` is baked as (its ``representation`` label)."""
    labels = [c["representation"] for c in result.get("candidates", [])]
    rep = entry.representation
    fit = entry.fit.to_json() if entry.fit is not None else {}
    if isinstance(rep, AnalyticRepresentation):
        wanted = [f"analytic:{rep.distribution}"]
    elif entry.factors is not None:
        wanted = [f"separable:{entry.factors.terms or entry.factors.term_slices}"]
    elif fit.get("from") == "physical":
        wanted = ["lut: fitted from physics, 8-bit"]
    elif isinstance(rep, LutRepresentation) and rep.supersampling > 1:
        wanted = ["lut: model, 4x4 supersampled, 8-bit", "lut: model, point-sampled, 8-bit"]
    else:
        wanted = ["lut: model, point-sampled, 8-bit"]
    return next((w for w in wanted if w in labels), None)


#: Candidate lists computed in this process, by key: a process that writes several reports
#: (tests, a fuzzer) measures each material once.
_MEMO: dict = {}


def _compute(job):
    entry, gloss = job
    try:
        # The manifest's params are the model's values as baked. The report checked them first
        # (check_manifest_params), naming the manifest and the field; a backend missing is said here.
        values = manifest_params(entry, "the manifest", f"material {entry.name!r}", deep=True)
        return physical_candidates(get_model(entry.type), values, bake_supersampled, gloss=gloss)
    except AtlasgenError as exc:  # e.g. Mitsuba missing: the page says so, and nothing is cached
        return {"reference": None, "reason": f"not measured: {exc}", "transient": True}


def _gloss(entry: MaterialEntry) -> float | None:
    """The renderer gloss a material fitted from physics is drawn with (every object showing it), else None."""
    return None if entry.fit is None else float(entry.fit.gloss)


def _cache_path(cache_dir: Path, name: str) -> Path:
    return cache_dir / f"{name}.json"


def material_candidates(entry: MaterialEntry, cache_dir=None) -> dict:
    """:func:`~atlasgen.models.physical_error.physical_candidates` of one manifest entry, from the cache when current."""
    return library_candidates([entry], cache_dir, jobs=1)[entry.name]


def _content_digest(result: dict) -> str:
    """SHA-256 of a cached result's JSON but its own ``digest``: what the cache file records of its content."""
    body = {k: v for k, v in result.items() if k != "digest"}
    return hashlib.sha256(json.dumps(body, sort_keys=True).encode("utf-8")).hexdigest()


def _read_cached(path: Path, warn=None) -> dict | None:
    """The result cached at ``path`` if it is whole: JSON whose ``digest`` is its content's. A file edited by hand
    kept its ``key`` and was shown as measured (a cost made null ended in an internal error); it is computed again,
    said to ``warn`` where given."""
    try:
        cached = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        reason = getattr(exc, "strerror", None) or "not JSON"
    else:
        if isinstance(cached, dict) and cached.get("digest") == _content_digest(cached):
            return cached
        if isinstance(cached, dict) and "digest" not in cached:
            return None  # written before entries recorded their digest: computed again, nothing damaged
        reason = "its content is not what it records"
    if warn is not None:
        warn(f"{path.as_posix()}: a damaged cache entry ({reason}); computed again")
    return None


def library_candidates(entries, cache_dir=None, jobs: int = MAX_JOBS, warn=None) -> dict:
    """``{name: candidates}`` for ``entries`` (:func:`material_candidates`); missing ones computed in
    up to ``jobs`` processes. The cache files (``cache_dir/NAME.json``) are written by the caller's
    report writer: this returns ``{name: result}`` where each result carries its ``key``. A cache file
    that is damaged is computed again, and said to ``warn`` (:func:`_read_cached`)."""
    cache_dir = None if cache_dir is None else Path(cache_dir)
    out, todo = {}, []
    for entry in entries:
        # The code below bake/ (the bake cache's fingerprint) decides the figures as much as the params.
        key = hashlib.sha256(
            f"{candidates_key(get_model(entry.type), entry.params, _gloss(entry))}:{tool_fingerprint()}".encode()
        ).hexdigest()
        cached = None
        if key not in _MEMO and cache_dir is not None and _cache_path(cache_dir, entry.name).exists():
            cached = _read_cached(_cache_path(cache_dir, entry.name), warn)
        if key in _MEMO:
            out[entry.name] = _MEMO[key]
        elif isinstance(cached, dict) and cached.get("key") == key:
            out[entry.name] = cached
        else:
            todo.append((entry, key))
    jobs = max(1, min(int(jobs), len(todo), os.cpu_count() or 1))
    work = [(e, _gloss(e)) for e, _ in todo]
    if jobs > 1:
        with worker_pool(jobs) as pool:
            results = list(pool.map(_compute, work))
    else:
        results = [_compute(w) for w in work]
    for (entry, key), result in zip(todo, results):
        out[entry.name] = {"key": key, **result}
        if not result.get("transient"):
            _MEMO[key] = out[entry.name]
    return {e.name: out[e.name] for e in entries}


def cache_files(results: dict, cache_dir) -> dict:
    """``{path: bytes}`` of the cache files for ``results`` (deterministic JSON)."""
    cache_dir = Path(cache_dir)
    return {_cache_path(cache_dir, name): (json.dumps({**r, "digest": _content_digest(r)}, indent=1, sort_keys=True)
                                           + "\n").encode("utf-8")
            for name, r in results.items() if not r.get("transient")}  # fmt: skip


def front_flags(candidates: list[dict]) -> list[bool]:
    """Whether each candidate is on the Pareto front of (cost, error): nothing both cheaper and closer."""
    front = set(pareto_front([(c["cost"], c["error"]) for c in candidates]))
    return [i in front for i in range(len(candidates))]


def _axis_label(result_or_table) -> str:
    return f"lighting pass cost ({result_or_table['cost_unit']})\non {result_or_table['cost_device']}"


_SHORT = {"lut: model closed form (no texels)": "LUT model, no texels", "lut: model, point-sampled, 8-bit": "LUT model",
          "lut: model, 4x4 supersampled, 8-bit": "LUT model 4x4", "lut: fitted from physics": "LUT fit, float",
          "lut: fitted from physics, 8-bit": "LUT fit", "lut: fitted from physics, 4x4 supersampled": "LUT fit 4x4, float",
          "lut: fitted from physics, 4x4 supersampled, 8-bit": "LUT fit 4x4",
          "lut: fitted from physics over the 4x4 footprint": "LUT fit footprint, float",
          "lut: fitted from physics over the 4x4 footprint, 8-bit": "LUT fit footprint"}  # fmt: skip


def short_label(representation: str) -> str:
    """A chart label: ``K=3`` for ``separable:3``, ``analytic`` for the shader's closed form, a LUT's kind."""
    if representation.startswith("separable:"):
        return "K=" + representation.split(":", 1)[1]
    if representation.startswith("analytic:"):
        return "analytic (exact)"
    return _SHORT.get(representation, representation)


def _draw(ax, candidates, chosen, colour, label=None, annotate=True):
    xs = [c["cost"] for c in candidates]
    ys = [max(c["error"], ERROR_FLOOR) for c in candidates]
    se = [c.get("error_se", 0.0) for c in candidates]
    ax.errorbar(xs, ys, yerr=se, fmt="none", ecolor=colour, elinewidth=0.8, capsize=2)
    ax.scatter(xs, ys, s=18, facecolors="none", edgecolors=colour, label=label)
    front = pareto_front(list(zip(xs, ys)))
    ax.plot([xs[i] for i in front], [ys[i] for i in front], color=colour, linewidth=1.0, drawstyle="steps-post")
    picked = [i for i, c in enumerate(candidates) if c["representation"] == chosen]
    if picked:
        ax.scatter([xs[i] for i in picked], [ys[i] for i in picked], s=90, marker="*", color=colour, zorder=3)
    if annotate:
        label_points(ax, [(xs[i], ys[i]) for i in front], [short_label(candidates[i]["representation"]) for i in front])
    if any(c["error"] <= 0.0 for c in candidates):
        ax.axhline(ERROR_FLOOR, color="0.6", linewidth=0.6, linestyle=":")


def _room(ax, candidates):
    """Room above the highest and below the lowest point for their labels."""
    ys = [max(c["error"], ERROR_FLOOR) for c in candidates]
    ax.set_ylim(min(ys) / 3.0, max(ys) * 3.0)


def plot_material(name: str, result: dict, chosen: str | None, size) -> Chart:
    """One material's Pareto chart (see the module docstring); the baked representation a star; the
    front's labels placed over it (:func:`atlasgen.reports.html.figure_chart`)."""
    with plot_style() as plt:
        fig, ax = plt.subplots(figsize=size)
        _draw(ax, result["candidates"], chosen, "C0")
        ax.set_yscale("log")
        _room(ax, result["candidates"])
        ax.set_xlabel(_axis_label(result))
        ax.set_ylabel(f"rel. RMS of f cos vs physical (±1 SE)\n(exact: drawn at {ERROR_FLOOR:g})")
        ax.set_title(f"{name}: cost against error vs physical", fontsize="medium")
        return figure_chart(fig)


def plot_library(results: dict, chosen: dict, size) -> bytes:
    """Every projectable material's candidates, one colour each, its Pareto front a line, its baked representation a star."""
    shown = [(n, r) for n, r in results.items() if r.get("candidates")]
    with plot_style() as plt:
        fig, ax = plt.subplots(figsize=size)
        for k, (name, result) in enumerate(shown):
            _draw(ax, result["candidates"], chosen.get(name), f"C{k % 10}", label=name, annotate=False)
        ax.set_yscale("log")
        if shown:
            ax.set_xlabel(_axis_label(shown[0][1]))
            ax.legend(fontsize="small", ncol=2)
        ax.set_ylabel(f"rel. RMS of f cos vs physical (±1 SE)\n(exact: drawn at {ERROR_FLOOR:g})")
        ax.set_title("Library: run-time cost against error vs the physical reference", fontsize="medium")
        return figure_png(fig)
