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

from typing import Any

import numpy as np

from atlasgen.errors import MaterialError
from atlasgen.separable.materialx_oracle import SURFACE_MODELS

__all__ = ["SPEC_KEYS", "check_materialx_spec", "describe_materialx", "materialx_mitsuba_bsdf", "artistic_ior"]

#: Keys of a ``materialx`` table; the first four are required.
SPEC_KEYS = ("document", "material", "category", "oracle_inputs", "inputs", "flattened", "not_in_table", "sharp_lobes",
             "alpha", "error_measure")  # fmt: skip
#: What ``materialx.error_measure`` may say ``representation = "auto"`` judges by (the separable model's ``error_measure``).
ERROR_MEASURES = ("relative_rms", "relative_log_rms")

#: standard_surface inputs that must be at these values for a Mitsuba BSDF to be faithful to it.
_PLAIN = {"coat": 0.0, "sheen": 0.0, "thin_film_thickness": 0.0, "specular_anisotropy": 0.0, "transmission": 0.0,
          "subsurface": 0.0}  # fmt: skip


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
    if spec.get("error_measure", "relative_rms") not in ERROR_MEASURES:
        raise MaterialError(path, "materialx.error_measure", f"expected one of {', '.join(ERROR_MEASURES)}, "
                                                              f"got {spec['error_measure']!r}")  # fmt: skip
    return {"inputs": dict(spec["oracle_inputs"]), "flattened": {}, "not_in_table": [], "sharp_lobes": [], "alpha": None, **spec}


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
