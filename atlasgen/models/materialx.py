"""MaterialX surface shaders as separable-model sources: the ``materialx`` table, its checks and its references.

A ``.mtlx`` document's materials (:mod:`atlasgen.materials.materialx_document`) become
``type = "separable"`` materials with ``source = "materialx"``: their BRDF is MaterialX's own
GLSL, evaluated by :mod:`atlasgen.separable.materialx_oracle`, and the separable model fits it
as it fits any source (a LUT slice, K terms, or the cheapest within a budget). This module holds
what is MaterialX's own: the table's fields, the one-line description, and the Mitsuba BSDF
that is a faithful physical stand-in where one exists (``roughconductor`` for a
``standard_surface`` metal, ``roughplastic`` for a ``standard_surface`` dielectric without coat).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from atlasgen.errors import MaterialError, did_you_mean
from atlasgen.io.fields import FLOAT32_MAX, is_number, shown
from atlasgen.separable.materialx_oracle import SURFACE_MODELS, surface_inputs, surface_ranges

__all__ = ["SPEC_KEYS", "check_materialx_spec", "describe_materialx", "materialx_mitsuba_bsdf", "artistic_ior"]

#: Keys of a ``materialx`` table; the first four are required.
SPEC_KEYS = ("document", "material", "category", "oracle_inputs", "inputs", "flattened", "not_in_table", "sharp_lobes",
             "alpha", "error_measure")  # fmt: skip
#: What ``materialx.error_measure`` may say ``representation = "auto"`` judges by (the separable model's ``error_measure``).
ERROR_MEASURES = ("relative_rms", "relative_log_rms")

#: standard_surface inputs that must be at these values for a Mitsuba BSDF to be faithful to it.
_PLAIN = {"coat": 0.0, "sheen": 0.0, "thin_film_thickness": 0.0, "specular_anisotropy": 0.0, "transmission": 0.0,
          "subsurface": 0.0}  # fmt: skip


#: What a value of each MaterialX type must be, for the one-line refusals.
EXPECTED_VALUES = {"float": "a finite number", "integer": "an integer", "boolean": "true or false",
             "color3": "3 finite numbers", "color4": "4 finite numbers", "vector2": "2 finite numbers",
             "vector3": "3 finite numbers", "vector4": "4 finite numbers"}  # fmt: skip


def _shown(v: float) -> str:
    short = f"{v:g}"
    if float(short) == v or not abs(v) <= FLOAT32_MAX:
        return short
    # MaterialX holds values in float32: the shortest text that reads back as the same float32.
    single = np.float32(v)
    return short if np.float32(float(short)) == single else str(single)


def shown_values(values) -> str:
    """Values as a message shows them: short (``%g``) where that is the value (as MaterialX's float32 holds it),
    else as many digits as it takes, so that a refusal never shows a value inside the range it was refused for.

    >>> shown_values([1.0, 0.25, 1e39]), shown_values([float(np.float32(1.0000001))]), shown_values([float("nan")])
    ('1, 0.25, 1e+39', '1.0000001', 'nan')
    """
    return ", ".join(_shown(float(v)) for v in values)


def _single(v: float) -> float:
    """``v`` as a float32 holds it, where one can (1e300 stays itself: no float32, and refused as such by its bounds).

    >>> _single(6.283185) > 6.283185, _single(1e300)
    (True, 1e+300)
    """
    return float(np.float32(v)) if abs(v) <= FLOAT32_MAX else v


def check_input_value(path, field: str, kind: str, value, limits):
    """``value`` (plain) if it is finite and within the nodedef's ``limits`` (low, high), else refused on one line."""
    if isinstance(value, bool) or isinstance(value, str):
        return value
    components = [float(v) for v in value] if isinstance(value, list | tuple) else [float(value)]
    if not all(math.isfinite(v) for v in components):
        raise MaterialError(
            path, field, f"expected {EXPECTED_VALUES.get(kind, 'finite numbers')}, got {shown_values(components)}"
        )
    low, high = limits if limits is not None else (None, None)
    # In float32, as MaterialX holds both: a value written as the nodedef's uimax (6.283185) read as a float32
    # above the same text read as a double, and was refused as outside a range that its message showed it at.
    for bound, outside in ((low, lambda v, b: _single(v) < _single(b)), (high, lambda v, b: _single(v) > _single(b))):
        if bound is not None and any(outside(v, b) for v, b in zip(components, bound, strict=False)):
            if low is not None and high is not None:
                span = f"within {shown_values(low)} .. {shown_values(high)} (the nodedef's uimin .. uimax)"
            else:
                span = (
                    f"at least {shown_values(low)} (the nodedef's uimin)"
                    if low
                    else f"at most {shown_values(high)} (the nodedef's uimax)"
                )
            raise MaterialError(path, field, f"expected {kind} {span}, got {shown_values(components)}")
    return value


def check_materialx_spec(spec, path) -> dict:
    """A ``materialx`` table checked (``document``, ``material``, ``category``, ``oracle_inputs``
    required); returns it with the optional keys filled in."""
    if not isinstance(spec, dict):
        raise MaterialError(path, "materialx", f"expected a table {{document, material, category, oracle_inputs}}, got {spec!r}")
    for key in spec:
        if key not in SPEC_KEYS:
            raise MaterialError(path, f"materialx.{key}", f"unknown; expected one of {', '.join(SPEC_KEYS)}")
    for key in SPEC_KEYS[:4]:
        if key not in spec:
            raise MaterialError(
                path, f"materialx.{key}", "missing; a MaterialX source needs document, material, category, oracle_inputs"
            )
    if spec["category"] not in SURFACE_MODELS:
        raise MaterialError(path, "materialx.category", f"expected one of {', '.join(SURFACE_MODELS)}, got {spec['category']!r}")
    if not isinstance(spec["oracle_inputs"], dict):
        raise MaterialError(path, "materialx.oracle_inputs", "expected a table of constant inputs")
    for key in ("document", "material"):
        if not isinstance(spec[key], str) or not spec[key]:
            raise MaterialError(path, f"materialx.{key}", f"expected a non-empty string, got {shown(spec[key])}")
    _check_oracle_inputs(spec["category"], spec["oracle_inputs"], path)
    if spec.get("alpha") is not None and not (is_number(spec["alpha"]) and 0 < spec["alpha"] < math.inf):
        raise MaterialError(path, "materialx.alpha", f"expected a finite number > 0, got {shown(spec['alpha'])}")
    sharp = spec.get("sharp_lobes", [])
    if not isinstance(sharp, list) or not all(isinstance(lobe, str) for lobe in sharp):
        raise MaterialError(path, "materialx.sharp_lobes", f"expected a list of input names, got {shown(spec['sharp_lobes'])}")
    if spec.get("error_measure", "relative_rms") not in ERROR_MEASURES:
        raise MaterialError(path, "materialx.error_measure", f"expected one of {', '.join(ERROR_MEASURES)}, "
                                                              f"got {spec['error_measure']!r}")  # fmt: skip
    return {"inputs": dict(spec["oracle_inputs"]), "flattened": {}, "not_in_table": [], "sharp_lobes": [], "alpha": None, **spec}


#: Components of a MaterialX vector or colour type.
_COMPONENTS = {"color3": 3, "color4": 4, "vector2": 2, "vector3": 3, "vector4": 4}


def _of_kind(kind: str, value) -> bool:
    """Whether ``value`` (as TOML gives it) has the shape of a MaterialX ``kind``."""
    if kind in _COMPONENTS:
        return isinstance(value, list | tuple) and len(value) == _COMPONENTS[kind] and all(is_number(v) for v in value)
    if kind == "boolean":
        return isinstance(value, bool)
    if kind in ("string", "filename"):
        return isinstance(value, str)
    return is_number(value) and (kind != "integer" or isinstance(value, int))


def _check_oracle_inputs(category: str, inputs: dict, path) -> None:
    """Refuse an oracle input its nodedef does not declare, or one not of the input's type, finite and within its
    limits (:func:`check_input_value`): the oracle would drop the first silently and fail deep on the rest. The
    .mtlx reader writes these already checked; a material file written by hand is checked here."""
    kinds, ranges = surface_inputs(category), surface_ranges(category)
    for name, value in inputs.items():
        field = f"materialx.oracle_inputs.{name}"
        if name not in kinds:
            raise MaterialError(path, field, f"unknown input of {category}{did_you_mean(name, kinds)}")
        if not _of_kind(kinds[name], value):
            raise MaterialError(path, field, f"expected {EXPECTED_VALUES.get(kinds[name], 'a ' + kinds[name])} "
                                f"({kinds[name]}, the nodedef's type), got {shown(value)}")  # fmt: skip
        check_input_value(path, field, kinds[name], value, ranges.get(name))


def describe_materialx(spec: dict) -> str:
    """``MaterialX standard_surface 'Gold' from materials/x.mtlx``."""
    return f"MaterialX {spec['category']} {spec['material']!r} from {spec['document']}"


def artistic_ior(reflectivity, edge_colour):
    """Gulbrandsen's artist-friendly metallic Fresnel (JCGT 3(4), 2014), as MaterialX's
    ``mx_artistic_ior``: r = clamp(reflectivity, 0, 0.99), n = lerp(n_max, n_min, g) with
    n_min = (1 - r) / (1 + r), n_max = (1 + sqrt r) / (1 - sqrt r), k = sqrt(((n+1)^2 r - (n-1)^2) / (1 - r)).

    >>> n, k = artistic_ior([0.5, 0.5, 0.5], [1.0, 1.0, 1.0])
    >>> round(float(n[0]), 4), round(float(k[0]), 4)
    (0.3333, 0.9428)
    """
    r = np.clip(np.asarray(reflectivity, dtype=np.float64), 0.0, 0.99)
    g = np.asarray(edge_colour, dtype=np.float64)
    n_min = (1.0 - r) / (1.0 + r)
    n_max = (1.0 + np.sqrt(r)) / (1.0 - np.sqrt(r))
    n = n_max + (n_min - n_max) * g
    k = np.sqrt(np.maximum(((n + 1.0) ** 2 * r - (n - 1.0) ** 2) / (1.0 - r), 0.0))
    return n, k


def _get(inputs: dict, name: str, default) -> Any:
    value = inputs.get(name, default)
    return tuple(float(x) for x in value) if isinstance(value, list | tuple) else float(value)


def materialx_mitsuba_bsdf(spec: dict, albedo=(1.0, 1.0, 1.0)) -> tuple[dict, str] | None:
    """The Mitsuba BSDF faithful to a MaterialX material, and its description, or ``None``.

    A ``standard_surface`` with none of coat, sheen, thin film, anisotropy, transmission or
    subsurface: with metalness 1, ``roughconductor`` (GGX, alpha = roughness^2, n and k from
    :func:`artistic_ior` of base colour x base and specular colour x specular); with metalness 0,
    a white specular colour and diffuse roughness 0, ``roughplastic`` (GGX, alpha = roughness^2,
    int_ior = specular_IOR, diffuse = base colour x base). Both tinted by the object's albedo, as
    the renderer's L += E albedo f cos is. MaterialX's own differences (its energy compensation, its
    layering of the diffuse base) stay in the comparison: it measures them.
    """
    if spec.get("category") != "standard_surface":
        return None
    inputs = spec.get("inputs", {})
    if any(abs(_get(inputs, k, v) - v) > 0.0 for k, v in _PLAIN.items()):
        return None
    metalness = _get(inputs, "metalness", 0.0)
    roughness = _get(inputs, "specular_roughness", 0.2)
    alpha = float(max(float(roughness) ** 2, 1e-4))
    tint = {"type": "rgb", "value": [float(a) for a in albedo]}
    base = np.asarray(_get(inputs, "base_color", (0.8, 0.8, 0.8))) * float(_get(inputs, "base", 1.0))
    if metalness == 1.0:
        edge = np.asarray(_get(inputs, "specular_color", (1.0, 1.0, 1.0))) * float(_get(inputs, "specular", 1.0))
        n, k = artistic_ior(base, edge)
        bsdf = {"type": "roughconductor", "distribution": "ggx", "alpha": alpha, "eta": {"type": "rgb", "value": n.tolist()},
                "k": {"type": "rgb", "value": k.tolist()}, "specular_reflectance": tint}  # fmt: skip
        return bsdf, f"Mitsuba roughconductor (GGX alpha {alpha:.4g}, n and k from the artistic IOR)"
    white = np.allclose(_get(inputs, "specular_color", (1.0, 1.0, 1.0)), 1.0) and _get(inputs, "specular", 1.0) == 1.0
    if metalness == 0.0 and white and _get(inputs, "diffuse_roughness", 0.0) == 0.0:
        ior = float(_get(inputs, "specular_IOR", 1.5))
        bsdf = {"type": "roughplastic", "distribution": "ggx", "alpha": alpha, "int_ior": ior, "nonlinear": False,
                "diffuse_reflectance": {"type": "rgb", "value": (base * np.asarray(albedo)).tolist()},
                "specular_reflectance": tint}  # fmt: skip
        return bsdf, f"Mitsuba roughplastic (GGX alpha {alpha:.4g}, n = {ior:g})"
    return None
