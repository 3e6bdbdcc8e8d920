"""Registry of material models by TOML ``type``; each shipped model module is imported only when used.

A model is one :class:`~atlasgen.models.base.Model` subclass; registering it is all the rest
of the library needs (docs/adding-a-model.md): the bake, the shader include, the renderer's
lighting pass, validation and the reports ask it through its hooks.
"""

from __future__ import annotations

import importlib

from atlasgen.errors import BackendError, FieldError, ManifestError, shorten
from atlasgen.io.fields import validate_params
from atlasgen.models.base import Model

__all__ = ["MODEL_TYPES", "get_model", "register_model", "unregister_model", "model_types", "check_manifest_models",
           "manifest_params", "check_manifest_params"]  # fmt: skip

#: TOML ``type`` -> "module:Class" (shipped, imported on first use) or a registered class.
#: Import is deferred so a LUT-only bake never pulls in what the separable model needs
#: (Mitsuba, Dr.Jit).
MODEL_TYPES: dict[str, str | type[Model]] = {
    "lambert": "lambert:Lambert",
    "fresnel": "fresnel:Fresnel",
    "iridescent": "iridescent:Iridescent",
    "sss": "sss:Subsurface",
    "backlit": "backlit:Backlit",
    "toon": "toon:Toon",
    "separable": "separable:Separable",
    "bsdf": "bsdf:Bsdf",
}

_cache: dict[str, Model] = {}


def model_types() -> tuple[str, ...]:
    """Every registered TOML ``type``, in registration order."""
    return tuple(MODEL_TYPES)


def get_model(type_name: str) -> Model:
    """The model instance for a TOML ``type``; ``KeyError`` if unknown."""
    if type_name not in _cache:
        spec = MODEL_TYPES[type_name]
        if isinstance(spec, str):
            module_name, class_name = spec.split(":")
            spec = getattr(importlib.import_module(f"{__name__}.{module_name}"), class_name)
        _cache[type_name] = spec()
    return _cache[type_name]


def register_model(cls: type[Model]) -> type[Model]:
    """Register a :class:`Model` subclass under its ``type_name``; usable as a class decorator.

    Raises ``ValueError`` for a class without a ``type_name`` or one whose name another
    model already has.
    """
    name = getattr(cls, "type_name", "")
    if not (isinstance(cls, type) and issubclass(cls, Model)) or not name:
        raise ValueError(f"expected a Model subclass with a type_name, got {cls!r}")
    if name in MODEL_TYPES and MODEL_TYPES[name] is not cls:
        raise ValueError(f"model type {name!r} is already registered")
    MODEL_TYPES[name] = cls
    _cache.pop(name, None)
    return cls


def unregister_model(type_name: str) -> None:
    """Forget a model type (tests that register a model of their own clean up with it)."""
    MODEL_TYPES.pop(type_name, None)
    _cache.pop(type_name, None)


def check_manifest_models(manifest, shown: str) -> None:
    """Refuse a manifest (read from ``shown``) with an entry whose model this atlasgen lacks, or which its model
    cannot use (:meth:`~atlasgen.models.base.Model.check_entry`): a hand-edited manifest reaches every command
    that asks an entry's model for something (the renderer's shader code, the reports, validation), and each
    would fail deep inside instead, on no line of its own."""
    for i, entry in enumerate(manifest.materials):
        if entry.type not in MODEL_TYPES:
            raise ManifestError(shown, f"materials[{i}].type", f"expected one of the models atlasgen knows "
                                f"({', '.join(sorted(MODEL_TYPES))}), got {shorten(repr(entry.type))}")  # fmt: skip
        get_model(entry.type).check_entry(entry, shown, f"materials[{i}]")
        manifest_params(entry, shown, f"materials[{i}]")


def manifest_params(entry, shown: str, where: str, deep: bool = False) -> dict:
    """The model's values of a manifest ``entry``'s ``params`` (its entry ``where`` in the manifest read from ``shown``),
    each field checked as a material file's is (:func:`~atlasgen.io.fields.validate_params`), and with ``deep`` by the
    model's own :meth:`~atlasgen.models.base.Model.check` too, which may load its backend (a Mitsuba BSDF).

    A field refused names ``where.params.FIELD`` in the manifest. A colour edited to a string was read by the library
    report's Pareto charts as "not measured: <manifest params>: ...", and the report exited 0.
    """
    model = get_model(entry.type)
    # A bake writes every parameter of its model (null where unset): another set is another version's model.
    expected, got = {p.name for p in model.params}, set(entry.params)
    if got != expected:
        missing, extra = sorted(expected - got), sorted(got - expected)
        what = "; ".join(x for x in (f"missing {', '.join(missing)}" if missing else "",
                                     f"unknown {', '.join(extra)}" if extra else "") if x)  # fmt: skip
        raise ManifestError(shown, f"{where}.params", f"expected the current '{entry.type}' model's parameters, got "
                            f"others ({shorten(what)}): an atlas baked by another atlasgen; re-run atlasgen bake")  # fmt: skip
    unset = {p.name for p in model.params if p.default is None}  # written as null, given as absent
    given = {k: v for k, v in entry.params.items() if not (v is None and k in unset)}
    try:
        values = validate_params(model.params, given, shown)
        if deep:
            model.check(values, shown)
    except FieldError as exc:
        field = f"{where}.params" + (f".{exc.field}" if exc.field else "")
        raise ManifestError(shown, field, exc.expected) from None
    return values


def check_manifest_params(manifest, shown: str) -> None:
    """Refuse a manifest (read from ``shown``) whose entries' params their models refuse (:func:`manifest_params`
    with ``deep``): what a command that rebuilds a material's reference from them checks first. A backend that is
    missing refuses nothing here; the command says what it could not measure."""
    for i, entry in enumerate(manifest.materials):
        try:
            manifest_params(entry, shown, f"materials[{i}]", deep=True)
        except BackendError:
            pass
