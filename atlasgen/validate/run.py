"""Orchestration of ``atlasgen validate``: every material, every scene, atlas against references.

For each material and validation scene:

1. the bundled deferred renderer renders it through the baked atlas (GPU; timed as the
   median of :data:`ATLAS_TIMING_FRAMES` frames after a warm-up frame);
2. Mitsuba 3 renders the *model reference* (:mod:`.references`) in ``llvm_ad_rgb``;
3. where one exists, Mitsuba renders the *physical reference*.

Images stay in memory; :func:`atlasgen.reports.validation.write_validation` writes the report all-or-nothing.
Everything that can be checked before rendering is checked first (materials,
references, scenes, Mitsuba, the GPU), so bad input fails fast and writes nothing.
"""

from __future__ import annotations

import gc
import hashlib
import math
import os
import statistics
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from atlasgen.bake.cache import load_cached
from atlasgen.errors import BackendError, InputError, ManifestError, SceneError, did_you_mean
from atlasgen.io.atlas import Atlas, read_atlas
from atlasgen.io.manifest import Manifest
from atlasgen.io.referenced_files import referenced_files
from atlasgen.io.text import MISSING, path_kind
from atlasgen.materials.material import MAX_MATERIAL_BYTES, read_material_file
from atlasgen.materials.scene import with_fitted_surfaces
from atlasgen.models import check_manifest_models, get_model
from atlasgen.optics.display import display_clip
from atlasgen.render.atlas_texture import read_render_atlas
from atlasgen.render.renderer import Renderer
from atlasgen.validate.backend import load_mitsuba
from atlasgen.validate.environment import break_down_environment, environment_parts
from atlasgen.validate.identity import atlas_identity
from atlasgen.validate.materialx_reference import (
    FORWARD_DESCRIPTION,
    is_materialx_entry,
    oracle_over_physical_bsdf,
    render_forward_reference,
)
from atlasgen.validate.metrics import (
    NOISE_FLOOR_MARGIN_DB,
    compare_images,
    finite_or_none,
    noise_floor,
    psnr,
    relative_rms,
)
from atlasgen.validate.mitsuba_scene import (
    CENTRE_PASS_SPP,
    SLAB_DIFFUSION_LENGTHS,
    build_mitsuba_scene,
    cast_shadow_mask,
    diffusion_length,
    object_mask,
    register_direct_integrator,
    render_environment_qmc,
    render_mitsuba,
    render_pixel_centres,
    slab_object,
)
from atlasgen.validate.rebuild import material_mask, n_dot_v_image, rebuild_images
from atlasgen.validate.reference_cache import ReferenceCache, render_key
from atlasgen.validate.references import entry_model, model_reference, physical_reference, register_references
from atlasgen.validate.scenes import (
    MATERIAL_PLACEHOLDER,
    STANDARD_SCENES,
    bind_material,
    load_validation_scene,
    resize_scene,
)

__all__ = [
    "DEFAULT_SCENES",
    "FACING_AWAY_NOTE",
    "ENVIRONMENT_SCENES",
    "GOAL_ENVIRONMENT_PSNR_DB",
    "ATLAS_TIMING_FRAMES",
    "GOAL_PSNR_DB",
    "GOAL_FLIP",
    "GOAL_LOOK_PSNR_DB",
    "GOAL_LOOK_FLIP",
    "GRAZING_N_DOT_V",
    "MAX_PHYSICAL_SPP",
    "PHYSICAL_SPP",
    "ReferenceRender",
    "facing_away_mask",
    "MaterialRun",
    "ValidationRun",
    "is_material_file",
    "render_physical",
    "add_physical_samples",
    "measure_physical",
    "mean_of_seeds",
    "plan_validation",
    "validate_atlas",
]

DEFAULT_SCENES = ("front", "back")
#: The environment scenes (``atlasgen validate --environment``): a lone sphere under a uniform
#: environment and under the procedural sky (docs/validation.md, "Environment lighting").
ENVIRONMENT_SCENES = ("env-uniform", "env-sky")
#: Samples per pixel and seed an environment reference starts at, and the most it grows to.
ENVIRONMENT_SPP = 64
MAX_ENVIRONMENT_SPP = 4096
#: Goal of the environment-map case against the model reference (issue #20); the uniform case has the usual goals.
GOAL_ENVIRONMENT_PSNR_DB = 35.0
#: What an environment comparison leaves out.
ENVIRONMENT_MASK_NOTE = "every pixel that does not show the material (the background)"
#: A stochastic reference whose noise floor is too close to the error gets the samples the
#: floor needs, at least this many times the last count, up to MAX_PHYSICAL_SPP in all (or
#: --max-physical-spp; :func:`_converged_physical`). 8192 lets every shipped reference clear
#: its floor (skin's volpathmis needs about 7000 spp on the front scene); the reference cache
#: (:mod:`.reference_cache`) keeps a second run from rendering them again.
MIN_SPP_GROWTH = 2
MAX_PHYSICAL_SPP = 8192
#: Samples per pixel a stochastic physical reference starts with (two seeds of it give its floor).
PHYSICAL_SPP = 64
#: dB the predicted floor aims above PSNR + margin: the PSNR rises as the reference's noise falls.
FLOOR_HEADROOM_DB = 1.0
ATLAS_TIMING_FRAMES = 3
#: Goals against the model reference for shipped LUT materials (issue #5): what the atlas's storage costs.
GOAL_PSNR_DB = 45.0
GOAL_FLIP = 0.01
#: The default look goal: the atlas image against the material's physical reference, on the material's
#: pixels (issue #21). A material's ``[validate]`` table overrides either (docs/materials.md).
GOAL_LOOK_PSNR_DB = 30.0
GOAL_LOOK_FLIP = 0.05
#: N.V below which a pixel counts as grazing in each comparison's ``regions``.
GRAZING_N_DOT_V = 0.2
#: What every comparison on the validation scenes leaves out.
BACKGROUND_NOTE = "the pixels that do not show the material (background, other materials)"
#: What a MaterialX forward reference leaves out besides the background (:func:`facing_away_mask`).
FACING_AWAY_NOTE = (
    "{} of the material's pixels whose interpolated normal faces away from the camera (N.V <= 0, at silhouettes): "
    "outside the atlas's domain (v = N.V in 0..1), where MaterialX's shader clamps N.V to M_FLOAT_EPS and shades "
    "them as grazing, while the renderer's separable rebuild, like Mitsuba's BSDFs, gives 0 and a LUT slice repeats "
    "its N.V = 0 row"
)


@dataclass
class ReferenceRender:
    """One Mitsuba reference render and the atlas image's metrics against it."""

    kind: str  # "model" or "physical"
    description: str
    image: np.ndarray
    seconds: float
    spp: int
    variant: str
    metrics: object = None  # ImageMetrics
    second_image: np.ndarray | None = None  # a stochastic reference rendered again with another seed
    noise_floor_db: float | None = None  # PSNR between the two seeds (:func:`~atlasgen.validate.metrics.noise_floor`)
    mask: np.ndarray | None = None  # (h, w) True where the comparison leaves pixels out
    masked: str | None = None  # what the mask removes, for the report
    part_floors: dict = field(default_factory=dict)  # part -> the noise floor on its pixels (metrics.parts)
    part_spp: dict = field(default_factory=dict)  # part -> the samples per pixel its object took (:func:`_converged_by_object`)

    @property
    def masked_fraction(self) -> float | None:
        return None if self.mask is None else float(np.mean(self.mask))

    def floor_checks(self) -> list:
        """``(where, floor dB, PSNR dB)`` of every figure the noise floor must clear: the whole
        comparison (``where`` None), then each part of it (``metrics.parts``) that shows a pixel, a perfect
        match's PSNR inf."""
        if self.noise_floor_db is None or self.metrics is None:
            return []
        checks = [(None, self.noise_floor_db, self.metrics.psnr)]
        for name, floor in self.part_floors.items():
            part = self.metrics.parts.get(name) or {}
            if part.get("pixels") == 0:  # an object out of view: no error of its own to clear
                continue
            psnr_db = part.get("psnr_db")
            checks.append((name, floor, math.inf if psnr_db is None else psnr_db))
        return checks

    @property
    def noise_floor_ok(self) -> bool | None:
        """Whether the noise floor lies :data:`NOISE_FLOOR_MARGIN_DB` above the PSNR measured against
        this reference, and so does each part's floor above the part's PSNR, where the comparison
        has parts (``None`` for a deterministic reference)."""
        checks = self.floor_checks()
        if not checks or getattr(self.metrics, "not_measured", None) is not None:  # no error measured: no floor to clear
            return None
        return all(floor >= p + NOISE_FLOOR_MARGIN_DB for _, floor, p in checks)


@dataclass
class MaterialRun:
    """A material on one scene: the atlas render and its references."""

    material: str
    type: str
    scene: str
    atlas_image: np.ndarray
    atlas_seconds: float
    exposure: float
    references: dict = field(default_factory=dict)  # kind -> ReferenceRender
    claimed: dict | None = None  # the errors the manifest claims (Model.claimed_errors), and what the scene measures
    breakdown: dict | None = None  # the atlas's error split by cause, where the model has a float rebuild (:func:`_break_down`)
    notes: list = field(default_factory=list)
    goals: bool = True  # the model-reference goals apply (Model.validation_goals)
    environment_breakdown: dict | None = None  # the environment terms' CPU error by part (environment scenes)
    goal_psnr_db: float | None = None  # a goal of this scene's own, PSNR only (an environment map), else the usual goals
    look: dict | None = None  # the look goal: which reference, what it is, the goal (:func:`_look_goal`)
    materialx: dict | None = None  # a MaterialX material: its document, representation, cross-checks (:func:`_materialx_model`)


@dataclass
class ValidationRun:
    atlas: str
    runs: list
    settings: dict
    environment: dict
    seconds: float = 0.0
    warnings: list = field(default_factory=list)  # one line each, for the command to print (reference-cache entries not used)
    identity: dict = field(default_factory=dict)  # material -> what identifies it in the atlas validated (:mod:`.identity`)


@dataclass
class _Plan:
    atlas_path: Path
    manifest: Manifest
    entries: list
    scenes: list  # (name, Scene)
    atlas: Atlas | None = None  # read once: the renderer, the rebuilds and the checks share it
    float_slices: dict = field(default_factory=dict)  # name -> the bake cache's float slices, where current


def plan_validation(atlas_path, materials=None, scenes=DEFAULT_SCENES, resolution=None, bake_cache=None) -> _Plan:
    """Check every input before anything renders: atlas, materials, references and scenes.

    Each material's float slices are taken from ``bake_cache`` where its entry is current
    (:func:`_float_slices`) before any reference is built, so a fitted slice is not fitted again."""
    atlas_path = Path(atlas_path)
    atlas = read_atlas(atlas_path)  # a missing one: "no such atlas; bake one first (...)"
    if atlas.manifest is None:
        raise InputError(f"{atlas_path.as_posix()}: no manifest beside the atlas; re-run atlasgen bake")
    check_manifest_models(atlas.manifest, atlas.manifest_path.as_posix())
    entries_by_name = {e.name: e for e in atlas.manifest.materials}
    if materials:
        names = list(dict.fromkeys(n for m in materials for n in _material_names(m, atlas, entries_by_name)))
    else:
        names = sorted(entries_by_name, key=lambda n: entries_by_name[n].first_slice)
    entries, float_slices = [], {}
    for name in names:
        if name not in entries_by_name:
            known = ", ".join(sorted(entries_by_name)) or "none"
            hint = did_you_mean(name, entries_by_name)
            raise InputError(f"{atlas_path.as_posix()}: no material {name!r}{hint}; known: {known}")
        entry = entries_by_name[name]
        slices = _float_slices(entry, bake_cache)
        if slices is not None:
            float_slices[name] = slices
            entry_model(entry, slices)  # a fitted slice's table, for every FittedSlice of this material
        # Before the reference is built from them: a manifest's params are read as the model reads a material file's.
        _check_referenced_files(atlas_path, atlas.manifest.materials.index(entry), entry)
        model_reference(entry)  # raises InputError when no reference is possible
        entries.append(entry)
    if not entries:
        raise InputError(f"{atlas_path.as_posix()}: the atlas holds no materials to validate")
    loaded, given = [], {}
    for s in scenes:
        name, scene = load_validation_scene(s)
        if name in given:  # a scene's name names its results' images and rows: a second would overwrite the first's
            raise InputError(f"--scene {s}: a second scene named {name!r} (the first: --scene {given[name]}); expected "
                             "scenes of distinct names")  # fmt: skip
        given[name] = s
        if resolution is not None:
            scene = resize_scene(scene, *resolution)
        for obj in scene.objects:  # objects with a fixed material: it must be in the atlas
            if obj.material != MATERIAL_PLACEHOLDER and obj.material not in entries_by_name:
                known = ", ".join(sorted(entries_by_name)) or "none"
                raise SceneError(scene.path, f"objects[{obj.index}].material",
                                 f"unknown material {obj.material!r}{did_you_mean(obj.material, entries_by_name)}; "
                                 f"expected one of the names in {atlas_path.as_posix()}: {known}")  # fmt: skip
            if obj.material != MATERIAL_PLACEHOLDER:
                model_reference(entries_by_name[obj.material])
        loaded.append((name, scene))
    return _Plan(atlas_path, atlas.manifest, entries, loaded, atlas, float_slices)


def is_material_file(item) -> bool:
    """Whether a ``materials`` item names a material file rather than a material.

    Material names are letters, digits, ``-`` and ``_`` only, so anything ending in
    ``.toml`` or ``.mtlx`` (or a :class:`~pathlib.Path`) cannot be a name.
    """
    return isinstance(item, Path) or str(item).endswith((".toml", ".mtlx"))


def _material_names(item, atlas, entries_by_name) -> list[str]:
    """The material names of a ``materials`` item: a name as it is, a material file by the manifest
    entries it was baked into (a MaterialX document by each of its materials). A file must be the
    one the atlas was baked from (same content hash), or the atlas's slices would not be what the
    file describes.

    A TOML file's bytes are hashed, not parsed: the entry whose ``source`` is this file, or else whose
    content hash is the file's, names it. Only a file no entry matches is parsed (a MaterialX
    document's entries hash each material's name and values, not the file's bytes), for its names and the message
    (a missing or invalid file fails there, naming the file)."""
    if not is_material_file(item):
        return [str(item)]
    atlas_path = atlas.path
    path = Path(item)
    digest = None
    # Only a regular file of a material file's size is hashed: a named pipe would wait for a writer for ever and a
    # device has no end. Anything else is left to read_material_file, which refuses it on one line.
    if path_kind(path) is None:
        try:
            if path.stat().st_size <= MAX_MATERIAL_BYTES:
                digest = hashlib.sha256(path.read_bytes()).hexdigest()
        except OSError:
            pass
    # realpath: resolve() raises RuntimeError where another entry's material file has become a link loop.
    here = os.path.realpath(path)
    by_source = [e for e in entries_by_name.values() if os.path.realpath(atlas.source_path(e)) == here]
    if digest is not None:
        by_hash = [e for e in entries_by_name.values() if e.content_hash == digest]
        match = next((e for e in by_source if e.content_hash == digest), None) or (by_hash[0] if len(by_hash) == 1 else None)
        if match is not None:
            return [match.name]
    # A document baked with --flatten default is read as it was baked: its entries record what was flattened
    # (read plainly, the driven input was refused, with a hint to flatten that validate has no option for).
    flattened = any(((e.params.get("materialx") or {}).get("flattened")) for e in by_source)
    names = []
    for material in read_material_file(item, "default" if flattened else None):  # errors name the file
        entry = entries_by_name.get(material.name)
        if entry is None:
            known = ", ".join(sorted(entries_by_name)) or "none"
            raise InputError(f"{material.source}: material {material.name!r} is not in {atlas_path.as_posix()} "
                             f"(known: {known}); re-run atlasgen bake")  # fmt: skip
        if entry.content_hash != material.content_hash:
            raise InputError(f"{material.source}: changed since {atlas_path.as_posix()} was baked "
                             f"(its content hash differs from the manifest's); re-run atlasgen bake")  # fmt: skip
        names.append(material.name)
    return names


def _check_referenced_files(atlas_path, index: int, entry) -> None:
    """Refuse a manifest entry naming a file that is no longer there, naming ``materials[index].params.<name>``
    (check_manifest_models has checked each parameter's value as a material file's)."""
    # A file the material names (its manifest holds it relative to itself): moved or deleted since the bake, Mitsuba's
    # references failed with OpenImageIO's complaints and an internal error.
    for where, name in referenced_files(entry.params):
        kind = path_kind(name)
        if kind is not None:
            raise ManifestError(atlas_path.with_suffix(".json").as_posix(), f"materials[{index}].params.{where}",
                                f"expected the file the material was baked from, got {name}: "
                                f"{'no such file' if kind == MISSING else kind} (moved since the bake? re-run atlasgen "
                                "bake)")  # fmt: skip


def _object_entries(scene, entry, manifest) -> list:
    """Per object of a bound scene: its manifest entry (the material under test, or its own)."""
    by_name = {e.name: e for e in manifest.materials}
    return [by_name.get(o.material, entry) for o in scene.objects]


def _object_bsdfs(scene, entry, manifest):
    """Per object: its material's model reference, with the object's albedo and gloss."""
    return [model_reference(e, o.albedo, o.gloss).bsdf for o, e in zip(scene.objects, _object_entries(scene, entry, manifest))]


def _time_atlas(renderer, scene) -> tuple[np.ndarray, float, dict]:
    """The atlas image, the median frame time and the g-buffer read-backs (from the warm-up)."""
    warm = renderer.render(scene, outlines=False, aovs=True)  # warm-up: pipelines, uploads
    times, image = [], None
    for _ in range(ATLAS_TIMING_FRAMES):
        t0 = time.perf_counter()
        image = renderer.render(scene, outlines=False, aovs=False).radiance
        times.append(time.perf_counter() - t0)
    return np.asarray(image, dtype=np.float32), statistics.median(times), warm.aovs


def validate_atlas(atlas_path, materials=None, scenes=DEFAULT_SCENES, spp: int = 1, physical_spp: int = PHYSICAL_SPP,
                   max_physical_spp: int | None = None, resolution=None, physical: bool = True, progress=None, on_material=None,
                   bake_cache=None, reference_cache=None) -> ValidationRun:  # fmt: skip
    """Render every material on every scene, through the atlas and with Mitsuba; measure.

    Parameters
    ----------
    atlas_path
        ``X.dds`` with ``X.json`` and ``X.wgsl`` beside it (``atlasgen bake``).
    materials
        Material names, or material TOML files (read for their ``name``; each must be
        the file the atlas was baked from), to validate; all materials of the atlas by
        default.
    scenes
        Standard scene names (``front``, ``back``) or scene TOML paths.
    spp
        Mitsuba samples per pixel of the model references (1 = the pixel centre, what
        the rasteriser samples; a square number k^2 averages a k x k grid).
    max_physical_spp
        The most samples per pixel a stochastic reference grows to (default :data:`MAX_PHYSICAL_SPP`, and
        :data:`MAX_ENVIRONMENT_SPP` for an environment scene's reference; given, it caps both).
    physical_spp
        Samples per pixel of the stochastic physical references (``volpath``, spectral
        ones). Each is rendered twice, with seeds 0 and 1, for its noise floor.
    resolution
        ``(width, height)`` overriding the scenes' image size.
    physical
        Also render physical references where they exist.
    progress
        Called with a short text after each render.
    on_material
        Called as ``on_material(name, done, total)`` when a material has been rendered
        and measured on every scene (``done`` of ``total`` materials).
    bake_cache
        The bake's cache folder (``build/cache``, :mod:`atlasgen.bake.cache`): a material's float
        slices come from its current entry there, and are not computed (or fitted) again.
        ``None``, or no current entry: computed.
    reference_cache
        A folder of reference renders (:mod:`.reference_cache`): renders found there are not
        rendered again, and new ones are stored. ``None``: kept for the run only.

    Raises
    ------
    InputError, SceneError
        Unknown material or scene, a material no reference can be built for, or a
        material file that is missing, invalid, or changed since the atlas was baked.
    BackendError
        Mitsuba's LLVM backend or a GPU adapter is missing.
    """
    if spp < 1 or physical_spp < 1:
        raise InputError(f"spp: expected a positive sample count, got {spp if spp < 1 else physical_spp}")
    # An environment scene's reference grows to its own default cap, or to the maximum given (the option the
    # noise-floor warning points to); a physical reference to at least the samples it starts with.
    max_environment_spp = MAX_ENVIRONMENT_SPP if max_physical_spp is None else max(int(max_physical_spp), ENVIRONMENT_SPP)
    max_physical_spp = max(MAX_PHYSICAL_SPP if max_physical_spp is None else int(max_physical_spp), physical_spp)
    t_start = time.perf_counter()
    plan = plan_validation(atlas_path, materials, scenes, resolution, bake_cache)
    mi = load_mitsuba("llvm_ad_rgb")
    register_references(mi)
    renderer = Renderer(read_render_atlas(plan.atlas_path, atlas=plan.atlas))
    errors_before = len(renderer.ctx.errors)
    _check_visible(renderer, plan, resolution)
    say = progress or (lambda text: None)

    runs = []
    # Reference renders, by what decides them (:func:`_render_key`): two materials with the same
    # physics (a closed-form and a fitted skin) share their reference within a run, and with a
    # ``reference_cache`` folder a second run renders none of them again.
    renders = ReferenceCache(reference_cache)
    bake_hits = []
    bsdf_ratios: dict = {}  # a MaterialX material's BRDF over its physical reference's, measured once per material
    for done, entry in enumerate(plan.entries, 1):
        float_slices = plan.float_slices.get(entry.name)
        if float_slices is not None:
            bake_hits.append(entry.name)
        model = entry_model(entry, float_slices)
        for scene_name, scene in plan.scenes:
            bound = with_fitted_surfaces(bind_material(scene, entry.name), {e.name: e for e in plan.manifest.materials})
            atlas_image, atlas_s, aovs = _time_atlas(renderer, bound)
            run = MaterialRun(entry.name, entry.type, scene_name, atlas_image, atlas_s, bound.settings.exposure,
                              goals=model.validation_goals)  # fmt: skip
            if entry.fit is not None:
                run.notes.append(f"fitted to a physical BSDF for gloss {entry.fit.gloss:g}: the objects showing it are "
                                 f"shaded with that gloss and albedo 1, whatever the scene sets")  # fmt: skip
            say(f"{entry.name} / {scene_name}: atlas {1000 * atlas_s:.1f} ms")

            mi.set_variant("llvm_ad_rgb")
            if bound.environment is not None:
                _check_environment(run, mi, renderer, entry, plan.manifest, bound, aovs, model.custom_lighting,
                                   max_environment_spp)  # fmt: skip
                ref = run.references["model"]
                say(f"{entry.name} / {scene_name}: environment reference {ref.seconds:.2f} s at {ref.spp} spp, "
                    f"{_psnr_said(ref.metrics)}, noise floor {ref.noise_floor_db:.1f} dB")  # fmt: skip
                runs.append(run)
                continue
            own = material_mask(entry, aovs)
            n_dot_v = n_dot_v_image(bound, aovs, own)
            outside, regions = ~own, _grazing_regions(own, n_dot_v)
            ref = _model_render(mi, bound, entry, plan.manifest, spp, renders)
            if is_materialx_entry(entry):
                ref = _materialx_model(run, bound, entry, model, ref, outside, facing_away_mask(own, n_dot_v))
            measure_physical(ref, atlas_image, run.exposure, outside, regions)
            run.references["model"] = ref
            _check_rebuilds(run, model, plan.atlas, entry, bound, aovs, float_slices)
            say(f"{entry.name} / {scene_name}: model reference {ref.seconds:.2f} s, {_psnr_said(ref.metrics)}")

            phys = physical_reference(entry) if physical else None
            if phys is not None:
                # A medium's reference shows each object as the physics of its shape (a plane: a slab): scored apart.
                objects = _object_parts(renderer, bound, entry, aovs) if phys.interior is not None else []
                if objects:
                    run.notes.append(PARTS_NOTE.format(", ".join(label for label, _, _ in objects)))
                    ref = _converged_by_object(mi, bound, entry, phys, plan.manifest, physical_spp, max_physical_spp, spp,
                                               renders, atlas_image, run.exposure, outside, regions, objects)  # fmt: skip
                else:
                    ref = _converged_physical(mi, bound, entry, phys, plan.manifest, physical_spp, max_physical_spp, spp,
                                              renders, atlas_image, run.exposure, outside, regions)  # fmt: skip
                run.references["physical"] = ref
                say(
                    f"{entry.name} / {scene_name}: physical reference {ref.seconds:.2f} s, {_psnr_said(ref.metrics)}"
                    + (f", noise floor {ref.noise_floor_db:.1f} dB" if ref.noise_floor_db is not None else "")
                )
            if run.materialx is not None and "physical" in run.references:
                run.materialx["oracle_over_physical"] = _oracle_over_physical(run, entry, own, bsdf_ratios)
            run.look = _look_goal(entry, model, run, physical)
            runs.append(run)
        if on_material is not None:
            on_material(entry.name, done, len(plan.entries))

    errors = renderer.ctx.errors[errors_before:]
    if errors:
        raise BackendError(f"the GPU device reported {len(errors)} error(s); first: {errors[0].splitlines()[0]}")
    environment = {
        "gpu": renderer.ctx.name,
        "mitsuba": getattr(mi, "__version__", "?"),
        "atlas_timing": f"median of {ATLAS_TIMING_FRAMES} frames after a warm-up, outlines off, including read-back",
        "mitsuba_timing": "one mi.render call, including Dr.Jit kernel compilation (cached across materials)",
        "reference_cache": None if reference_cache is None else Path(reference_cache).as_posix(),
        "reference_renders_from_cache": renders.hits,
        "reference_renders_stored": renders.stored,
        "reference_renders_rejected": len(renders.rejected),
        "float_slices_from_bake_cache": bake_hits,
    }
    settings = {
        "spp": spp,
        # None where no physical reference was rendered (--no-physical): the page then says so, not an spp.
        "physical_spp": physical_spp if physical else None,
        "max_physical_spp": max_physical_spp if physical else None,
        # Each scene by its name and file's bytes, not its path: the path as typed gave other bytes from another folder
        # (a built-in scene's, from another clone), and a merge took one path for one scene whatever the file held.
        "scenes": [{"name": n, "sha256": _file_sha256(s.path), "width": s.width, "height": s.height} for n, s in plan.scenes],
        "goals": {
            "psnr_db": GOAL_PSNR_DB,
            "flip": GOAL_FLIP,
            "environment_map_psnr_db": GOAL_ENVIRONMENT_PSNR_DB,
            "look_psnr_db": GOAL_LOOK_PSNR_DB,
            "look_flip": GOAL_LOOK_FLIP,
            "grazing_n_dot_v": GRAZING_N_DOT_V,
        },
    }
    identity = {e.name: atlas_identity(plan.atlas, e) for e in plan.entries}
    return ValidationRun(plan.atlas_path.as_posix(), runs, settings, environment, time.perf_counter() - t_start,
                         warnings=list(renders.rejected), identity=identity)  # fmt: skip


def _check_visible(renderer, plan, resolution=None) -> None:
    """Refuse a scene on which a material to validate shows no pixel (its objects out of view, or a frame too
    small to cover one pixel centre), before any reference renders: every figure would be a mean over
    nothing. One g-buffer per material and scene (a frame of the rasteriser: milliseconds)."""
    by_name = {e.name: e for e in plan.manifest.materials}
    for entry in plan.entries:
        for name, scene in plan.scenes:
            bound = with_fitted_surfaces(bind_material(scene, entry.name), by_name)
            aovs = renderer.render(bound, outlines=False, aovs=True).aovs
            if material_mask(entry, aovs).any():
                continue
            shown = name if name in STANDARD_SCENES else Path(scene.path).as_posix()
            size = " (--resolution)" if resolution is not None else ""
            raise InputError(f"scene {shown!r}: no pixel of its {scene.width}x{scene.height} frame{size} shows material "
                             f"{entry.name!r} (nothing to compare); expected a scene in which it is visible (an object "
                             f"with material = {MATERIAL_PLACEHOLDER!r} in view of the camera, covering a pixel centre)")  # fmt: skip


def _check_environment(
    run, mi, renderer, entry, manifest, scene, aovs, custom_lighting: bool, max_spp: int = MAX_ENVIRONMENT_SPP
) -> None:
    """The model reference of an environment scene, converged, on the material's pixels; and the CPU breakdown.

    The reference is stochastic: a scene lit by its environment alone by
    :func:`~atlasgen.validate.mitsuba_scene.render_environment_qmc` (the BSDF and the emitter sampled on
    shifted Halton points, which converges far faster for a glossy lobe), one with lights too by
    :func:`~atlasgen.validate.mitsuba_scene.render_pixel_centres` (``atlasgen_direct``'s MIS estimate); seeds 0 and 1 from
    :data:`ENVIRONMENT_SPP` samples per pixel each, grown as physical references are
    (:func:`_samples_for_floor`) up to ``max_spp``. Every figure covers the pixels whose
    g-buffer ID is the material's only (the background is not the material). A table material also
    gets its error split into the SH band limit and the split sum (:mod:`atlasgen.validate.environment`).
    """
    mask = ~material_mask(entry, aovs)
    mi_scene = build_mitsuba_scene(mi, scene, _object_bsdfs(scene, entry, manifest), 1, stochastic=True)
    # Lit by its environment alone: sample the BSDF too, on quasi-random points (render_environment_qmc).
    qmc = not scene.lights
    render = render_environment_qmc if qmc else render_pixel_centres
    image = second = None
    n, target, seconds = 0, ENVIRONMENT_SPP, 0.0
    while True:
        more = target - n
        a, t_a = render(mi, mi_scene, more, seed=0, first_sample=n)
        b, t_b = render(mi, mi_scene, more, seed=1, first_sample=n)
        image = a if image is None else (n * image + more * a) / target
        second = b if second is None else (n * second + more * b) / target
        n, seconds = target, seconds + t_a + t_b
        floor = noise_floor(image, second, run.exposure, mask)
        metrics = compare_images(0.5 * (image + second), run.atlas_image, run.exposure, mask=mask)
        wanted = _samples_for_floor(n, floor, metrics.psnr)
        if floor >= metrics.psnr + NOISE_FLOOR_MARGIN_DB or n >= max_spp or wanted is None:
            break
        target = min(wanted, max_spp)
    del mi_scene
    source = model_reference(entry).description
    how = ", BSDF and emitter sampled on shifted Halton points" if qmc else ""
    ref = ReferenceRender("model", f"{source}, under the environment{how}", 0.5 * (image + second), seconds, n, "llvm_ad_rgb",
                          metrics=metrics, noise_floor_db=floor, mask=mask, masked=ENVIRONMENT_MASK_NOTE)  # fmt: skip
    run.references["model"] = ref
    if scene.environment.source != "uniform":
        run.goal_psnr_db = GOAL_ENVIRONMENT_PSNR_DB
    if custom_lighting:
        run.notes.append("a separable material: the renderer's split sum with its directional albedo; "
                         "its error is not split by part")  # fmt: skip
        return
    data = renderer.environment.data(scene.environment)
    parts = environment_parts(renderer.atlas.levels, renderer.atlas.srgb, entry, scene, aovs, data)
    out = break_down_environment(parts, run.exposure)
    keep = ~parts.mask
    m = compare_images(ref.image, parts.exact, run.exposure, with_flip=False, mask=keep)
    out["exact_vs_reference"] = {"psnr_db": finite_or_none(m.psnr), "linear_relative_rms": m.linear_relative_rms}
    m = compare_images(parts.approx, np.where(parts.mask[..., None], run.atlas_image, 0.0), run.exposure, with_flip=False,
                       mask=keep)  # fmt: skip
    out["gpu_vs_cpu"] = {"psnr_db": finite_or_none(m.psnr), "linear_relative_rms": m.linear_relative_rms}
    run.environment_breakdown = out


def _float_slices(entry, bake_cache):
    """``entry``'s float slices ``(n, H, W, 4)`` from its current bake-cache entry (``<bake_cache>/<stem>.npz``,
    keyed by the material file's content hash, as the manifest records it, and the bake code), or None."""
    if bake_cache is None:
        return None
    material = SimpleNamespace(name=entry.name, source=entry.source, content_hash=entry.content_hash,
                               slice_count=entry.slice_count, model=get_model(entry.type))  # fmt: skip
    slices = load_cached(bake_cache, material)
    if slices is None or slices.values.shape[0] != entry.slice_count:
        return None
    return slices.values


def facing_away_mask(own, n_dot_v) -> np.ndarray:
    """``(h, w)`` bool: the pixels of ``own`` whose g-buffer normal faces away from the camera, N.V <= 0
    (``n_dot_v``: :func:`~atlasgen.validate.rebuild.n_dot_v_image`, NaN off ``own``).

    Interpolated vertex normals do so at a silhouette. No BRDF is defined there, so each renderer has its
    convention; validation leaves these pixels out where the reference's convention differs from the atlas's
    (:data:`FACING_AWAY_NOTE`)."""
    with np.errstate(invalid="ignore"):
        return own & (n_dot_v <= 0.0)


def _grazing_regions(own, n_dot_v) -> dict:
    """The material's pixels split at :data:`GRAZING_N_DOT_V` (``n_dot_v`` from the g-buffer normal and the camera)."""
    with np.errstate(invalid="ignore"):
        grazing = own & (n_dot_v < GRAZING_N_DOT_V)
    return {"grazing": grazing, "rest": own & ~grazing}


#: The run's note where the physical comparison is split by object (:func:`_object_parts`).
PARTS_NOTE = (
    "the physical reference renders each object alone (no shadows or light between them, as the deferred renderer), "
    "filled with the medium, and a plane as the top of a slab of it, 10 diffusion lengths deep and beyond the plane's "
    "edges (only the plane's pixels take it: its sides never show); each converges to its own noise floor, and is "
    "scored apart by object ({}) as well as together"
)


def _object_parts(renderer, scene, entry, aovs) -> list:
    """``[(label, object index, (h, w) bool)]``: the pixels showing ``entry`` in ``aovs`` (the g-buffer of
    ``scene``), split by the object they show, where two or more objects show it (else ``[]``). Each object
    is drawn alone by the renderer; a pixel is that object's where its depth there is the whole scene's,
    the nearest surface. A plane is the "flat part"; a shape shown by two objects is named with each
    one's index."""
    own = material_mask(entry, aovs)
    objects = [o for o in scene.objects if o.material == entry.name]
    if len(objects) < 2:
        return []
    depth = np.asarray(aovs["depth"])
    shapes = [o.shape for o in objects]
    out = []
    for obj in objects:
        alone = renderer.render(replace(scene, objects=[obj]), outlines=False, aovs=True).aovs
        label = "flat part" if obj.shape == "plane" else obj.shape
        if shapes.count(obj.shape) > 1:
            label += f" (objects[{obj.index}])"
        out.append((label, obj.index, own & material_mask(entry, alone) & (np.asarray(alone["depth"]) == depth)))
    return out


def _converged_by_object(mi, scene, entry, reference, manifest, physical_spp, max_spp, spp, renders, atlas_image, exposure,
                         outside, regions, objects) -> ReferenceRender:  # fmt: skip
    """A medium's physical reference converged object by object (``objects``: :func:`_object_parts`), and measured.

    Each object is rendered alone at its own pixels (:func:`render_physical`'s ``only``) and gets the
    samples its own floor needs against its own error (:func:`_converged_physical` on its pixels): a
    flat part whose error is large converges in a few hundred samples where the sphere's small one
    needs thousands. The reference is their sum (each is 0 off its pixels), measured over the
    material's pixels with the objects as ``parts``; ``part_floors`` are the objects' floors, and
    the whole comparison's floor follows from them, the display MSE of two seeds adding over pixels:

        F = -10 log10(sum_k n_k 10^(-F_k / 10) / sum_k n_k),  n_k the pixels of part k.

    Each part clearing its floor by the margin makes the whole clear it too (its noise is at most a
    tenth of its error on every part). ``spp`` is the most any object took, ``part_spp`` each one's.
    """
    alone = {}
    for label, index, part in objects:
        alone[label] = _converged_physical(mi, scene, entry, reference, manifest, physical_spp, max_spp, spp, renders,
                                           atlas_image, exposure, outside | ~part, None, only=(index, part))  # fmt: skip
    image = np.sum([r.image for r in alone.values()], axis=0).astype(np.float32)
    ref = ReferenceRender("physical", reference.description, image, sum(r.seconds for r in alone.values()),
                          max(r.spp for r in alone.values()), reference.variant)  # fmt: skip
    parts = {label: part for label, _, part in objects}
    measure_physical(ref, atlas_image, exposure, outside, regions, parts)
    if reference.stochastic:
        ref.part_floors = {label: r.noise_floor_db for label, r in alone.items()}
        ref.part_spp = {label: r.spp for label, r in alone.items()}
        counts = {label: int((part & ~outside).sum()) for label, part in parts.items()}
        total = sum(counts.values())
        mse = sum(counts[k] * 10.0 ** (-ref.part_floors[k] / 10.0) for k in counts) / total if total else 0.0
        ref.noise_floor_db = math.inf if mse == 0.0 else -10.0 * math.log10(mse)
    return ref


def _model_render(mi, scene, entry, manifest, spp, renders) -> ReferenceRender:
    """The model reference of ``entry`` on ``scene`` (every object's model reference), from ``renders`` if there."""
    bsdfs = _object_bsdfs(scene, entry, manifest)
    unnamed = replace(scene, objects=[replace(o, material="") for o in scene.objects])
    key = _render_key(mi, "model", "llvm_ad_rgb", unnamed, bsdfs, spp)
    description = model_reference(entry).description
    kept = renders.get(key, (scene.height, scene.width)) if renders is not None else None
    if kept is not None:
        return ReferenceRender(**{**kept, "description": description})
    mi_scene = build_mitsuba_scene(mi, scene, bsdfs, spp)
    image, seconds = render_mitsuba(mi, mi_scene, spp)
    del mi_scene
    ref = ReferenceRender("model", description, image, seconds, spp, "llvm_ad_rgb")
    if renders is not None:
        renders.put(key, _render_fields(ref))
    return ref


def _materialx_model(run, scene, entry, model, plugin: ReferenceRender, outside, facing_away) -> ReferenceRender:
    """The model reference of a MaterialX material: the scene forward-rendered with MaterialX's shader
    (:func:`~atlasgen.validate.materialx_reference.render_forward_reference`), where the lighting is the
    atlas's and only the BRDF differs. The oracle through Mitsuba's ``atlasgen_brdf`` plugin (``plugin``)
    stays beside it as a cross-check: ``run.materialx`` records how far the two images of the same
    shading differ on the material's pixels (only the geometry can: rasterised against ray-traced shading
    points and normals). A scene with a light the forward render cannot bind keeps ``plugin``.

    The forward reference leaves out ``facing_away`` (:func:`facing_away_mask`): MaterialX's shader
    shades a normal facing away from the camera as a grazing one, which no table indexed by N.V in 0..1
    holds (:data:`FACING_AWAY_NOTE`); the cross-check leaves them out too."""
    spec = entry.params["materialx"]
    run.materialx = {"document": spec.get("document"), "material": spec.get("material"), "category": spec.get("category"),
                     "representation": model.describe_representation(entry).split(": ", 1)[-1],
                     "not_in_table": list(spec.get("not_in_table") or []),
                     "flattened": sorted(spec.get("flattened") or {})}  # fmt: skip
    forward = render_forward_reference(scene, entry)
    if forward is None:
        run.materialx["reference"] = "mitsuba plugin"
        run.notes.append("the scene has a light the MaterialX forward render does not bind: the model "
                         "reference is the oracle through Mitsuba's atlasgen_brdf plugin")  # fmt: skip
        return plugin
    image, seconds, _ = forward
    agree = compare_images(plugin.image, image, run.exposure, with_flip=False, mask=outside | facing_away)
    run.materialx["reference"] = "forward"
    run.materialx["forward_vs_mitsuba_plugin"] = {"psnr_db": finite_or_none(agree.psnr),
                                                  "linear_relative_rms": agree.linear_relative_rms,
                                                  "plugin_seconds": plugin.seconds}  # fmt: skip
    run.notes.append(f"model reference: MaterialX's shader forward-rendered under the scene's lights; the oracle through "
                     f"Mitsuba's plugin (intersections at the pixel centres) gives the same pixels to "
                     f"{_psnr_text(agree.psnr)} dB PSNR, relative RMS {agree.linear_relative_rms:.2e}")  # fmt: skip
    ref = ReferenceRender("model", f"{FORWARD_DESCRIPTION}; {model_reference(entry).description}", image, seconds, 1,
                          "moderngl")  # fmt: skip
    count = int(np.count_nonzero(facing_away))
    run.materialx["facing_away"] = {"pixels": count, "psnr_db_counting_them": None}
    if count:
        ref.mask, ref.masked = facing_away, FACING_AWAY_NOTE.format(count)
        counted = compare_images(image, run.atlas_image, run.exposure, with_flip=False, mask=outside)
        run.materialx["facing_away"]["psnr_db_counting_them"] = finite_or_none(counted.psnr)
    return ref


def _psnr_said(metrics) -> str:
    """``PSNR 41.2 dB`` for a progress line; what was not measured where nothing was (never "inf" or "nan")."""
    if metrics.not_measured is not None and not math.isfinite(metrics.psnr):
        return f"nothing measured ({metrics.not_measured})"
    return f"PSNR {_psnr_text(metrics.psnr)} dB"


def _psnr_text(psnr) -> str:
    return "inf" if psnr is None or not math.isfinite(psnr) else f"{psnr:.1f}"


def _oracle_over_physical(run, entry, own, bsdf_ratios: dict) -> dict:
    """MaterialX's shading over its physical reference's (the gold's ``roughconductor``): per pixel on this
    scene (the model reference's image over the physical one, every channel above 1% of the physical
    image's peak on the material's pixels) and, once per material, f cos over uniform (l, v) pairs
    (:func:`~atlasgen.validate.materialx_reference.oracle_over_physical_bsdf`)."""
    model = run.references["model"].image[..., :3].astype(np.float64)
    phys = mean_of_seeds(run.references["physical"])[..., :3].astype(np.float64)
    keep = own[..., None] & (phys > 0.01 * max(float(phys[own].max(initial=0.0)), 1e-12))
    ratio = model[keep] / phys[keep]
    if entry.name not in bsdf_ratios:
        bsdf_ratios[entry.name] = oracle_over_physical_bsdf(entry)
    out = {"reference": run.references["physical"].description, "pixels": int(ratio.size),
           "pixel_p1_p50_p99": [float(x) for x in np.percentile(ratio, [1, 50, 99])] if ratio.size else None,
           **bsdf_ratios[entry.name]}  # fmt: skip
    if out["pixel_p1_p50_p99"] is not None:
        p = out["pixel_p1_p50_p99"]
        run.notes.append(f"MaterialX over its physical reference ({_short_description(out['reference'])}): per pixel "
                         f"{p[0]:.3f} / {p[1]:.3f} / {p[2]:.3f} (1st / 50th / 99th percentile of {ratio.size} channel values); "
                         f"f cos over {out['pairs']} uniform (l, v) pairs with N.L, N.V >= 0.2: "
                         f"{out['bsdf_min_max'][0]:.3f} to {out['bsdf_min_max'][1]:.3f}")  # fmt: skip
    return out


def _short_description(description: str) -> str:
    """A reference's description up to its first clause: what it is, not how.

    >>> _short_description("Mitsuba roughplastic: exact Fresnel, GGX lobe of the renderer's roughness")
    'Mitsuba roughplastic'
    >>> _short_description("Mitsuba diffuse (the consistency gate)")
    'Mitsuba diffuse'
    """
    cut = min((i for i in (description.find(c) for c in (":", ",", " (", ";")) if i > 0), default=len(description))
    return description[:cut].strip()


def _file_sha256(path) -> str | None:
    """The SHA-256 of the file at ``path`` (a scene's), or None where it was read from no file."""
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except (OSError, TypeError):
        return None


def _look_goal(entry, model, run, physical: bool) -> dict:
    """What the look of ``entry`` is judged against on this scene, and the goal: the physical reference
    (or, for a model whose model reference is the physical BSDF itself, that), the material's
    ``[validate]`` goal or the defaults (:data:`GOAL_LOOK_PSNR_DB`, :data:`GOAL_LOOK_FLIP`), or why
    there is none. The verdict itself is the report's (:func:`atlasgen.reports.validation.look_verdict`)."""
    own = dict(entry.extra.get("validate") or {})
    goal = {"psnr_db": float(own.get("psnr_db", GOAL_LOOK_PSNR_DB)), "flip": float(own.get("flip", GOAL_LOOK_FLIP))}
    out = {"goal": goal, "goal_source": "material" if own else "default"}
    if "physical" in run.references:
        kind = "physical"
    elif getattr(model, "model_reference_is_physical", False):
        kind = "model"
    elif not physical and physical_reference(entry) is not None:
        return {**out, "reference": None, "compared": None, "why_none": "not rendered (--no-physical)", "skipped": True}
    else:
        return {**out, "reference": None, "compared": None, "why_none": model.no_physical_reference or "its model has none"}
    short = _short_description(run.references[kind].description)
    if entry.fit is not None and entry.fit.source in ("physical", "bsdf"):
        compared = f"the {short} it was fitted from"
    elif kind == "model":
        compared = f"the {short} it was factored from"
    else:
        compared = f"its physical reference, {short}"
    return {**out, "reference": kind, "compared": compared}


def _converged_physical(mi, scene, entry, reference, manifest, physical_spp, max_spp, spp, renders, atlas_image, exposure,
                        mask=None, regions=None, only=None) -> ReferenceRender:  # fmt: skip
    """The physical reference, measured against ``atlas_image``; a stochastic one converged.

    A stochastic reference renders with seeds 0 and 1 at ``physical_spp`` samples per pixel;
    the image compared is their mean, and the PSNR between them is its noise floor. While the
    floor is not :data:`NOISE_FLOOR_MARGIN_DB` above the PSNR it measures, both renders get
    more samples, up to ``max_spp`` in all: a reference is converged where the error needs it,
    and cheap elsewhere.

    Noise variance falls as 1/n, so n samples give a floor F(n) = F(n0) + 10 log10(n / n0).
    The next total is the n at which F reaches the PSNR + margin + :data:`FLOOR_HEADROOM_DB`
    (the PSNR itself rises a little as the reference's noise goes), at least
    :data:`MIN_SPP_GROWTH` times the last, rounded up to whole passes. The new samples
    continue the old ones (``first_sample``), so none is rendered twice. ``only``: converge the
    render of one object alone (:func:`render_physical`; ``mask`` then leaves out all but its pixels).
    """
    n = physical_spp
    ref = render_physical(mi, scene, entry, reference, manifest, n, spp, renders, only=only)
    while True:
        measure_physical(ref, atlas_image, exposure, mask, regions)
        target = _samples_for_floor(n, ref.noise_floor_db, None if ref.metrics is None else ref.metrics.psnr)
        if ref.noise_floor_ok is not False or n >= max_spp or target is None:
            break
        more = min(target, max_spp) - n
        add_physical_samples(mi, scene, entry, reference, manifest, ref, more, spp, renders, only)
        n = ref.spp
    ref.image, ref.second_image = mean_of_seeds(ref), None
    return ref


def measure_physical(ref: ReferenceRender, atlas_image, exposure: float, mask=None, regions=None, parts=None) -> None:
    """Set ``ref``'s noise floor (the PSNR between its two seeds, where it has two) and the atlas
    image's metrics against the mean of its seeds, leaving out ``ref.mask`` and ``mask`` (True = left out:
    validation passes every pixel that does not show the material), with figures over ``regions``
    and ``parts`` (:func:`~atlasgen.validate.metrics.compare_images`; each part gets a noise floor of
    its own, ``ref.part_floors``) and the whole-frame PSNR of earlier reports (only ``ref.mask`` left
    out, the background counted) for comparison."""
    own_mask = ref.mask
    if mask is not None:
        mask = mask if ref.mask is None else (ref.mask | mask)
    else:
        mask = ref.mask
    if ref.second_image is not None:
        ref.noise_floor_db = noise_floor(ref.image, ref.second_image, exposure, mask)
        outside = np.zeros(ref.image.shape[:2], dtype=bool) if mask is None else mask
        ref.part_floors = {name: noise_floor(ref.image, ref.second_image, exposure, outside | ~np.asarray(part, dtype=bool))
                           for name, part in (parts or {}).items()}  # fmt: skip
    reference = mean_of_seeds(ref)
    ref.metrics = compare_images(reference, atlas_image, exposure, mask=mask, regions=regions, parts=parts)
    keep = (slice(None),) if own_mask is None else (~own_mask,)
    ref.metrics.whole_frame_psnr = psnr(display_clip(reference, exposure)[keep], display_clip(atlas_image, exposure)[keep])


def add_physical_samples(mi, scene, entry, reference, manifest, ref: ReferenceRender, more: int, spp: int,
                         renders: dict | None = None, only=None) -> None:  # fmt: skip
    """Continue both seeds of the stochastic render ``ref`` (``ref.spp`` samples each) by ``more``
    samples, [``ref.spp``, ``ref.spp`` + ``more``), so none is rendered twice; each image becomes
    the sample-weighted mean (n I_n + m I_m) / (n + m) of the old and the new. ``only``: as
    :func:`render_physical`'s, the object ``ref`` is a render of."""
    n = ref.spp
    extra = render_physical(mi, scene, entry, reference, manifest, more, spp, renders, first_sample=n, only=only)
    ref.image = (n * ref.image + more * extra.image) / (n + more)
    ref.second_image = (n * ref.second_image + more * extra.second_image) / (n + more)
    ref.seconds += extra.seconds
    ref.spp = n + more


def mean_of_seeds(ref: ReferenceRender) -> np.ndarray:
    """The mean of a stochastic reference's two seeds; a deterministic one's image."""
    return ref.image if ref.second_image is None else 0.5 * (ref.image + ref.second_image)


def _samples_for_floor(n: int, floor_db: float | None, psnr_db: float | None) -> int | None:
    """Samples per pixel (per seed) at which a floor of ``floor_db`` at ``n`` samples clears
    ``psnr_db`` by the margin, by F(m) = F(n) + 10 log10(m / n); ``None`` when either figure
    is not finite (identical seeds, a perfect match: more samples cannot settle it)."""
    if floor_db is None or psnr_db is None or not (math.isfinite(floor_db) and math.isfinite(psnr_db)):
        return None
    needed = psnr_db + NOISE_FLOOR_MARGIN_DB + FLOOR_HEADROOM_DB - floor_db
    wanted = max(n * MIN_SPP_GROWTH, n * 10.0 ** (needed / 10.0))
    return int(math.ceil(wanted / CENTRE_PASS_SPP) * CENTRE_PASS_SPP) if wanted > CENTRE_PASS_SPP else int(math.ceil(wanted))


def _check_rebuilds(run, model, atlas, entry, scene, aovs, float_slices=None) -> None:
    """Measure the model's CPU rebuilds (:meth:`~atlasgen.models.base.Model.radiance_rebuilds`)
    against the atlas image and the model reference, and the manifest's claims where it makes any.

    ``atlas`` is the run's :class:`~atlasgen.io.atlas.Atlas` (read once); ``float_slices`` the
    material's float slices where the bake cache has them (else the model computes them).
    With a float rebuild the atlas's error splits by cause (:func:`_break_down`); with the
    8-bit rebuild alone, that rebuild is reported as a reference of its own (``rebuild``).
    Every figure covers the material's pixels only.
    """
    images = rebuild_images(model, entry, atlas, scene, aovs, float_slices)
    outside = ~material_mask(entry, aovs)
    if "float" in images:
        _break_down(run, entry, images["float"][0], images["8bit"][0], aovs)
    else:
        image, seconds, description = images["8bit"]
        ref = ReferenceRender("rebuild", description, image, seconds, 1, "numpy")
        ref.metrics = compare_images(image, _only_material(run.atlas_image, entry, aovs), run.exposure, mask=outside)
        ref.mask, ref.masked = outside, BACKGROUND_NOTE
        run.references["rebuild"] = ref
    claimed = model.claimed_errors(entry)
    if claimed is not None:
        _check_claims(run, entry, claimed, images["8bit"][0], aovs)


def _break_down(run, entry, table_float, table_8bit, aovs) -> None:
    """Split the atlas's error against its model reference by cause, on the CPU.

    ``table_float``: the model's float data sampled as the renderer does (resolution and
    filtering only); ``table_8bit``: the atlas's 8-bit texels (adds the 8-bit
    quantization); ``gpu_vs_8bit``: the GPU image against the 8-bit rebuild (the
    renderer's own precision, half-float output, f32 filtering).
    """
    model = run.references["model"]
    model_image = _only_material(model.image, entry, aovs)
    atlas_image = _only_material(run.atlas_image, entry, aovs)
    outside = ~material_mask(entry, aovs)
    if model.mask is not None:  # the split explains the model comparison's figure, so it leaves out what that does
        outside = outside | model.mask
    out = {}
    for key, image in (("table_float", table_float), ("table_8bit", table_8bit)):
        m = compare_images(model_image, image, run.exposure, mask=outside)
        out[key] = {"psnr_db": finite_or_none(m.psnr), "flip": finite_or_none(m.flip),
                    "linear_relative_rms": finite_or_none(m.linear_relative_rms)}  # fmt: skip
    m = compare_images(table_8bit, atlas_image, run.exposure, with_flip=False, mask=outside)
    out["gpu_vs_8bit"] = {"psnr_db": finite_or_none(m.psnr), "linear_relative_rms": finite_or_none(m.linear_relative_rms)}
    run.breakdown = out


def _only_material(image, entry, aovs) -> np.ndarray:
    """``image`` with every pixel not covered by ``entry``'s slices set to 0 (the CPU rebuilds cover only those)."""
    return np.where(material_mask(entry, aovs)[..., None], image, 0.0).astype(np.float32)


def _check_claims(run, entry, claimed, rebuild, aovs) -> None:
    """Set the manifest's claims beside what the scene measures, and split the gap."""
    source = _only_material(run.references["model"].image, entry, aovs)
    atlas = _only_material(run.atlas_image, entry, aovs)
    in_scene = relative_rms(source, rebuild)
    gpu = relative_rms(rebuild, atlas)
    run.claimed = {
        **claimed,
        "measured_relative_rms_rebuild_vs_source": in_scene,
        "measured_relative_rms_atlas_vs_source": relative_rms(source, atlas),
        "measured_relative_rms_atlas_vs_rebuild": gpu,
    }
    if claimed.get("relative_rms_8bit") is not None:
        run.notes.append(
            f"manifest claims relative RMS {claimed['relative_rms_8bit']:.4f} (8-bit; f cos over the hemisphere); "
            f"in this scene the rebuild differs from the source BSDF by {in_scene:.4f} (radiance-weighted), and the GPU "
            f"image from the rebuild by {gpu:.4f}"
        )


def register_references_for_variant(mi) -> None:
    """atlasgen's Python plugins for the current variant (Mitsuba registers per variant)."""
    register_references(mi)
    register_direct_integrator(mi)


def _plane_stand_in(entry, albedo) -> dict:
    """A diffuse BSDF of ``entry``'s ``colour`` (if it has one) for another material's object in a reference
    where that material's own reference cannot run (built-in plugins only, or a spectral variant)."""
    colour = np.asarray(entry.params.get("colour", (1.0, 1.0, 1.0))) * np.asarray(albedo)
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": colour.tolist()}}


#: What the physical comparison leaves out where the reference's integrator traces visibility.
CAST_SHADOW_NOTE = "cast shadows of other objects (the deferred renderer has none); inter-reflection is not masked"


def _render_key(mi, *decides) -> str | None:
    """SHA-256 of everything that decides a reference render (the scene as shown, each object's
    BSDF and medium, the integrator, samples and first sample, the variant), of the Mitsuba
    version and of the reference code (:func:`~atlasgen.validate.reference_cache.render_key`);
    ``None`` when some part has no canonical form, and the render is then not kept."""
    return render_key(getattr(mi, "__version__", None), *decides)


def _render_fields(ref: ReferenceRender) -> dict:
    """What a reference cache keeps of a render: its images, masks and how it was made (no metrics)."""
    return {"kind": ref.kind, "description": ref.description, "image": ref.image, "seconds": ref.seconds, "spp": ref.spp,
            "variant": ref.variant, "second_image": ref.second_image, "mask": ref.mask, "masked": ref.masked}  # fmt: skip


def render_physical(
    mi, scene, entry, reference, manifest, physical_spp, spp, renders: dict | None = None, first_sample: int = 0, only=None
) -> ReferenceRender:
    """The physical ``reference`` of ``entry`` on ``scene``. Objects of other materials keep
    their model reference, or a diffuse stand-in where the integrator needs built-in
    plugins only.

    A stochastic reference is rendered with seeds 0 and 1 (the second for its noise floor),
    samples [``first_sample``, ``first_sample`` + ``physical_spp``) of each.

    Where the material lives in a medium (``reference.interior``), every object is rendered
    alone, each where it is the first surface a pixel-centre ray meets in ``scene``
    (:func:`~atlasgen.validate.mitsuba_scene.object_mask`), and the renders add up to the
    reference: the deferred renderer neither shadows nor lights one object by another, and
    transport between two media (a sphere of skin on a slab of it) would be both. A plane
    showing the material, which cannot hold a medium, is a slab of it
    (:func:`~atlasgen.validate.mitsuba_scene.slab_object`): the plane is its top face, and it
    reaches :data:`~atlasgen.validate.mitsuba_scene.SLAB_DIFFUSION_LENGTHS` diffusion lengths
    below the plane and beyond its edges, so that light inside it meets no edge or bottom.
    Only the plane's pixels take that render, so the slab's sides and margin are never shown.
    ``only`` = ``(object index, (h, w) bool pixels)`` renders that one object at those pixels (the
    g-buffer's, :func:`_converged_by_object`) and nothing else.

    Otherwise the objects render together, and where the reference's integrator traces
    visibility (one of its own), the pixels in another object's cast shadow are masked
    (:func:`~atlasgen.validate.mitsuba_scene.cast_shadow_mask`).
    ``renders`` (a :class:`~atlasgen.validate.reference_cache.ReferenceCache`) holds renders by
    :func:`_render_key`: one already made is not made again (``None``: render, and keep nothing).
    """
    if reference.builtin_only:
        # Free every Python BSDF first: a symbolic call (volpath's loop) traces every
        # live instance, and NumPy cannot run on symbolic arrays.
        gc.collect()
    variant = reference.variant
    alone = reference.interior is not None
    mi.set_variant(variant)
    register_references_for_variant(mi)
    bsdfs, interiors, shown_objects = [], [], []
    for o, e in zip(scene.objects, _object_entries(scene, entry, manifest)):
        if e.name == entry.name:
            own = physical_reference(entry, o.albedo, o.gloss)
            bsdfs.append(own.bsdf)
            interiors.append(own.interior)
            slab = alone and o.shape == "plane" and own.interior is not None
            shown_objects.append(slab_object(o, SLAB_DIFFUSION_LENGTHS * diffusion_length(own.interior)) if slab else o)
        else:
            # Other materials' objects keep a diffuse stand-in where only built-in plugins may
            # run, or where the variant is spectral (the model references are RGB).
            stand_in = reference.builtin_only or alone or variant != "llvm_ad_rgb"
            bsdfs.append(_plane_stand_in(e, o.albedo) if stand_in else model_reference(e, o.albedo, o.gloss).bsdf)
            interiors.append(None)
            shown_objects.append(o)
    n = physical_spp if reference.stochastic else spp
    shown = replace(scene, objects=shown_objects)
    # The objects' material names decide nothing the render shows: their BSDFs and media do.
    unnamed = [replace(s, objects=[replace(o, material="") for o in s.objects]) for s in (scene, shown)]
    if only is not None and not alone:
        raise ValueError("render_physical: only one object is rendered alone only where the material lives in a medium")
    which = None if only is None else (int(only[0]), np.flatnonzero(np.asarray(only[1], dtype=bool)))
    key = None if renders is None else _render_key(mi, variant, unnamed, "each object alone" if alone else "together", bsdfs,
                                                   interiors, n, reference.integrator, reference.stochastic,
                                                   reference.builtin_only, first_sample, which)  # fmt: skip
    kept = None if key is None else renders.get(key, (scene.height, scene.width))
    if kept is not None:
        mi.set_variant("llvm_ad_rgb")
        return ReferenceRender(**kept)
    ref = _render_physical_scene(mi, scene, shown, bsdfs, interiors, reference, n, first_sample, only)
    if key is not None:
        renders.put(key, _render_fields(ref))
    return ref


#: The name validation's tests know it by.
_render_physical = render_physical


def _render_physical_scene(mi, scene, shown, bsdfs, interiors, reference, n, first_sample, only=None):
    """Render the reference's Mitsuba scene (both seeds where it is stochastic) and its mask: ``shown``
    (``scene`` with each plane of a medium as its slab) object by object where the material lives
    in a medium (:func:`render_physical`; ``only``: one object at the pixels given), else all together."""
    variant = reference.variant
    if reference.interior is not None:
        if only is not None:
            nothing = np.zeros((scene.height, scene.width), dtype=bool)
            seen = [np.asarray(only[1], dtype=bool) if o.index == only[0] else nothing for o in scene.objects]
        else:
            # First hits in the scene as the atlas shows it (planes, not slabs), before the variant changes.
            seen = [object_mask(mi, scene, [o.index]) for o in scene.objects]
        mi.set_variant(variant)
        image = np.zeros((scene.height, scene.width, 3), dtype=np.float32)
        second = np.zeros_like(image) if reference.stochastic else None
        seconds = 0.0
        for k, (obj, pixels) in enumerate(zip(shown.objects, seen)):
            if not pixels.any():
                continue
            alone = replace(shown, objects=[obj])
            mi_scene = build_mitsuba_scene(mi, alone, [bsdfs[k]], n, reference.integrator, [interiors[k]],
                                           stochastic=reference.stochastic)  # fmt: skip
            if reference.stochastic:
                plugins = not reference.builtin_only
                # Seeds of their own per object: no two objects' pixels share a random stream.
                a, t = render_pixel_centres(mi, mi_scene, n, seed=2 * k, python_plugins=plugins, first_sample=first_sample,
                                            pixels=pixels)  # fmt: skip
                b, _ = render_pixel_centres(mi, mi_scene, n, seed=2 * k + 1, python_plugins=plugins,
                                            first_sample=first_sample, pixels=pixels)  # fmt: skip
                image += a
                second += b
            else:
                a, t = render_mitsuba(mi, mi_scene, n, python_plugins=not reference.builtin_only)
                image += np.where(pixels[..., None], a, 0.0).astype(np.float32)
            seconds += t
            del mi_scene
        mi.set_variant("llvm_ad_rgb")
        return ReferenceRender("physical", reference.description, image, seconds, n, variant, second_image=second)
    mi_scene = build_mitsuba_scene(mi, shown, bsdfs, n, reference.integrator, interiors, stochastic=reference.stochastic)
    second = None
    if reference.stochastic:
        # Every sample through the pixel centre, as the rasteriser shades: many samples
        # converge the paths and wavelengths without antialiasing what the atlas cannot.
        plugins = not reference.builtin_only
        image, seconds = render_pixel_centres(mi, mi_scene, n, python_plugins=plugins, first_sample=first_sample)
        second, _ = render_pixel_centres(mi, mi_scene, n, seed=1, python_plugins=plugins, first_sample=first_sample)
    else:
        image, seconds = render_mitsuba(mi, mi_scene, n, python_plugins=not reference.builtin_only)
    del mi_scene
    ref = ReferenceRender("physical", reference.description, image, seconds, n, variant, second_image=second)
    if reference.integrator is not None:  # an integrator of its own traces shadow rays
        ref.mask, ref.masked = cast_shadow_mask(mi, scene), CAST_SHADOW_NOTE
    mi.set_variant("llvm_ad_rgb")
    return ref


def speed_ratio(reference_seconds: float, atlas_seconds: float) -> float:
    """How many times faster the atlas frame is than the reference render."""
    return reference_seconds / atlas_seconds if atlas_seconds > 0 else math.inf
