"""The atlas manifest (``X.json``) as typed records, with its one reader and its one writer.

The bake builds a :class:`Manifest` and writes it with :func:`format_manifest` (one material
per line: readable in a diff, and fast to write); everything else reads it with
:func:`read_manifest`, which checks the format version and every field, and refuses a file
it cannot read with one line naming the file and the field::

    build/atlas.json: field 'materials[3].first_slice': expected an integer >= 0, got -1

A material entry holds the fields every model writes (:class:`MaterialEntry`) and, chosen by
the JSON keys present (never by the model's type name), typed model-specific parts:
``representation`` (how an error budget was met: :class:`LutRepresentation` or
:class:`SeparableRepresentation`) and ``factors`` (:class:`SeparableFactors`, how a separable
BRDF's factors are stored in its slices). Keys of no typed part stay in ``extra``, in order.
Serialising writes the keys in the bake's order, so ``format_manifest(read_manifest(p))``
reproduces the file's bytes.

The JSON Schema ``atlasgen/schemas/manifest.schema.json`` describes the same format for
other tools; the checks here do not depend on it. The format itself is docs/atlas-format.md.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Literal, TypeGuard, overload

from atlasgen import __version__
from atlasgen.contract import FORMAT_VERSION, LAYERS, MAPPING, NAME_PATTERN, SPECULAR_LOBE, material_constant
from atlasgen.errors import ManifestError, shorten
from atlasgen.io.atomic import write_file_atomically
from atlasgen.io.fields import fits_float32, is_number
from atlasgen.io.referenced_files import absolute_files, referenced_files
from atlasgen.io.text import loads_json, read_input_text

__all__ = [
    "MAX_MANIFEST_BYTES",
    "read_manifest_text",
    "read_slots",
    "Manifest",
    "MaterialEntry",
    "Dimensions",
    "ErrorSummary",
    "VolumeBleed",
    "BrdfError",
    "SeparableErrors",
    "SeparableFactors",
    "SeparableTransmission",
    "LutRepresentation",
    "SeparableRepresentation",
    "AnalyticRepresentation",
    "Fit",
    "read_manifest",
    "parse_manifest",
    "format_manifest",
    "write_manifest",
    "COMMON_KEYS",
]

_MISSING = object()
_ENCODINGS = {"srgb": 29, "linear": 28}  # encoding -> its DXGI format (docs/atlas-format.md)
_LAYOUTS = ("array", "volume")
_SHA256 = re.compile(r"[0-9a-f]{64}")
#: A material's ``constant``: the includes declare it by this name in WGSL, GLSL and HLSL.
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,254}")


def _is_sha256(value) -> bool:
    """A SHA-256 digest as lowercase hex."""
    return isinstance(value, str) and _SHA256.fullmatch(value) is not None


# ---- checking one JSON object ---------------------------------------------------------------------


def _describe(value) -> str:
    """A short, one-line rendering of a refused value."""
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, dict):
        return "an object"
    if value == []:
        return "an empty list"
    # A list shown too: [[1e+300, 1.0, 1.0], ...] says more than "a list of 2".
    text = json.dumps(value) if isinstance(value, str | list) else repr(value)
    limit = 80 if isinstance(value, list) else 40
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _is_int(value) -> TypeGuard[int]:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_finite(value) -> bool:
    return is_number(value) and math.isfinite(value)


class _Fields:
    """One JSON object being read: each accessor checks a field and names it in a refusal.

    Values are returned as parsed (an integer stays an integer where a number is
    expected), so writing them back gives the same JSON text.
    """

    def __init__(self, shown: str, where: str, data):
        if not isinstance(data, dict):
            what = "a JSON object" if where else "an atlas manifest (a JSON object)"
            raise ManifestError(shown, where or None, f"expected {what}, got {_describe(data)}")
        self.shown, self.where, self.data = shown, where, data

    def name(self, key: str) -> str:
        return f"{self.where}.{key}" if self.where else key

    def fail(self, key: str, expected: str, value=_MISSING):
        if value is _MISSING:
            raise ManifestError(self.shown, self.name(key), f"missing; expected {expected}")
        raise ManifestError(self.shown, self.name(key), f"expected {expected}, got {_describe(value)}")

    def take(self, key: str, expected: str, ok, optional: bool = False, nullable: bool = False):
        if key not in self.data:
            if optional:
                return None
            self.fail(key, expected)
        value = self.data[key]
        if (value is None and nullable) or ok(value):
            return value
        self.fail(key, expected + (" or null" if nullable else ""), value)

    def integer(self, key, minimum: int = 0, optional=False):
        return self.take(key, f"an integer >= {minimum}", lambda v: _is_int(v) and v >= minimum, optional)

    def number(self, key, optional=False, nullable=False, minimum=None):
        """A finite number: NaN and Infinity are JSON to Python's reader, and no figure the bake writes."""
        if minimum is None:
            return self.take(key, "a finite number", _is_finite, optional, nullable)
        return self.take(key, f"a finite number >= {minimum}", lambda v: _is_finite(v) and v >= minimum, optional, nullable)

    def shader_number(self, key, positive=False):
        """A number the include writes into shader code as a float32 literal (and, if ``positive``, above 0)."""
        expected = "a number > 0 that float32 holds" if positive else "a number float32 holds"
        return self.take(key, expected, lambda v: fits_float32(v) and (not positive or v > 0))

    def string(self, key, optional=False, choices=None):
        if choices is not None:
            return self.take(key, "one of " + ", ".join(repr(c) for c in choices), lambda v: v in choices, optional)
        return self.take(key, "a string", lambda v: isinstance(v, str), optional)

    def nonempty(self, key):
        return self.take(key, "a non-empty string", lambda v: isinstance(v, str) and v != "")

    def boolean(self, key, optional=False, nullable=False):
        return self.take(key, "true or false", lambda v: isinstance(v, bool), optional, nullable)

    def mapping(self, key, optional=False, values=None, expected="an object", value_expected=None):
        """An object; ``values`` checks each of its values. With ``value_expected`` (what one value should
        be), a bad value is named by its own key ("flags.outline": expected true or false, got "yes"),
        where the object as a whole was "expected an object of true/false flags, got an object"."""
        mapping = self.take(key, expected, lambda v: isinstance(v, dict), optional)
        for name, x in (mapping or {}).items():
            if values is not None and not values(x):
                if value_expected is None:
                    self.fail(key, expected, mapping)
                self.fail(f"{key}.{name}", value_expected, x)
        return mapping

    def array(self, key, expected="a list", item=None, length=None, optional=False):
        """A list (of ``length`` items); ``item`` = (check, description) of each item."""
        value = self.take(key, expected, lambda v: isinstance(v, list) and (length is None or len(v) == length), optional)
        for i, x in enumerate(value or []):
            if item is not None and not item[0](x):
                self.fail(f"{key}[{i}]", item[1], x)
        return value

    @overload
    def child(self, key: str, optional: Literal[False] = False) -> _Fields: ...
    @overload
    def child(self, key: str, optional: bool) -> _Fields | None: ...
    def child(self, key, optional=False):
        if key not in self.data and optional:
            return None
        self.take(key, "an object", lambda v: isinstance(v, dict))
        return _Fields(self.shown, self.name(key), self.data[key])


def _to_json(record) -> dict:
    """A record's fields as JSON, in field order; ``None`` left out where the field says so."""
    out = {}
    for f in fields(record):
        value = getattr(record, f.name)
        if value is None and f.metadata.get("omit_none"):
            continue
        out[f.metadata.get("key", f.name)] = _plain(value)
    return out


def _plain(value):
    if is_dataclass(value):
        return value.to_json()
    if isinstance(value, list):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


_OPTIONAL = {"omit_none": True}
_OBJECT = (lambda v: isinstance(v, dict), "an object")


class _Record:
    """A manifest record: its JSON is its fields in order (``metadata["key"]`` renames one)."""

    def to_json(self) -> dict:
        return _to_json(self)


# ---- records ------------------------------------------------------------------------------------


@dataclass(kw_only=True)
class Dimensions(_Record):
    """The texture's size: ``width`` x ``height`` texels, ``layers`` slices, ``mip_count`` levels."""

    width: int
    height: int
    layers: int
    mip_count: int

    @classmethod
    def from_json(cls, f: _Fields) -> Dimensions:
        return cls(width=f.integer("width", 1), height=f.integer("height", 1), layers=f.integer("layers", 1),
                   mip_count=f.integer("mip_count", 1))  # fmt: skip


@dataclass(kw_only=True)
class ErrorSummary(_Record):
    """Largest and RMS absolute error, linear units (``quantization_error``)."""

    max: float
    rms: float

    @classmethod
    def from_json(cls, f: _Fields) -> ErrorSummary:
        return cls(max=f.number("max", minimum=0), rms=f.number("rms", minimum=0))


@dataclass(kw_only=True)
class VolumeBleed(_Record):
    """How far volume mip ``level`` is from each material's own 2D mip (linear units)."""

    level: int
    max: float
    rms: float

    @classmethod
    def from_json(cls, f: _Fields) -> VolumeBleed:
        return cls(level=f.integer("level", 1), max=f.number("max", minimum=0), rms=f.number("rms", minimum=0))


@dataclass(kw_only=True)
class BrdfError(_Record):
    """A BRDF approximation's error over the sampled (l, v) pairs, each estimate with its
    standard error (``_se``; absent in manifests written before estimates carried one)
    (docs/separable.md, "Error")."""

    relative_rms: float
    relative_rms_se: float | None = field(default=None, metadata=_OPTIONAL)
    log_error: float
    log_error_se: float | None = field(default=None, metadata=_OPTIONAL)

    @classmethod
    def from_json(cls, f: _Fields) -> BrdfError:
        return cls(relative_rms=f.number("relative_rms"), relative_rms_se=f.number("relative_rms_se", optional=True, minimum=0),
                   log_error=f.number("log_error"), log_error_se=f.number("log_error_se", optional=True, minimum=0))  # fmt: skip


def _lists_of_objects(v) -> bool:
    return isinstance(v, list) and all(isinstance(x, dict) for x in v)


def _lists_of_numbers(v) -> bool:
    return isinstance(v, list) and all(is_number(x) for x in v)


@dataclass(kw_only=True)
class SeparableErrors(_Record):
    """A separable material's float errors: ``float`` (JSON key) at the chosen term count, and
    per target the curves against the term count (float, estimated 8-bit, on the grid).

    Every figure is estimated on ``pairs`` (l, v) pairs drawn with ``seed`` by the
    ``estimator`` (``defensive-ggx-mixture``: lobes of width ``lobe_alpha`` around the
    mirror direction; ``uniform``), independent of the ``selection_pairs`` drawn with
    ``selection_seed`` that chose K, the grid and the target. A budget counts as met when
    estimate + ``met_sigmas`` standard errors is within it (docs/separable.md, "Error").
    """

    estimator: str | None = field(default=None, metadata=_OPTIONAL)
    pairs: int
    seed: int
    selection_pairs: int | None = field(default=None, metadata=_OPTIONAL)
    selection_seed: int | None = field(default=None, metadata=_OPTIONAL)
    lobe_alpha: float | None = field(default=None, metadata=_OPTIONAL)
    met_sigmas: float | None = field(default=None, metadata=_OPTIONAL)
    float_error: BrdfError = field(metadata={"key": "float"})
    float_by_terms: dict  # target -> [{"terms", "relative_rms", "log_error"}]
    estimated_8bit_srgb_by_terms: dict  # target -> [{"terms", "relative_rms"}]
    grid_by_terms: dict  # target -> [relative RMS on the sampling grid, K = 1, 2, ...]

    @classmethod
    def from_json(cls, f: _Fields) -> SeparableErrors:
        curves = "an object of lists of {terms, relative_rms, ...} per target"
        return cls(
            estimator=f.string("estimator", optional=True),
            pairs=f.integer("pairs", 1),
            seed=f.integer("seed", 0),
            selection_pairs=f.integer("selection_pairs", 1, optional=True),
            selection_seed=f.integer("selection_seed", 0, optional=True),
            lobe_alpha=f.number("lobe_alpha", optional=True, minimum=0),
            met_sigmas=f.number("met_sigmas", optional=True, minimum=0),
            float_error=BrdfError.from_json(f.child("float")),
            float_by_terms=f.mapping("float_by_terms", values=_lists_of_objects, expected=curves),
            estimated_8bit_srgb_by_terms=f.mapping("estimated_8bit_srgb_by_terms", values=_lists_of_objects, expected=curves),
            grid_by_terms=f.mapping(
                "grid_by_terms", values=_lists_of_numbers, expected="an object of lists of numbers per target"
            ),
        )


@dataclass(kw_only=True)
class SeparableTransmission(_Record):
    """A separable BRDF's light from below the surface (a back-light): one table slice after its
    K terms, slice ``first_slice + slice`` (``slice`` = K), laid out as any slice of the atlas
    (u = N.L, v = N.V, the atlas's per-slice scale and bias). Where N.L <= 0 < N.V the include
    returns f cos = rgb / pi of it (docs/separable.md, "Light from behind").

    ``errors_8bit_sphere`` is the relative RMS of the whole f cos the include rebuilds (the terms
    above the surface, this slice below) against the source, with l over the whole sphere:
    ``pairs`` pairs drawn with ``seed`` by ``estimator``.
    """

    slice: int
    estimator: str | None = field(default=None, metadata=_OPTIONAL)
    pairs: int | None = field(default=None, metadata=_OPTIONAL)
    seed: int | None = field(default=None, metadata=_OPTIONAL)
    errors_8bit_sphere: BrdfError | None = field(default=None, metadata=_OPTIONAL)

    @classmethod
    def from_json(cls, f: _Fields, slice_count: int) -> SeparableTransmission:
        if slice_count < 2:  # the slice after at least one term's: the entry itself is short, whatever the slice says
            raise ManifestError(f.shown, f.where, f"expected an entry of at least 2 slices (a term and this one), "
                                f"got slice_count {slice_count}")  # fmt: skip
        offset = f.take("slice", f"{slice_count - 1} (the entry's last slice, after its terms)",
                        lambda v: _is_int(v) and v == slice_count - 1)  # fmt: skip
        errors = f.child("errors_8bit_sphere", optional=True)
        return cls(slice=offset, estimator=f.string("estimator", optional=True), pairs=f.integer("pairs", 1, optional=True),
                   seed=f.integer("seed", 0, optional=True),
                   errors_8bit_sphere=None if errors is None else BrdfError.from_json(errors))  # fmt: skip


_VIEW_FRACTION = (lambda v: isinstance(v, dict) and _is_finite(v.get("view_deg")) and _is_finite(v.get("fraction"))
                  and 0 <= v["fraction"] <= 1, "{view_deg, fraction} with the fraction in [0, 1]")  # fmt: skip


def _factor_table(v) -> bool:
    """``[[r, g, b], [r, g, b]]``: one value per colour channel of the g and the h factor, each a float32 (the
    renderer's and the include's storage tables hold them as such: 1e300 would be infinity there)."""
    return (isinstance(v, list) and len(v) == 2
            and all(isinstance(c, list) and len(c) == 3 and all(fits_float32(x) for x in c) for c in v))  # fmt: skip


@dataclass(kw_only=True)
class SeparableFactors(_Record):
    """How a separable BRDF's factors are stored in its slices (docs/separable.md, "Storage").

    Slice k holds term k: g_k left, h_k right; a factor's value is
    ``stored * factor_scale[k][f][c] + factor_bias[k][f][c]`` (f = 0 for g, 1 for h, c the
    colour channel). ``target`` names what the terms hold (``f_cos``: f cos(theta_l);
    ``f_proxy``: f times the proxy cosine). Fields the bake always writes but a rebuild
    does not need are optional here (``None``: absent from the JSON).
    ``brdf_source`` is the BRDF that was factored (``ggx``, ``mitsuba``, ...); the entry's
    own ``source`` stays the material file. ``transmitted_fraction`` (``reflection_only``
    materials) is the share of a transmissive BSDF's response the slices drop, T / (R + T),
    at a few view angles. ``transmission`` (a thin film with a back-light): the entry's last
    slice holds the light from below the surface, and the terms are the slices before it.
    """

    brdf_source: str | None = field(default=None, metadata=_OPTIONAL)
    parametrization: str
    factorization: str | None = field(default=None, metadata=_OPTIONAL)
    target: str = "f_cos"
    terms: int | None = field(default=None, metadata=_OPTIONAL)
    sampling_grid: int | None = field(default=None, metadata=_OPTIONAL)
    factor_resolution: int | None = field(default=None, metadata=_OPTIONAL)
    channel_layout: str | None = field(default=None, metadata=_OPTIONAL)
    factor_scale: list
    factor_bias: list
    nonfinite_samples: int | None = field(default=None, metadata=_OPTIONAL)
    nonfinite_reference: int | None = field(default=None, metadata=_OPTIONAL)
    errors: SeparableErrors | None = field(default=None, metadata=_OPTIONAL)
    transmitted_fraction: list | None = field(default=None, metadata=_OPTIONAL)  # [{"view_deg", "fraction"}]
    max_error: float | None = field(default=None, metadata=_OPTIONAL)
    max_error_met: bool | None = field(default=None, metadata=_OPTIONAL)
    errors_8bit: BrdfError | None = field(default=None, metadata=_OPTIONAL)
    transmission: SeparableTransmission | None = field(default=None, metadata=_OPTIONAL)

    @classmethod
    def keys(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))

    @property
    def term_slices(self) -> int:
        """How many of the entry's slices hold terms (all but a transmission slice)."""
        return len(self.factor_scale)

    @classmethod
    def from_json(cls, f: _Fields, slice_count: int) -> SeparableFactors:
        found = f.child("transmission", optional=True)
        transmission = None if found is None else SeparableTransmission.from_json(found, slice_count)
        terms = slice_count - (transmission is not None)
        table = f"a list of {terms} (one per term)"
        cell = (_factor_table, "[[r, g, b], [r, g, b]]: the g and h factor's per-channel values, each a float32")
        errors = f.child("errors", optional=True)
        errors_8bit = f.child("errors_8bit", optional=True)
        factor_scale = f.array("factor_scale", table, cell, terms)
        factor_bias = f.array("factor_bias", table, cell, terms)
        stated = f.integer("terms", 1, optional=True)
        if stated is not None and stated != terms:
            # An engine loops over 'terms' factor pairs: one more than the slices hold reads the next material.
            f.fail(
                "terms",
                f"{terms}, the entry's term slices (slice_count{' less the transmission slice' if transmission else ''})",
                stated,
            )
        return cls(
            brdf_source=f.string("brdf_source", optional=True),
            parametrization=f.nonempty("parametrization"),
            factorization=f.string("factorization", optional=True),
            target=f.string("target", optional=True) or "f_cos",
            terms=stated,
            sampling_grid=f.integer("sampling_grid", 1, optional=True),
            factor_resolution=f.integer("factor_resolution", 1, optional=True),
            channel_layout=f.string("channel_layout", optional=True),
            factor_scale=factor_scale,
            factor_bias=factor_bias,
            nonfinite_samples=f.integer("nonfinite_samples", 0, optional=True),
            nonfinite_reference=f.integer("nonfinite_reference", 0, optional=True),
            errors=None if errors is None else SeparableErrors.from_json(errors),
            transmitted_fraction=f.array("transmitted_fraction", "a list of {view_deg, fraction}", _VIEW_FRACTION, optional=True),
            max_error=f.number("max_error", optional=True),
            max_error_met=f.boolean("max_error_met", optional=True),
            errors_8bit=None if errors_8bit is None else BrdfError.from_json(errors_8bit),
            transmission=transmission,
        )


#: Linux's PATH_MAX: the longest path an entry's ``source`` may hold.
MAX_PATH_BYTES = 4096
#: A material's look goal (``[validate]`` in its file), kept in an entry's ``extra``: key -> (check, expected).
_LOOK_GOAL = {"psnr_db": (lambda v: _is_finite(v) and v > 0, "a finite number > 0 (dB)"),
              "flip": (lambda v: _is_finite(v) and 0 <= v <= 1, "a finite number in [0, 1]")}  # fmt: skip


def _check_look_goal(f: _Fields) -> None:
    """An entry's ``validate`` (the material's look goal, which validation judges the look against): an object of
    ``psnr_db`` and/or ``flip``. Edited to a string, a number or a NaN goal, it was an internal error there."""
    if f.mapping("validate", optional=True) is None:
        return
    goal = f.child("validate")
    for key in goal.data:
        if key not in _LOOK_GOAL:
            raise ManifestError(f.shown, goal.name(key), f"unknown key; expected a look goal's {' and/or '.join(_LOOK_GOAL)}")
    for key, (ok, expected) in _LOOK_GOAL.items():
        goal.take(key, expected, ok, optional=True)


def _checked_auto(f: _Fields) -> dict | None:
    """``auto``: the run-time choice (``representation = "auto"``) that the library report and a material's description
    read: the error budget, the representation chosen, and the candidates, each a representation with a finite cost
    and error, the chosen one among them. A hand-edited one (no ``candidates``, a cost of NaN) was an internal error
    in the report."""
    if f.mapping("auto", optional=True) is None:
        return None
    auto = f.child("auto")
    auto.number("error_budget", minimum=0)
    # A choice by run-time cost names the cost table's device and unit, and each candidate's cost; a separable
    # material baked as representation = "lut" records its one candidate's error alone.
    auto.string("cost_device", optional=True)
    auto.string("cost_unit", optional=True)
    chosen = auto.nonempty("chosen")
    candidates = auto.array("candidates", "a list of objects", _OBJECT)
    for i, candidate in enumerate(candidates):
        c = _Fields(f.shown, auto.name(f"candidates[{i}]"), candidate)
        c.nonempty("representation")
        c.number("cost", optional=True, minimum=0)
        c.number("error", minimum=0)
        c.number("error_se", optional=True, nullable=True, minimum=0)
        c.boolean("meets_budget")
    if chosen not in [c["representation"] for c in candidates]:
        auto.fail("chosen", "one of its candidates' representations", chosen)
    return auto.data


@dataclass(kw_only=True)
class LutRepresentation(_Record):
    """A LUT material baked within an ``error_budget``: the supersampling that met it
    (:mod:`atlasgen.bake.adaptive`) and every factor tried."""

    kind: str = "lut"
    supersampling: int
    error_budget: float
    reconstruction_error: float
    meets_budget: bool
    candidates: list  # [{"supersampling", "error"}]
    #: A separable material's ``representation = "auto"`` that chose one fitted slice: the choice
    #: by run-time cost (see :class:`AnalyticRepresentation`).
    auto: dict | None = field(default=None, metadata=_OPTIONAL)

    @classmethod
    def from_json(cls, f: _Fields) -> LutRepresentation:
        return cls(kind=f.string("kind"), supersampling=f.integer("supersampling", 1),
                   error_budget=f.number("error_budget"), reconstruction_error=f.number("reconstruction_error"),
                   meets_budget=f.boolean("meets_budget"), candidates=f.array("candidates", "a list of objects", _OBJECT),
                   auto=_checked_auto(f))  # fmt: skip


@dataclass(kw_only=True)
class SeparableRepresentation(_Record):
    """A separable material's chosen term count and sampling grid, and the candidates tried."""

    kind: str = "separable"
    terms: int
    sampling_grid: int
    target: str
    error_budget: float | None
    estimated_error_8bit: float
    estimated_error_8bit_se: float | None = field(default=None, metadata=_OPTIONAL)
    meets_budget: bool | None
    candidates: list  # [{"grid", "target", "relative_rms_by_terms", "relative_rms_se_by_terms"}]
    #: ``representation = "auto"``: the choice by run-time cost (see :class:`AnalyticRepresentation`).
    auto: dict | None = field(default=None, metadata=_OPTIONAL)

    @classmethod
    def from_json(cls, f: _Fields) -> SeparableRepresentation:
        return cls(kind=f.string("kind"), terms=f.integer("terms", 1), sampling_grid=f.integer("sampling_grid", 1),
                   target=f.string("target"), error_budget=f.number("error_budget", nullable=True),
                   estimated_error_8bit=f.number("estimated_error_8bit"),
                   estimated_error_8bit_se=f.number("estimated_error_8bit_se", optional=True, minimum=0), meets_budget=f.boolean("meets_budget", nullable=True),
                   candidates=_checked_candidates(f),
                   auto=_checked_auto(f))  # fmt: skip


#: A separable candidate's error lists: per K, a relative RMS (and its standard error), finite and at least 0.
_ERRORS_BY_TERMS = (lambda v: isinstance(v, list) and all(_is_finite(x) and x >= 0 for x in v),
                    "a list of finite numbers of at least 0, one per K")  # fmt: skip


def _checked_candidates(f: _Fields) -> list:
    """``candidates``: objects whose error lists the library report charts are lists of figures (a "x" or null in
    one was an internal error there)."""
    candidates = f.array("candidates", "a list of objects", _OBJECT)
    for i, candidate in enumerate(candidates):
        c = _Fields(f.shown, f.name(f"candidates[{i}]"), candidate)
        for key in ("relative_rms_by_terms", "relative_rms_se_by_terms"):
            if key in candidate:
                c.take(key, _ERRORS_BY_TERMS[1], _ERRORS_BY_TERMS[0])
    return candidates


@dataclass(kw_only=True)
class AnalyticRepresentation(_Record):
    """A BRDF drawn by direct evaluation of its closed form in the lighting shader, no atlas.

    The parameters are the small table the shader call takes: ``distribution`` (``ggx``,
    ``beckmann`` or ``lambert`` for none), roughness ``alpha``, ``fresnel`` (``schlick``
    with RGB ``f0``, ``exact`` dielectric of index ``ior``, or ``none``), the lobe's
    RGB ``specular`` factor and the Lambertian ``diffuse`` colour. ``auto`` holds the
    run-time choice (``representation = "auto"``): ``{"error_budget", "cost_device",
    "cost_unit", "chosen", "candidates": [{"representation", "cost", "error", "meets_budget"}]}``.
    """

    kind: str = "analytic"
    distribution: str
    alpha: float
    fresnel: str
    f0: list
    ior: float
    specular: list
    diffuse: list
    auto: dict | None = field(default=None, metadata=_OPTIONAL)

    @classmethod
    def from_json(cls, f: _Fields) -> AnalyticRepresentation:
        return cls(kind=f.string("kind"), distribution=f.nonempty("distribution"), alpha=f.shader_number("alpha", positive=True),
                   fresnel=f.nonempty("fresnel"), f0=_rgb(f, "f0"),
                   ior=f.shader_number("ior", positive=True), specular=_rgb(f, "specular"), diffuse=_rgb(f, "diffuse"),
                   auto=_checked_auto(f))  # fmt: skip


def _rgb(f: _Fields, key: str) -> list:
    return f.take(
        key,
        "an RGB triple of numbers float32 holds",
        lambda v: isinstance(v, list) and len(v) == 3 and all(fits_float32(x) for x in v),
    )


@dataclass(kw_only=True)
class Fit:
    """How a slice was fitted to a physical BSDF rather than baked from a closed form.

    ``source`` (JSON ``from``) is ``"physical"`` (a model's ``from = "physical"``),
    ``"bsdf"`` (the ``bsdf`` model) or ``"auto"`` (a separable material whose
    ``representation = "auto"`` chose one slice fitted to its source BRDF); ``gloss`` is the renderer gloss the slice was fitted
    for. The slice reproduces the physical material only under that lobe, so every object
    showing it is shaded with this gloss (docs/materials.md). ``details`` holds every key as
    written, in order (the fit's own figures: ``reference``, ``azimuths``, ``relative_rms``...).
    """

    source: str
    gloss: float
    details: dict

    def to_json(self) -> dict:
        out = dict(self.details)
        out["from"], out["gloss"] = self.source, self.gloss
        return out

    @classmethod
    def from_json(cls, f: _Fields) -> Fit:
        return cls(source=f.string("from", choices=("physical", "bsdf", "auto")),
                   gloss=f.take("gloss", "a number in [0, 1]", lambda v: is_number(v) and 0 <= v <= 1),
                   details=dict(f.data))  # fmt: skip


def _read_representation(f: _Fields):
    if f.data.get("kind") == "analytic":
        return AnalyticRepresentation.from_json(f)
    if "supersampling" in f.data:
        return LutRepresentation.from_json(f)
    if "estimated_error_8bit" in f.data:
        return SeparableRepresentation.from_json(f)
    raise ManifestError(f.shown, f.where, "expected a LUT representation (with 'supersampling') or a separable one "
                                          "(with 'estimated_error_8bit')")  # fmt: skip


def _scale_pair(v) -> bool:
    # Shader constants: a scale beyond float32 would be infinity on the GPU, every texel of the slice with it.
    return isinstance(v, list) and len(v) == 2 and all(fits_float32(x) for x in v)


def _positive_scale_pair(v) -> bool:
    # A slice's scale maps UNORM8's codes onto [0, peak]: the bake's is always above 0 (1 for a black slice),
    # and a zero or negative one would blank or invert every texel in an engine that trusts it.
    return _scale_pair(v) and all(x > 0 for x in v)


#: The fields every material entry has, in the order the bake writes them.
COMMON_KEYS = ("name", "id", "constant", "first_slice", "slice_count", "type", "source", "content_hash",
               "description", "params", "scale", "bias", "flags", "clamped_fraction", "quantization_error")  # fmt: skip


@dataclass(kw_only=True)
class MaterialEntry:
    """One material of the atlas: where its slices are, how to decode them, what it was baked from.

    The linear value of slice ``first_slice + k`` is ``texel * scale[k] + bias[k]``, with
    ``(rgb, alpha)`` pairs. ``source`` is the material file as given to the bake (a separable
    BRDF's own source, ``ggx``, ``mitsuba``, ..., is ``factors.brdf_source``).
    ``params`` are the model's parameter values (defaults filled in), ``flags`` its
    render-time requests (``outline``, ``nearest``).

    Model-specific parts, each ``None`` when the entry has none of its keys:
    ``representation`` (how an ``error_budget`` was met) and ``factors`` (a separable
    BRDF's factor storage). ``extra`` holds any other key, in order.
    """

    name: str
    id: int
    constant: str
    first_slice: int
    slice_count: int = 1
    type: str
    source: str = ""
    content_hash: str = ""
    description: str = ""
    params: dict = field(default_factory=dict)
    scale: list = field(default_factory=list)  # per slice [rgb_scale, alpha_scale]; [] -> all 1
    bias: list = field(default_factory=list)  # per slice [rgb_bias, alpha_bias]; [] -> all 0
    flags: dict = field(default_factory=dict)
    clamped_fraction: float = 0.0
    quantization_error: ErrorSummary = field(default_factory=lambda: ErrorSummary(max=0.0, rms=0.0))
    representation: LutRepresentation | SeparableRepresentation | AnalyticRepresentation | None = None
    factors: SeparableFactors | None = None
    fit: Fit | None = None
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        if not self.scale:
            self.scale = [[1.0, 1.0] for _ in range(self.slice_count)]
        if not self.bias:
            self.bias = [[0.0, 0.0] for _ in range(self.slice_count)]

    @property
    def slices(self) -> range:
        """The atlas slices this material occupies."""
        return range(self.first_slice, self.first_slice + self.slice_count)

    def flag(self, name: str) -> bool:
        """Whether the model asked for render-time behaviour ``name`` (``outline``, ``nearest``)."""
        return bool(self.flags.get(name, False))

    def to_json(self) -> dict:
        """The entry as the bake writes it: common fields, the separable storage fields,
        ``representation``, then ``errors_8bit`` (measured last, on the 8-bit result)."""
        out = {key: _plain(getattr(self, key)) for key in COMMON_KEYS}
        factors = self.factors.to_json() if self.factors is not None else {}
        errors_8bit = factors.pop("errors_8bit", None)
        out.update(factors)
        if self.representation is not None:
            out["representation"] = self.representation.to_json()
        if errors_8bit is not None:
            out["errors_8bit"] = errors_8bit
        if self.fit is not None:
            out["fit"] = self.fit.to_json()
        out.update(self.extra)
        return out

    @classmethod
    def from_json(cls, data, shown: str = "<manifest>", where: str = "") -> MaterialEntry:
        """Parse one entry; :class:`ManifestError` names ``shown`` and the field (``where.key``)."""
        f = _Fields(shown, where, data)
        slice_count = f.integer("slice_count", 1)
        pairs = f"a list of {slice_count} (one per slice)"
        pair = (_scale_pair, "an [rgb, alpha] pair of numbers float32 holds")
        positive_pair = (_positive_scale_pair, "an [rgb, alpha] pair of numbers above 0 that float32 holds")
        first = f.integer("first_slice", 0)
        entry_id = f.integer("id", 0)
        if entry_id != first:
            f.fail("id", f"the entry's first_slice ({first})", entry_id)
        representation = f.child("representation", optional=True)
        fit = f.child("fit", optional=True)
        has_factors = any(k in data for k in SeparableFactors.keys())
        known = set(COMMON_KEYS) | {"representation", "fit"} | set(SeparableFactors.keys())
        _check_look_goal(f)
        return cls(
            name=f.take(
                "name",
                "a material name (a letter, then letters, digits, '-' or '_'; at most 63)",
                lambda v: isinstance(v, str) and NAME_PATTERN.fullmatch(v) is not None,
            ),
            id=entry_id,
            constant=f.take(
                "constant",
                "a shader identifier (a letter or '_', then letters, digits or '_')",
                lambda v: isinstance(v, str) and _IDENTIFIER.fullmatch(v) is not None,
            ),
            first_slice=first,
            slice_count=slice_count,
            type=f.nonempty("type"),
            # A path from the manifest's folder, or "" (baked from memory): a NUL ended info -v's path lookup in an
            # internal error.
            # A path longer than PATH_MAX names no file, and info -v's realpath of one of 1.6 MB took minutes.
            source=f.take(
                "source",
                f"a material file's path (no NUL character) of at most {MAX_PATH_BYTES} bytes",
                lambda v: isinstance(v, str) and "\0" not in v and len(v.encode("utf-8", "surrogatepass")) <= MAX_PATH_BYTES,
            ),
            content_hash=f.string("content_hash"),
            description=f.string("description"),
            params=f.mapping("params"),
            scale=f.array("scale", pairs, positive_pair, slice_count),
            bias=f.array("bias", pairs, pair, slice_count),
            flags=f.mapping(
                "flags",
                values=lambda v: isinstance(v, bool),
                expected="an object of true/false flags",
                value_expected="true or false",
            ),
            clamped_fraction=f.take("clamped_fraction", "a number in [0, 1]", lambda v: is_number(v) and 0 <= v <= 1),
            quantization_error=ErrorSummary.from_json(f.child("quantization_error")),
            representation=None if representation is None else _read_representation(representation),
            factors=SeparableFactors.from_json(f, slice_count) if has_factors else None,
            fit=None if fit is None else Fit.from_json(fit),
            extra={k: v for k, v in data.items() if k not in known},
        )

    def with_fields(self, model_fields: dict, shown: str = "<manifest>") -> MaterialEntry:
        """This entry with ``model_fields`` (a model's manifest fields, JSON values) merged in
        and parsed into the typed parts; a key naming a common field replaces it in place.

        Raises :class:`ManifestError` (naming ``shown`` and ``<name>.<key>``) for a field
        the manifest cannot hold."""
        return MaterialEntry.from_json({**self.to_json(), **model_fields}, shown, self.name)


@dataclass(kw_only=True)
class Manifest(_Record):
    """The atlas manifest: texture format, the (N.L, N.V) mapping, and every material.

    ``materials`` are in slice order as baked; ``volume_bleed`` is present for volume
    layouts only (how far each mip level blends neighbouring materials).
    ``atlas_sha256`` is the SHA-256 of the texels (:func:`atlasgen.io.atlas.texel_sha256`) written with this
    manifest: readers refuse a pair whose texture does not hash to it (the two are from
    different bakes). The bake fills it in as it writes the pair; ``""`` until then.

    ``specular_lobe`` names the specular lobe the slices' A was made for, with its
    equation and roughness mapping (:data:`atlasgen.contract.SPECULAR_LOBE`): an engine
    must shade A with exactly that lobe.
    """

    format_version: int = FORMAT_VERSION
    generator: str = f"atlasgen {__version__}"
    atlas_sha256: str = ""
    dimensions: Dimensions
    encoding: str
    dxgi_format: int
    layout: str = "array"
    mapping: dict = field(default_factory=lambda: dict(MAPPING))
    specular_lobe: dict = field(default_factory=lambda: dict(SPECULAR_LOBE))
    materials: list[MaterialEntry] = field(default_factory=list)
    volume_bleed: list[VolumeBleed] | None = field(default=None, metadata=_OPTIONAL)

    @property
    def srgb(self) -> bool:
        """Whether RGB is stored sRGB-encoded (a sampler decodes it to linear)."""
        return self.encoding == "srgb"

    @property
    def names(self) -> list[str]:
        return [m.name for m in self.materials]

    @property
    def slices_used(self) -> int:
        return sum(m.slice_count for m in self.materials)

    def entry_named(self, name: str) -> MaterialEntry | None:
        """The entry of material ``name``, or ``None``."""
        return next((m for m in self.materials if m.name == name), None)

    def by_slice(self, index: int) -> MaterialEntry | None:
        """The entry whose slices include ``index``, or ``None`` for an unused slice."""
        return next((m for m in self.materials if index in m.slices), None)

    @classmethod
    def from_json(cls, data, shown: str = "<manifest>") -> Manifest:
        """Check and parse a manifest's JSON value; :class:`ManifestError` on the first fault.

        The format version is checked first: another version may be laid out differently,
        so only the current one is read (an older atlas is re-baked, not converted).
        """
        f = _Fields(shown, "", data)
        version = f.take("format_version", f"format version {FORMAT_VERSION} (an integer)", lambda v: _is_int(v) and v >= 1)
        if version < FORMAT_VERSION:
            f.fail("format_version", f"format version {FORMAT_VERSION} (the file is from an older atlasgen: "
                                     "re-bake the atlas with this one)", version)  # fmt: skip
        if version > FORMAT_VERSION:
            f.fail("format_version", f"format version {FORMAT_VERSION} (the file is newer than this atlasgen: "
                                     "upgrade atlasgen, or re-bake the atlas)", version)  # fmt: skip
        known = [x.name for x in fields(cls)]
        unknown = [k for k in data if k not in known]
        if unknown:
            raise ManifestError(shown, unknown[0], f"unknown field; expected only {', '.join(known)}")
        dimensions = Dimensions.from_json(f.child("dimensions"))
        encoding = f.string("encoding", choices=tuple(_ENCODINGS))
        dxgi = f.integer("dxgi_format")
        if dxgi != _ENCODINGS[encoding]:
            f.fail("dxgi_format", f"{_ENCODINGS[encoding]} (the DXGI format of {encoding} encoding)", dxgi)
        f.array("materials", "a list of material objects")  # each checked below, by index
        materials = [MaterialEntry.from_json(m, shown, f"materials[{i}]") for i, m in enumerate(data["materials"])]
        _check_slices(shown, materials, dimensions.layers)
        _check_constants(shown, materials)
        lobe = f.mapping("specular_lobe", values=lambda v: isinstance(v, str), expected="an object of strings")
        if lobe.get("name") != SPECULAR_LOBE["name"]:
            # A was made for one lobe; shading it with another gives other materials.
            f.fail(
                "specular_lobe.name",
                f"{SPECULAR_LOBE['name']!r} (the lobe this atlasgen renders with)",
                lobe.get("name", _MISSING),
            )
        bleed = f.array("volume_bleed", "a list of {level, max, rms} objects", optional=True)
        return cls(
            format_version=version,
            generator=f.string("generator"),
            atlas_sha256=f.take("atlas_sha256", "the SHA-256 of the atlas texels (64 lowercase hex digits)", _is_sha256),
            dimensions=dimensions,
            encoding=encoding,
            dxgi_format=dxgi,
            layout=f.string("layout", choices=_LAYOUTS),
            mapping=f.mapping("mapping", values=lambda v: isinstance(v, str), expected="an object of strings"),
            specular_lobe=lobe,
            materials=materials,
            volume_bleed=None if bleed is None else [
                VolumeBleed.from_json(_Fields(shown, f"volume_bleed[{i}]", b)) for i, b in enumerate(bleed)],
        )  # fmt: skip


def _check_slices(shown: str, materials: list[MaterialEntry], layers: int) -> None:
    """Every material inside the atlas, none sharing a slice or a name with another."""
    _check_runs(shown, ((m.name, m.first_slice, m.slice_count) for m in materials), layers)


def _check_runs(shown: str, runs, layers: int) -> None:
    """The manifest's materials as ``(name, first_slice, slice_count)`` runs, ``materials[i]`` the i-th: each name
    once, each run inside the atlas's ``layers`` and no other's. The full reader and :func:`read_slots` share it."""
    owners: dict[int, str] = {}
    names: set[str] = set()
    for i, (name, first, count) in enumerate(runs):
        where = f"materials[{i}]"
        if name in names:
            raise ManifestError(shown, f"{where}.name", f"expected each material once, got {name!r} twice")
        names.add(name)
        if first >= layers:  # the first slice itself is out: slice_count is not what is wrong
            raise ManifestError(shown, f"{where}.first_slice", f"expected a slice of the atlas's {layers} layers "
                                                               f"(0..{layers - 1}), got {first}")  # fmt: skip
        if not 1 <= count <= layers - first:
            raise ManifestError(shown, f"{where}.slice_count", f"expected an integer from 1 to {layers - first} "
                                f"(the slices from {first} to the atlas's last), got {_describe(count)}")  # fmt: skip
        taken = next((s for s in range(first, first + count) if s in owners), None)
        if taken is not None:
            raise ManifestError(shown, f"{where}.first_slice", f"expected slices of its own, got {first} "
                                f"(slice_count {count}), and {owners[taken]!r} holds slice {taken}")  # fmt: skip
        owners.update(dict.fromkeys(range(first, first + count), name))


def _check_constants(shown: str, materials: list[MaterialEntry]) -> None:
    """Each material's ``constant`` the one its name gives (:func:`~atlasgen.contract.material_constant`), and no
    other material's: every include declares it, beside its own functions, in three shading languages, so any
    other identifier could be a keyword or a name the include already declares, and two alike a redefinition."""
    owner: dict[str, str] = {}
    for i, m in enumerate(materials):
        expected = material_constant(m.name)
        if m.constant != expected:
            raise ManifestError(shown, f"materials[{i}].constant", f"expected {expected!r} (MATERIAL_ and the name in "
                                f"capitals, other characters as '_'), got {shorten(repr(m.constant))}")  # fmt: skip
        if m.constant in owner:
            raise ManifestError(shown, f"materials[{i}].constant", f"expected a constant of its own, got {m.constant!r}, "
                                f"also {owner[m.constant]!r}'s (names that differ only in case or '-' and '_')")  # fmt: skip
        owner[m.constant] = m.name


# ---- reading and writing -------------------------------------------------------------------------


def parse_manifest(text: str, shown: str = "<manifest>") -> Manifest:
    """A manifest from its JSON text; ``shown`` names the file in refusals."""
    try:
        data = loads_json(text)
    except ValueError as exc:
        raise ManifestError(shown, None, f"expected an atlas manifest (JSON), got malformed JSON ({exc})") from None
    return Manifest.from_json(data, shown)


def read_manifest(path) -> Manifest:
    """Read and check the manifest at ``path`` (``X.json`` beside ``X.dds``).

    Raises
    ------
    InputError
        The file is missing or unreadable.
    ManifestError
        It is not JSON, not an object, of another format version, or a field is wrong.
    """
    text = read_manifest_text(path)
    return with_absolute_files(parse_manifest(text, Path(path).as_posix()), Path(path).parent)


def with_absolute_files(manifest: Manifest, folder) -> Manifest:
    """``manifest`` read from ``folder``, with each file its entries' params name (a ``measured`` BSDF's data) absolute:
    the file holds them relative to its own folder (:func:`atlasgen.io.referenced_files.relative_files`), and they are
    read wherever the command runs. The manifest's bytes are written from the bake's entries, never from these."""
    if not any(referenced_files(m.params) for m in manifest.materials):
        return manifest
    return replace(manifest, materials=[replace(m, params=absolute_files(m.params, folder)) for m in manifest.materials])


#: The largest manifest read: 256 materials with every auto candidate recorded are a few megabytes (the shipped
#: library's 16 are 75 kB). A 100 MB one took 10 s and 0.66 GB to refuse nothing, and one just under 64 MiB of
#: empty lists 1.7 GB to parse: 8 MiB bounds that near 0.2 GB.
MAX_MANIFEST_BYTES = 8 << 20


def read_manifest_text(path) -> str:
    """The UTF-8 text of the manifest at ``path``, at most :data:`MAX_MANIFEST_BYTES` (InputError, ManifestError)."""
    return read_input_text(path, "no such manifest", "an atlas manifest (a UTF-8 JSON file)", ManifestError,
                           limit=MAX_MANIFEST_BYTES)  # fmt: skip


def read_slots(path) -> dict[str, int]:
    """``name -> first_slice`` of a manifest of any format version, for keeping slice IDs
    stable across a re-bake: an atlas written by an older atlasgen must not stop the bake
    that replaces it. Only the names and slices are read, and checked: each name once, each
    first slice one of the atlas's ``LAYERS``, its ``id`` (where there is one) the same, and each run
    (``slice_count`` slices from there, one where an old manifest gives no count) inside the atlas and no
    other name's (a slice 300, or two materials on one, would be no ID to keep).
    """
    shown = Path(path).as_posix()
    text = read_manifest_text(path)
    try:
        data = loads_json(text)
    except ValueError as exc:
        raise ManifestError(shown, None, f"expected an atlas manifest (JSON), got malformed JSON ({exc})") from None
    if not isinstance(data, dict):
        raise ManifestError(shown, None, f"expected an atlas manifest (a JSON object), got {_describe(data)}")
    materials = data.get("materials")
    if not isinstance(materials, list):
        raise ManifestError(shown, "materials", f"expected a list of materials, got {_describe(materials)}")
    runs = []
    for i, entry in enumerate(materials):
        name = entry.get("name") if isinstance(entry, dict) else None
        first = entry.get("first_slice") if isinstance(entry, dict) else None
        if not isinstance(name, str) or not _is_int(first) or first < 0:
            raise ManifestError(shown, f"materials[{i}]", "expected an object with a 'name' and a 'first_slice' >= 0")
        count = entry.get("slice_count", 1)
        if not _is_int(count):
            raise ManifestError(shown, f"materials[{i}].slice_count", f"expected an integer, got {_describe(count)}")
        # The ID an engine writes into its g-buffer is first_slice, as the full reader holds it: an edited 'id' was
        # kept silently, the material placed by its first_slice.
        if "id" in entry and entry["id"] != first:
            raise ManifestError(shown, f"materials[{i}].id", f"expected the entry's first_slice ({first}), "
                                f"got {_describe(entry['id'])}")  # fmt: skip
        runs.append((name, first, count))
    _check_runs(shown, runs, LAYERS)
    slots = {name: first for name, first, _ in runs}
    return slots


def format_manifest(manifest: Manifest) -> str:
    """Manifest JSON with one material per line: readable in a diff, and fast to write.

    (``json.dumps(indent=...)`` falls back to the pure-Python encoder, which costs
    more than the rest of a 256-material bake.)
    """
    lines = ["{"]
    items = list(manifest.to_json().items())
    for i, (key, value) in enumerate(items):
        comma = "," if i < len(items) - 1 else ""
        if key in ("materials", "volume_bleed") and value:
            lines.append(f"  {json.dumps(key)}: [")
            lines += [f"    {json.dumps(v)}{',' if j < len(value) - 1 else ''}" for j, v in enumerate(value)]
            lines.append(f"  ]{comma}")
        else:
            lines.append(f"  {json.dumps(key)}: {json.dumps(value)}{comma}")
    lines.append("}")
    return "\n".join(lines) + "\n"


def write_manifest(manifest: Manifest, path) -> Path:
    """Write ``manifest`` to ``path`` atomically; return the path."""
    path = Path(path)
    write_file_atomically(path, format_manifest(manifest).encode())
    return path
