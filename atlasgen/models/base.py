"""The interface every material model implements (docs/adding-a-model.md), and the default way its slices are encoded."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from atlasgen.contract import HEIGHT, WIDTH, texel_centres
from atlasgen.errors import ManifestError, shorten
from atlasgen.io.atlas import as_atlas
from atlasgen.io.fields import Param
from atlasgen.io.manifest import LutRepresentation, MaterialEntry
from atlasgen.optics.interpolation import sample_slice
from atlasgen.optics.quantize import unorm_scale
from atlasgen.optics.specular import half_vector_cosine, renderer_f_cos

__all__ = ["Model", "SliceSet", "DraftSlices", "EncodedSlices", "Reference", "RadianceRebuild", "PhysicalFCos", "encode_scaled",
           "MODEL_REFERENCE", "BRDF_REFERENCE", "THIN_FILM_REFERENCE", "THIN_SHEET_REFERENCE"]  # fmt: skip

# Names of atlasgen's Mitsuba BSDF plugins (:mod:`atlasgen.models.mitsuba_bsdfs` registers them).
#: The renderer's equation with the exact model in place of the atlas.
MODEL_REFERENCE = "atlasgen_model"
#: A separable material's source BSDF.
BRDF_REFERENCE = "atlasgen_brdf"
#: The iridescent model's thin-film microfacet BSDF.
THIN_FILM_REFERENCE = "atlasgen_thinfilm"
#: The backlit model's thin sheet: diffuse reflection and diffuse transmission.
THIN_SHEET_REFERENCE = "atlasgen_thinsheet"


@dataclass
class SliceSet:
    """Float slices a model wants in the atlas: ``values`` is ``(n, HEIGHT, WIDTH, 4)`` linear RGBA."""

    values: np.ndarray
    extra: dict = field(default_factory=dict)  # model-specific manifest fields (must be deterministic)
    timings: dict = field(default_factory=dict)  # seconds per stage, for atlas.timings.json


@dataclass
class DraftSlices:
    """A bake's slices before the figures that only describe them are measured (:meth:`Model.bake_draft`).

    ``slices.values`` and every field the atlas, the include and the renderer read are the full
    bake's; ``slices.extra`` lacks the figures ``complete()`` measures. ``complete()`` returns
    exactly what :meth:`Model.bake` returns for the same parameters, reusing the draft's work.
    """

    slices: SliceSet
    complete: Callable[[], SliceSet]


@dataclass
class EncodedSlices:
    """Slices mapped into [0, 1] for 8-bit storage.

    A renderer recovers the linear value as ``stored * scale + bias``, with one
    ``(rgb, alpha)`` pair of each per slice.
    """

    stored: np.ndarray  # (n, H, W, 4) in [0, 1]
    scale: np.ndarray  # (n, 2): rgb, alpha
    bias: np.ndarray  # (n, 2)
    clamped_fraction: float
    extra: dict = field(default_factory=dict)  # model-specific manifest fields (e.g. per-factor scale/bias)


@dataclass
class RadianceRebuild:
    """A CPU twin of the lighting pass for one material (:meth:`Model.radiance_rebuilds`).

    ``radiance(n, l, v, albedo, gloss, irradiance)`` is the radiance one light adds at N
    pixels: unit normals, light and view directions ``(N, 3)``, linear albedo ``(N, 3)``,
    gloss ``(N,)`` and the light's irradiance normal to its direction ``(N, 3)``; it
    returns ``(N, 3)``. ``description`` says what it reads, for the validation report.
    """

    description: str
    radiance: Callable[..., np.ndarray]


@dataclass
class Reference:
    """A Mitsuba reference of one material: the BSDF dict and how the scene must be rendered.

    ``bsdf`` goes into ``mi.load_dict`` (atlasgen's own plugins are registered by
    :func:`atlasgen.models.mitsuba_bsdfs.register_bsdfs`). ``integrator`` replaces the
    default ``atlasgen_direct``; ``interior`` is a medium for closed objects (open planes
    get a diffuse stand-in); ``stochastic`` renders with ``--physical-spp`` samples;
    ``builtin_only`` means no Python plugin may be live (keeps Dr.Jit's symbolic loops).
    """

    bsdf: dict
    description: str
    variant: str = "llvm_ad_rgb"
    integrator: dict | None = None
    interior: dict | None = None
    stochastic: bool = False
    builtin_only: bool = False


@dataclass(frozen=True)
class PhysicalFCos:
    """A model's physical reference as a NumPy function (:meth:`Model.physical_f_cos`).

    ``f_cos(l, v)`` is f |cos(theta_l)| in linear RGB, ``(N, 3)``, at unit ``(N, 3)`` light and
    view directions in the local frame (n = +z): v on the upper hemisphere, l on either side
    (a transmitting reference is non-zero below). It is the function the model's
    :meth:`Model.fit_physical` fits, so the error against it is the error against what the
    ``from = "physical"`` slice was made for. ``alpha`` is its lobe's GGX roughness, where it
    has one (the error sampler's lobe width; ``None``: measured, or no lobe); ``transmits``
    whether f cos is non-zero for l below the surface (the error is then integrated over l in
    the whole sphere, :func:`atlasgen.separable.error.sample_error_pairs`); ``source`` the
    separable model's source parameters of the same BRDF (``source = "thin_film"``, ...),
    where one exists, else ``no_source`` says why there is none (no separable candidates).
    """

    f_cos: Callable[[np.ndarray, np.ndarray], np.ndarray]
    description: str
    alpha: float | None = None
    transmits: bool = False
    source: dict | None = None
    no_source: str = ""


def encode_scaled(values: np.ndarray, rgb_scale="auto", alpha_scale="auto") -> EncodedSlices:
    """Divide each slice by a scale so it fits UNORM8; report what had to be clamped.

    With ``"auto"`` the scale is the peak of the slice's RGB (or A),
    :func:`~atlasgen.optics.quantize.unorm_scale`: nothing clamps, and every slice spends all
    256 codes on its own range (a dim specular A of 0.07 would otherwise get 18). A fixed
    scale trades range for precision, and what exceeds it is clamped and counted. Negative
    values (never produced by a valid LUT model) clamp to 0 and are counted too.
    """
    n = values.shape[0]
    peaks = np.stack([values[..., :3].max(axis=(1, 2, 3)), values[..., 3].max(axis=(1, 2))], axis=1)
    scale = np.empty((n, 2))
    for g, fixed in enumerate((rgb_scale, alpha_scale)):
        scale[:, g] = [unorm_scale(p) for p in peaks[:, g]] if fixed == "auto" else float(fixed)
    scaled = values / scale[:, [0, 0, 0, 1]][:, None, None, :]
    out_of_range = (scaled > 1.0) | (scaled < 0.0)
    stored = np.clip(scaled, 0.0, 1.0)
    return EncodedSlices(stored, scale, np.zeros((n, 2)), float(out_of_range.mean()))


class Model:
    """A material model: a TOML ``type``, its parameter schema, its evaluation, and everything
    the renderer, validation and the reports need of it (docs/adding-a-model.md).

    Subclasses set ``type_name``, ``params`` and ``reference``, and implement
    :meth:`evaluate`. The defaults of every other hook describe a *table* model: one
    (N.L, N.V) slice that the renderer samples with ``atlas_sample`` and shades with its
    own equation (:mod:`atlasgen.optics.specular`). A model that stores something else
    (the separable model's factors) overrides :meth:`bake`, :meth:`encode`,
    :meth:`finalize`, sets ``custom_lighting`` with :meth:`include_wgsl` and
    :meth:`lighting_wgsl`, and supplies its own :meth:`model_reference`,
    :meth:`radiance_rebuilds` and :meth:`describe_representation`.
    """

    type_name: ClassVar[str] = ""
    params: ClassVar[tuple[Param, ...]] = ()
    reference: ClassVar[str] = ""
    #: The lighting pass shades this model's materials with :meth:`lighting_wgsl` instead of
    #: the (N.L, N.V) table lookup; the renderer compiles that code in only for scenes that
    #: show such a material.
    custom_lighting: ClassVar[bool] = False
    #: Validation holds the atlas image to the PSNR/FLIP goals against the model reference
    #: (:data:`atlasgen.validate.run.GOAL_PSNR_DB`); models whose error is claimed in the
    #: manifest instead (:meth:`claimed_errors`) set False.
    validation_goals: ClassVar[bool] = True
    #: Parameters the physical reference deliberately does not reproduce, each with the reason
    #: (docs/validation.md lists them too). Every other parameter must change the reference
    #: (tests/models/test_physical_coverage.py).
    physical_omissions: ClassVar[dict[str, str]] = {}
    #: Why :meth:`physical_reference` returns ``None`` for this model ("" for a model that has one).
    no_physical_reference: ClassVar[str] = ""
    #: The model reference is the physical BSDF itself (a separable material's source): validation
    #: judges the look against it where there is no physical reference of its own.
    model_reference_is_physical: ClassVar[bool] = False
    #: Why a model with a physical reference that is not one plain BSDF has no :meth:`physical_f_cos`
    #: ("" where it has one or needs none): the cost-against-error report says it for the material.
    no_physical_f_cos: ClassVar[str] = ""

    def check(self, values: dict, path) -> None:
        """Cross-parameter checks beyond each parameter's own range; raise MaterialError."""

    def evaluate(self, values: dict, n_dot_l: np.ndarray, n_dot_v: np.ndarray) -> np.ndarray:
        """Linear RGBA at arbitrary (N.L, N.V): RGB the diffuse response, A the specular scale."""
        raise NotImplementedError

    def apply_budget(self, values: dict, budget: float, path) -> dict:
        """Parameters for a material that carries an ``error_budget``.

        LUT models keep theirs: the bake meets the budget by supersampling
        (:mod:`atlasgen.bake.adaptive`). Models with their own knob (the separable term
        count) map the budget onto it here.
        """
        return values

    def flags(self, values: dict) -> dict:
        """Render-time requests recorded in the manifest (e.g. ``{"outline": True}``)."""
        return {}

    def slice_count(self, values: dict) -> int:
        """The slices a bake of ``values`` gives, or the most it may give where only the bake knows."""
        return 1

    def fewest_slices(self, values: dict) -> int:
        """The fewest slices a bake of ``values`` may give: :meth:`slice_count` where the count is fixed. The
        bake refuses materials that cannot fit the atlas even so before it bakes any of them."""
        return self.slice_count(values)

    def bake(self, values: dict) -> SliceSet:
        """Evaluate at the texel centres of one slice.

        The axes go in as a row and a column, so a model that separates its N.L and
        N.V work (a spectral film, a profile integral) computes each only once.
        """
        nl, nv = texel_centres(WIDTH, HEIGHT)
        rgba = np.asarray(self.evaluate(values, nl[None, :], nv[:, None]), dtype=np.float64)
        rgba = np.broadcast_to(rgba, (HEIGHT, WIDTH, 4))
        return SliceSet(np.array(rgba).reshape(1, HEIGHT, WIDTH, 4))

    def bake_draft(self, values: dict) -> DraftSlices | None:
        """The slices of :meth:`bake` first, their error figures later (:class:`DraftSlices`), for a
        preview that shows the picture before the figures; None (the default): nothing to defer,
        :meth:`bake` it whole. :meth:`finalize` is handed the draft's slices too."""
        return None

    def encode(self, values: dict, slices: SliceSet, rgb_scale="auto", alpha_scale="auto") -> EncodedSlices:
        return encode_scaled(slices.values, rgb_scale, alpha_scale)

    def check_cached(self, extra: dict) -> None:
        """Raise ValueError where the fields a bake of this model recorded beside its slices (``extra``, read back
        from a bake cache entry) name what :meth:`encode` and :meth:`finalize` would look up and fail on. The
        entry's digest finds damage, not an entry forged with a digest of its own; the default checks nothing."""

    def finalize(self, values: dict, slices: SliceSet, encoded: EncodedSlices, decoded: np.ndarray) -> dict:
        """Extra manifest fields measured on the 8-bit result.

        ``decoded`` is what a sampler returns at level 0, ``(n, H, W, 4)``, sRGB
        already decoded, before the slice's scale and bias.
        """
        return {}

    # -- shader -----------------------------------------------------------------------------------
    @classmethod
    def include_wgsl(cls, entries: list[MaterialEntry]) -> str:
        """WGSL only this model type adds to the WGSL include, given its manifest entries."""
        return ""

    @classmethod
    def include_declarations(cls, entries: list[MaterialEntry]) -> list:
        """Shader declarations (:mod:`atlasgen.shaders.lang`) this model type adds to every
        include language (WGSL, GLSL, HLSL), given its manifest entries."""
        return []

    @classmethod
    def check_entry(cls, entry: MaterialEntry, shown: str, where: str) -> None:
        """Raise :class:`~atlasgen.errors.ManifestError` (naming ``shown`` and the field under ``where``) where a
        manifest ``entry`` of this model's type lacks what its shader code and reports are made from, or holds
        what the model would refuse: a hand-edited manifest (a LUT entry given this model's type).

        The default, a LUT model's: the one slice every bake of it gives, with bias 0 (docs/atlas-format.md). A
        manifest edited to two slices, or to a bias of 1e30 that saturated every pixel, was rendered as it said."""
        if entry.slice_count != 1:
            raise ManifestError(shown, f"{where}.slice_count", f"expected 1 (a {cls.type_name} material is one "
                                f"slice), got {entry.slice_count}")  # fmt: skip
        if any(value != 0.0 for pair in entry.bias for value in pair):
            raise ManifestError(shown, f"{where}.bias", f"expected [[0.0, 0.0]] (a {cls.type_name} slice has no "
                                f"bias), got {shorten(str([list(pair) for pair in entry.bias]))}")  # fmt: skip

    @classmethod
    def include_data(cls, entries: list[MaterialEntry]) -> bytes:
        """The binary side-car this model type writes beside the atlas (the separable model:
        ``X.separable.bin``, its rebuild's data table), or ``b""`` for none."""
        return b""

    @classmethod
    def lighting_wgsl(cls, entry: MaterialEntry) -> str:
        """A WGSL expression for f cos(theta_l) of ``entry`` in the lighting pass (``custom_lighting`` only).

        In scope: ``atlas`` (``texture_2d_array<f32>``), ``samp`` (its linear sampler),
        ``material`` (the g-buffer ID, ``u32``) and unit ``n``, ``l``, ``v``
        (``vec3<f32>``). The renderer adds L += E * albedo * f cos per light
        (lighting.wgsl); the functions it calls come from :meth:`include_wgsl`.
        """
        raise NotImplementedError(f"model {cls.type_name!r} sets custom_lighting but has no lighting_wgsl")

    # -- references and validation -----------------------------------------------------------------
    def renderer_f_cos(self, values: dict, albedo, gloss: float, n_dot_l, n_dot_v, n_dot_h, lv_degenerate=None):
        """f cos(theta_l) of the renderer's equation with this model's exact values in place of the atlas.

        f cos = albedo * M.rgb / pi + M.a * D(N.H) V(N.L, N.V) max(N.L, 0), the GGX lobe of
        roughness alpha(gloss) (:func:`atlasgen.optics.specular.renderer_f_cos`), with
        M = ``evaluate(values, clamp(N.L, -1, 1), clamp(N.V, 0, 1))``: the clamp is the
        sampler's clamp-to-edge addressing. Returns ``(..., 3)``.
        """
        nl = np.asarray(n_dot_l, dtype=np.float64)
        nv = np.asarray(n_dot_v, dtype=np.float64)
        m = self.evaluate(values, np.clip(nl, -1.0, 1.0), np.clip(nv, 0.0, 1.0))
        return renderer_f_cos(m, albedo, gloss, nl, nv, n_dot_h, lv_degenerate)

    def model_reference(self, values: dict, albedo=(1.0, 1.0, 1.0), gloss: float = 0.5) -> Reference | None:
        """The Mitsuba reference of what the atlas approximates: for a table model the renderer's
        equation with the exact model (``atlasgen_model``, evaluating :meth:`renderer_f_cos`).

        ``None`` where no reference can be built (validation then refuses the material).
        """
        material = {"type": self.type_name, "params": values, "albedo": [float(a) for a in albedo], "gloss": float(gloss)}
        return Reference({"type": MODEL_REFERENCE, "material": json.dumps(material, sort_keys=True)},
                         f"{self.type_name} model, exact, in the renderer's equation")  # fmt: skip

    def physical_reference(self, values: dict, albedo=(1.0, 1.0, 1.0), gloss: float = 0.5) -> Reference | None:
        """A physically based Mitsuba reference, where the model has one; ``None`` otherwise
        (``no_physical_reference`` then says why).

        It describes the same material as ``values``: every parameter has a counterpart in it,
        except those in ``physical_omissions``.
        """
        return None

    def physical_brdf_source(self, values: dict):
        """``(params, description)`` where this material *is* its physical BRDF: the separable model's
        source parameters (``source``, ``alpha``, ``bsdf``, ...) of it; ``None`` (the default) where the
        physical reference is :meth:`physical_reference` (:mod:`atlasgen.models.physical_error`)."""
        return None

    def fit_physical(self, values: dict, gloss: float) -> SliceSet | None:
        """The slice fitted to this model's physical reference for the renderer gloss ``gloss``
        (``from = "physical"``), where the model fits it itself; ``None`` (the default) where
        its physical reference is one plain Mitsuba BSDF, which
        :func:`atlasgen.models.physical_fit.bake_from_physics` projects onto the renderer's
        equation. An override also answers :meth:`physical_fit_problem` with ``None``.

        The returned ``SliceSet.extra["fit"]`` describes the fit: at least ``from``
        (``"physical"``), ``reference`` (a description) and ``gloss``.
        """
        return None

    def physical_f_cos(self, values: dict, gloss: float) -> PhysicalFCos | None:
        """This model's physical reference for an object of albedo 1 and renderer gloss ``gloss``
        as NumPy f cos (:class:`PhysicalFCos`), where it is a BSDF evaluated outside Mitsuba's
        own plugins (a spectral film, a thin sheet); ``None`` (the default) otherwise.

        A reference that is one plain Mitsuba BSDF needs none: :mod:`atlasgen.models.physical_error`
        evaluates it through Mitsuba (:func:`atlasgen.models.physical_fit.plain_bsdf_reference`).
        A model that sets it fits the same function in :meth:`fit_physical`; a model whose
        reference is no BSDF at all (a volume) sets ``no_physical_f_cos`` instead.
        """
        return None

    def physical_fit_problem(self, values: dict) -> str | None:
        """Why ``from = "physical"`` cannot bake this material (one clause), or ``None`` where it can.

        The default: a model with its own :meth:`fit_physical` can; any other needs a physical
        reference that is one plain BSDF (:func:`atlasgen.models.physical_fit.plain_bsdf_reference`).
        """
        return None

    def unused_fields(self, values: dict) -> dict[str, str]:
        """Fields these ``values`` leave unread, each with when it is read (one clause, e.g. "with
        source = 'blinn_phong'"): a material file that gives one is refused, since its value would be
        dropped without a word. The default: every field is read."""
        return {}

    def fit_limits(self, values: dict) -> list[str]:
        """What this material asks of a slice that no slice holds, one clause each, known before it is
        baked: the bake's error warning (:func:`atlasgen.bake.quality.assess_material`) gives them as its
        cause instead of "an unreachable fit". The default: none known."""
        return []

    def unheld_inputs(self, values: dict) -> list[str]:
        """What the material's definition asks for that its slices do not hold at all, and the bake leaves out,
        one clause each (a MaterialX document's emission or opacity): the bake warns with them
        (:func:`atlasgen.bake.quality.assess_material`), so nothing is dropped without a word. The default: none."""
        return []

    def flattened_inputs(self, values: dict) -> list[str]:
        """Inputs of the material's definition that a texture or node graph drives, baked at one value because the
        bake was asked to flatten them (``atlasgen bake --flatten``), one clause each: the bake warns with them, as
        the baked material is the document's at that value only. The default: none."""
        return []

    def nonfinite_fault(self, values: dict) -> tuple[str, str] | None:
        """Where a bake that met non-finite samples of this material's source points the user: ``(field, what was
        expected)``, for a definition that cannot set ``nonfinite_tolerance`` (a MaterialX document) or whose
        input at fault the model can tell. The default, None: the material file's ``type`` (or ``bsdf``), and
        ``nonfinite_tolerance`` as the way to bake them as 0."""
        return None

    def radiance_rebuilds(self, entry: MaterialEntry, atlas, float_slices=None) -> dict[str, RadianceRebuild]:
        """CPU twins of the lighting pass for ``entry``, by what they read: ``"8bit"`` the
        atlas's stored texels (what the GPU samples) and, where it can be computed,
        ``"float"`` the model's own float data sampled the same way.

        ``atlas`` is an :class:`~atlasgen.io.atlas.Atlas` already read, or its path;
        ``float_slices`` ``(n, H, W, 4)`` the material's float slices where the caller has them
        (the bake cache), else they are baked again.

        Validation rebuilds the renderer's image from its g-buffer with each. With both,
        the atlas's error against the model reference splits into resolution and filtering
        (float), 8-bit quantization (8bit against float) and the GPU's own precision (GPU
        against 8bit); with ``"8bit"`` only, the rebuild is reported as a reference of its
        own. A table model samples its slice at mip level 0, bilinearly (or nearest for
        ``flags.nearest``), in the renderer's equation.
        """
        nearest = entry.flag("nearest")
        table = (self.bake(entry.params).values if float_slices is None else float_slices)[0]
        return {
            "float": RadianceRebuild("the model's float table at the texel centres, sampled as the renderer does",
                                     _table_radiance(_SampledTable(table, nearest))),
            "8bit": RadianceRebuild("the baked 8-bit slice, sampled as the renderer does",
                                    _table_radiance(_SampledTable(as_atlas(atlas).decode_slice(entry.first_slice), nearest))),
        }  # fmt: skip

    def claimed_errors(self, entry: MaterialEntry) -> dict | None:
        """The error the bake claims in the manifest, for validation to set beside what a scene
        measures: ``{"relative_rms_8bit", "relative_rms_float", "terms"}`` (relative RMS of
        f cos over uniform (l, v) pairs), or ``None`` where the manifest claims none."""
        return None

    # -- reports ---------------------------------------------------------------------------------
    def describe_representation(self, entry: MaterialEntry) -> str:
        """One line on how ``entry`` is stored, for the library report."""
        rep = entry.representation
        if isinstance(rep, LutRepresentation):
            return f"LUT, supersampling {rep.supersampling}x (budget {rep.error_budget:g})"
        return "LUT, point-sampled"


class _SampledTable(Model):
    """A baked (H, W, 4) slice in a model's place: :meth:`evaluate` samples it as the renderer does."""

    def __init__(self, table, nearest=False):
        self.table = np.asarray(table, dtype=np.float64)
        self.nearest = nearest

    def evaluate(self, values, n_dot_l, n_dot_v):
        return sample_slice(self.table, n_dot_l, n_dot_v, self.nearest)


def _table_radiance(model: Model):
    """The radiance one light adds through the renderer's equation with ``model`` as the slice."""

    def radiance(n, l, v, albedo, gloss, irradiance):
        nh, degenerate = half_vector_cosine(l, v, n)
        nl, nv = (n * l).sum(1), (n * v).sum(1)
        out = np.zeros((len(n), 3))
        for g in np.unique(gloss):  # renderer_f_cos takes one gloss (one roughness): group the pixels by it
            sel = gloss == g
            f = model.renderer_f_cos({}, albedo[sel], float(g), nl[sel], nv[sel], nh[sel], lv_degenerate=degenerate[sel])
            out[sel] = irradiance[sel] * f
        return out

    return radiance
