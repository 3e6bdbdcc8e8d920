"""Bake materials and render each on the standard ball, on one renderer that stays warm.

A :class:`Previewer` holds the GPU device, its compiled pipelines and the ball's mesh across
previews: the first one pays for all of them, and each later one bakes the materials (from the
per-material bake cache: only a changed file is baked again), hands the new atlas to the
renderer (:meth:`~atlasgen.render.renderer.Renderer.set_atlas`, which recompiles the lighting
shader only when the generated include changed) and renders. Every step is timed.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from atlasgen.bake.pipeline import BakeResult, bake_atlas
from atlasgen.contract import LAYERS
from atlasgen.errors import InputError, MaterialError, OutputNameError
from atlasgen.io.atomic import refuse_set_link, write_file_atomically
from atlasgen.io.dds import DXGI_FORMAT_R8G8B8A8_UNORM_SRGB
from atlasgen.io.images import encode_png
from atlasgen.io.manifest import Manifest, MaterialEntry
from atlasgen.io.output_paths import check_cache_folder, check_output_paths, check_suffix
from atlasgen.io.package_data import package_data_path
from atlasgen.materials.material import check_unique_names, find_material_files, read_material, read_materials
from atlasgen.materials.scene import Scene
from atlasgen.preview.label import draw_label, label_lines
from atlasgen.preview.reference import MAX_SPP, ReferenceShot, load_reference_mitsuba, reference_lines, refine_reference
from atlasgen.preview.scene import ball_mesh_file, parse_preview_scene, preview_scene_data
from atlasgen.preview.sheet import arrange_sheet
from atlasgen.render.atlas_texture import RenderAtlas
from atlasgen.render.device import get_device
from atlasgen.render.meshes import make_material_ball
from atlasgen.render.output import display_codes
from atlasgen.render.renderer import Renderer

__all__ = [
    "DEFAULT_CACHE_DIR",
    "DEFAULT_OUTPUT_DIR",
    "FLOOR_MATERIAL",
    "Preview",
    "Shot",
    "compose_picture",
    "Previewer",
    "default_output",
    "check_preview_output",
]

#: The bake cache ``make`` fills (Makefile CACHE_DIR): a material ``make`` has baked is a hit here,
#: and one previewed here is a hit for ``make``. Entries are keyed by the file's content and the
#: bake code, so sharing them can cost a re-bake, never a wrong slice.
DEFAULT_CACHE_DIR = Path("build/cache")
#: Where the picture goes without ``-o``: beside the other build outputs.
DEFAULT_OUTPUT_DIR = Path("build/preview")
#: The floor's material file, shipped with atlasgen.
FLOOR_MATERIAL = ("preview", "atlasgen-preview-floor.toml")
#: zlib level of the preview's PNGs: the encoder's default, 6, spends more CPU on each picture for a
#: smaller file, and a watch writes one per save. The bytes depend on the pixels alone either way.
PNG_COMPRESSION = 2


@dataclass
class Shot:
    """One material's atlas picture, as rendered, and what its reference needs."""

    entry: MaterialEntry
    scene: Scene
    radiance: np.ndarray
    lines: list[str]
    #: The g-buffer read-backs (``id``: the material-ID AOV), kept when a reference was asked for.
    aovs: dict | None = None

    @property
    def name(self) -> str:
        return self.entry.name


def compose_picture(shots: list[Shot], references: dict | None = None) -> np.ndarray:
    """The labelled pictures of ``shots``, a contact sheet for several; with ``references`` (name ->
    :class:`~atlasgen.preview.reference.ReferenceShot`, a name missing while its first pass renders)
    each atlas picture has its reference beside it, on the right."""
    cells = []
    for shot in shots:
        exposure = shot.scene.settings.exposure
        cell = draw_label(display_codes(shot.radiance, exposure), shot.lines)
        if references is not None:
            ref = references.get(shot.name)
            if ref is not None and ref.image is not None:
                codes = display_codes(ref.image, exposure)
            else:
                codes = np.full((*shot.radiance.shape[:2], 3), 24, np.uint8)  # no image (yet): a dark panel
            cell = arrange_sheet([cell, draw_label(codes, reference_lines(ref))], columns=2)
        cells.append(cell)
    return arrange_sheet(cells)


@dataclass
class Preview:
    """One preview: its PNG, the materials it shows and where the time went (seconds)."""

    png: bytes
    names: list[str]
    #: read, bake, then device and pipelines (the first preview: the GPU device, the renderer's pipelines and
    #: the atlas's upload) or upload (later ones: the new atlas handed to the renderer), render (the frames,
    #: with any shader compiled for them, and their read-back), label, encode (PNG) and, written, write
    timings: dict[str, float] = field(default_factory=dict)
    #: The files the preview was made from: the material files, then the files they name.
    inputs: list[Path] = field(default_factory=list)
    #: Whether the lighting shader was compiled for this preview (a new include).
    compiled: bool = False
    #: Each material's picture, in order, and the atlas's manifest (the floor's entry included).
    shots: list[Shot] = field(default_factory=list)
    manifest: Manifest | None = None
    #: Each material's physical reference (``--reference``), by name; None without one asked for.
    references: dict | None = None
    #: ``preview(drafts=True)``: name -> completion of each material drawn from a draft bake, its label's
    #: error still to measure (:meth:`Previewer.complete`); empty once complete, or for a full bake.
    pending: dict = field(default_factory=dict)
    #: The materials shown, the floor last, and the bake they were drawn from (for :meth:`Previewer.complete`).
    materials: list = field(default_factory=list, repr=False)
    bake: BakeResult | None = field(default=None, repr=False)
    use_cache: bool = True
    #: :meth:`Previewer.complete`'s steps, s: measure (the drafts' figures and the atlas again), label, encode.
    label_timings: dict[str, float] = field(default_factory=dict)

    @property
    def seconds(self) -> float:
        return sum(self.timings.values())


def default_output(paths) -> Path:
    """``build/preview/NAME.png`` for one material file (its stem) or one folder (its name), else
    ``build/preview/contact-sheet.png``.

    >>> default_output(["materials/skin.toml"]).as_posix(), default_output(["materials"]).as_posix()
    ('build/preview/skin.png', 'build/preview/materials.png')
    >>> default_output(["a.toml", "b.toml"]).as_posix()
    'build/preview/contact-sheet.png'
    """
    paths = [Path(p) for p in paths]
    if len(paths) == 1:
        name = paths[0].stem if paths[0].suffix.lower() == ".toml" else Path(os.path.abspath(paths[0])).name
        return DEFAULT_OUTPUT_DIR / f"{name or 'preview'}.png"
    return DEFAULT_OUTPUT_DIR / "contact-sheet.png"


def check_preview_output(output, sources, cache_dir=None) -> None:
    """Refuse an output that is not a ``.png``, is a folder, would overwrite a material file or lies in a folder
    that takes no new file, and a ``cache_dir`` that cannot be written (None: no cache)."""
    check_suffix(output, "the preview (-o)", (".png",))
    inputs = [(f, "a material file") for f in find_material_files(sources)]
    check_output_paths([(Path(output), "the preview (-o)")], inputs)
    refuse_set_link(output)  # before rendering: write_file_atomically refuses it again
    if cache_dir is not None:
        cache, image = Path(os.path.realpath(cache_dir)), Path(os.path.realpath(output))
        if cache == image or image in cache.parents:
            # The cache was made and filled under the preview's name, and the preview then failed on the folder.
            where = "is" if cache == image else "lies under"
            raise OutputNameError(f"{Path(cache_dir).as_posix()}: --cache {where} the preview (-o); expected a cache "
                                  "folder of another name")  # fmt: skip
        check_cache_folder(cache_dir, "--cache")
        # The ball's mesh and the environment are kept in a folder of the cache's: a file of its name failed the
        # preview after its bake with "cannot write output folder (File exists)", naming no option.
        check_cache_folder(Path(cache_dir) / "preview", "--cache's preview folder")


class Previewer:
    """Renders materials on the standard ball (:mod:`atlasgen.preview.scene`), keeping the GPU warm.

    Parameters
    ----------
    cache_dir
        The per-material bake cache (:mod:`atlasgen.bake.cache`); None bakes every time.
    ctx
        A :class:`~atlasgen.render.device.GpuContext`; the shared one by default.
    """

    def __init__(self, cache_dir=DEFAULT_CACHE_DIR, ctx=None):
        self.cache_dir = None if cache_dir is None else Path(cache_dir)
        self.ctx = ctx
        self.renderer: Renderer | None = None
        self.ball = make_material_ball()
        self.floor = read_material(package_data_path(*FLOOR_MATERIAL))
        self._ball_file: Path | None = None

    @property
    def ball_file(self) -> Path:
        """The ball's mesh file the scene names (:func:`~atlasgen.preview.scene.ball_mesh_file`), beside the
        bake cache, written on first use and again where it has gone since (a watch outlives `make clean`, whose
        removed cache failed every later save on the missing mesh)."""
        if self._ball_file is None or not self._ball_file.is_file():
            self._ball_file = ball_mesh_file(self.ball, None if self.cache_dir is None else self.cache_dir / "preview")
        return self._ball_file

    def scene_for(self, name: str) -> Scene:
        """The scene a preview renders for the material ``name`` (:mod:`atlasgen.preview.scene`)."""
        return parse_preview_scene(preview_scene_data(name, self.floor.name, self.ball_file))

    def preview(self, paths, use_cache: bool = True, aovs: bool = False, drafts: bool = False, output=None) -> Preview:
        """Bake the materials under ``paths`` into one atlas and render each: one labelled picture,
        or a contact sheet of them. ``use_cache=False`` bakes them afresh (a file they name changed,
        which the cache's key does not cover). ``aovs`` keeps each picture's g-buffer read-backs (a
        reference needs the material-ID AOV). ``drafts`` bakes what the cache lacks as drafts where the
        model has them (:meth:`~atlasgen.models.base.Model.bake_draft`: a separable material's SVD and
        choice of K without the report sample's figures): the picture is the full bake's, its label says
        the error is being measured, and :meth:`complete` measures it (``Preview.pending``). ``output``, the
        picture's path where it is to be written, is refused where it is a file the materials read.

        Raises the bake's and the renderer's errors (:class:`~atlasgen.errors.MaterialError` with
        the file and field, :class:`~atlasgen.errors.BackendError` without a GPU) before anything is
        written.
        """
        timings: dict[str, float] = {}
        t0 = time.perf_counter()
        materials = read_materials(paths)
        if not materials:
            shown = ", ".join(Path(p).as_posix() for p in paths)
            raise InputError(f"{shown}: no material files; expected .toml files, or folders holding them")
        # The floor first: a material named as it is is the one refused (the floor's installed file was named, which
        # no user can edit).
        check_unique_names([self.floor, *materials])
        self._check_room(materials)
        # Each material's file and the files it reads (a measured BSDF's data, a bitmap, a document's xi:includes),
        # absolute where a file named them relatively: read_material resolved them (Material.includes).
        inputs = [Path(m.source) for m in materials] + [Path(f) for m in materials for f in m.includes]
        if output is not None:
            # A picture written over a texture the material reads replaced it, and a watch then saw its own write
            # as a change and drew again, forever (check_preview_output sees the material files alone).
            check_output_paths([(Path(output), "the preview (-o)")],
                               [(Path(f), f"a file the material file of {m.name!r} includes") for m in materials
                                for f in m.includes])  # fmt: skip
        t1 = time.perf_counter()
        timings["read"] = t1 - t0
        result = bake_atlas([*materials, self.floor], cache_dir=self.cache_dir if use_cache else None, drafts=drafts)
        atlas = RenderAtlas(result.levels, result.dxgi_format == DXGI_FORMAT_R8G8B8A8_UNORM_SRGB, result.manifest,
                            result.include, "the preview's atlas")  # fmt: skip
        t2 = time.perf_counter()
        timings["bake"] = t2 - t1
        if self.renderer is None:
            self.ctx = self.ctx or get_device()
            t_device = time.perf_counter()
            timings["device"] = t_device - t2
            self.renderer = Renderer(atlas, self.ctx)
            self.renderer.add_mesh(self.ball_file, self.ball)
            if self.cache_dir is not None:  # the sky, prefiltered once for every preview to come
                self.renderer.environment.cache_dir = self.cache_dir / "preview"
            compiled = True
            t3 = time.perf_counter()
            timings["pipelines"] = t3 - t_device
        else:
            compiled = self.renderer.set_atlas(atlas)
            t3 = time.perf_counter()
            timings["upload"] = t3 - t2
        shots, spent = self._render_shots(materials, result, aovs)
        timings.update(spent)
        t4 = time.perf_counter()
        png = encode_png(arrange_sheet([cell for cell, _ in shots]), compression=PNG_COMPRESSION)
        timings["encode"] = time.perf_counter() - t4
        return Preview(png, [m.name for m in materials], timings, inputs, compiled, [shot for _, shot in shots],
                       result.manifest, pending=dict(result.drafts), materials=[*materials, self.floor], bake=result,
                       use_cache=use_cache)  # fmt: skip

    def _render_shots(self, materials, result: BakeResult, aovs: bool) -> tuple[list, dict]:
        """Each material's labelled picture and :class:`Shot`, and the time of ``render`` and ``label``."""
        entries = {e.name: e for e in result.manifest.materials}
        shots, spent = [], {"render": 0.0, "label": 0.0}
        for material in materials:
            t = time.perf_counter()
            scene = self.scene_for(material.name)
            frame = self.renderer.render(scene, aovs=aovs)
            codes = display_codes(frame.radiance, scene.settings.exposure)
            t_render = time.perf_counter()
            entry = entries[material.name]
            shot = Shot(entry, scene, np.asarray(frame.radiance, np.float32), label_lines(entry, material.name in result.drafts),
                        frame.aovs if aovs else None)  # fmt: skip
            shots.append((draw_label(codes, shot.lines), shot))
            spent["render"] += t_render - t
            spent["label"] += time.perf_counter() - t_render
        return shots, spent

    def _check_room(self, materials) -> None:
        """Refuse, naming the floor, materials that leave its slice no room: the bake's own refusal would count the
        floor among the materials given (:func:`~atlasgen.bake.slots.assign_slices`, fewest slices as there)."""
        floor = self.floor.model.fewest_slices(self.floor.params)
        needed = sum(m.model.fewest_slices(m.params) for m in materials)
        if needed + floor > LAYERS:
            last = max(materials, key=lambda m: m.name)  # the one the bake's name order leaves without room
            raise MaterialError(last.source, None, f"the materials need {needed} slices and the preview's floor {floor}; "
                                f"expected at most {LAYERS - floor} for the materials (the atlas has {LAYERS})")  # fmt: skip

    def complete(self, preview: Preview, references: dict | None = None) -> Preview:
        """Measure the figures ``preview``'s drafts left out (``Preview.pending``: their completions, which
        also fill the bake cache), bake the atlas again from the full slices, and set each shot's entry and
        label, ``preview.manifest`` and ``preview.png`` (with ``references`` beside the pictures, as
        :func:`compose_picture`) to what a full bake's preview shows. The pictures are kept: a draft's
        texels and include are the full bake's; were they not, the pictures are rendered again. Timed in
        ``preview.label_timings``; nothing to do without pending drafts.
        """
        if not preview.pending:
            return preview
        t0 = time.perf_counter()
        baked = {name: complete() for name, complete in preview.pending.items()}
        result = bake_atlas(preview.materials, cache_dir=self.cache_dir if preview.use_cache else None, baked=baked)
        t1 = time.perf_counter()
        materials = preview.materials[:-1]
        same = result.include == preview.bake.include and all(
            np.array_equal(a, b) for a, b in zip(result.levels, preview.bake.levels)
        )
        if same:
            entries = {e.name: e for e in result.manifest.materials}
            for shot in preview.shots:
                shot.entry = entries[shot.name]
                shot.lines = label_lines(shot.entry)
        else:  # a model whose draft is not its bake: show what the full bake draws
            self.renderer.set_atlas(RenderAtlas(result.levels, result.dxgi_format == DXGI_FORMAT_R8G8B8A8_UNORM_SRGB,
                                                result.manifest, result.include, "the preview's atlas"))  # fmt: skip
            shots, _ = self._render_shots(materials, result, any(s.aovs is not None for s in preview.shots))
            preview.shots = [shot for _, shot in shots]
        t2 = time.perf_counter()
        preview.png = encode_png(compose_picture(preview.shots, references), compression=PNG_COMPRESSION)
        preview.manifest, preview.bake, preview.pending = result.manifest, result, {}
        preview.label_timings = {"measure": t1 - t0, "label": t2 - t1, "encode": time.perf_counter() - t2}
        return preview

    def add_references(self, preview: Preview, max_spp: int | None = None) -> Preview:
        """Render each material's physical reference of its scene (:mod:`atlasgen.preview.reference`) to
        convergence or the cap, and set ``preview.png`` to the pictures with their references beside them
        (timed as ``reference``). ``preview`` must have been made with ``aovs=True``.

        Raises :class:`~atlasgen.errors.BackendError` without Mitsuba's LLVM variant.
        """
        t = time.perf_counter()
        mi = load_reference_mitsuba()
        references: dict[str, ReferenceShot] = {}
        for shot in preview.shots:
            for ref in refine_reference(mi, shot.scene, shot.entry, preview.manifest, shot.radiance, shot.aovs or {},
                                        max_spp=max_spp or MAX_SPP):  # fmt: skip
                references[shot.name] = ref
        preview.references = references
        preview.png = encode_png(compose_picture(preview.shots, references), compression=PNG_COMPRESSION)
        preview.timings["reference"] = time.perf_counter() - t
        return preview

    def write(self, paths, output, use_cache: bool = True, reference: bool = False, max_spp: int | None = None,
              drafts: bool = False) -> Preview:  # fmt: skip
        """:meth:`preview` (with ``reference``, :meth:`add_references` too; ``drafts`` as there), then replace
        ``output`` with its PNG atomically (timed as ``write``).

        The output is checked first (:func:`check_preview_output`); a preview that fails leaves
        ``output`` as it was.
        """
        check_preview_output(output, paths, self.cache_dir)
        preview = self.preview(paths, use_cache, aovs=reference, drafts=drafts, output=output)
        if reference:
            self.add_references(preview, max_spp)
        t = time.perf_counter()
        write_file_atomically(output, preview.png)
        preview.timings["write"] = time.perf_counter() - t
        return preview
