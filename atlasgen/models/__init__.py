"""Registry of material models by TOML ``type``; each model module is imported only when used."""

from __future__ import annotations

import importlib

from atlasgen.models.base import Model

__all__ = ["MODEL_TYPES", "get_model"]

#: TOML ``type`` -> "module:Class". Import is deferred so a LUT-only bake never
#: pulls in what the separable model needs (Mitsuba, Dr.Jit).
MODEL_TYPES = {
    "lambert": "lambert:Lambert",
    "fresnel": "fresnel:Fresnel",
    "iridescent": "iridescent:Iridescent",
    "sss": "sss:Subsurface",
    "backlit": "backlit:Backlit",
    "toon": "toon:Toon",
    "separable": "separable:Separable",
}

_cache: dict[str, Model] = {}


def get_model(type_name: str) -> Model:
    """The model instance for a TOML ``type``; ``KeyError`` if unknown."""
    if type_name not in _cache:
        module_name, class_name = MODEL_TYPES[type_name].split(":")
        module = importlib.import_module(f"{__name__}.{module_name}")
        _cache[type_name] = getattr(module, class_name)()
    return _cache[type_name]
