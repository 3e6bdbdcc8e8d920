"""A Mitsuba 3 BSDF, given as a dict, evaluated vectorised with ``BSDF.eval`` in ``llvm_ad_rgb``.

Mitsuba and Dr.Jit are imported here only, inside functions: a LUT-only bake never loads them.
"""

from __future__ import annotations

import numpy as np

from atlasgen.errors import BackendError, MaterialError
from atlasgen.interrupts import deferred_interrupts

__all__ = ["VARIANT", "load_mitsuba_bsdf", "evaluate_mitsuba_f_cos"]

VARIANT = "llvm_ad_rgb"


def _mitsuba():
    # A Ctrl-C during start-up is raised as KeyboardInterrupt once it is over, never as
    # the failure it would cause inside it (see atlasgen.interrupts).
    with deferred_interrupts():
        try:
            import mitsuba as mi
        except ImportError as exc:  # pragma: no cover - depends on the installation
            raise BackendError(f"Mitsuba 3 is not installed ({exc}); install the 'mitsuba' extra") from None
        if mi.variant() != VARIANT:
            try:
                mi.set_variant(VARIANT)
            except Exception as exc:  # pragma: no cover - depends on the installation
                raise BackendError(f"Mitsuba variant {VARIANT!r} is unavailable: {_one_line(exc)}") from None
    return mi


def _one_line(text: str) -> str:
    return "; ".join(part.strip() for part in str(text).splitlines() if part.strip())


#: Microfacet roughness keys and the range a bake accepts for them (the ``alpha`` of the
#: analytic sources is (0, 4] too); Mitsuba itself takes any number, and a negative one
#: gives factors of 1e5 and more. ``roughness`` is the principled BSDF's, in [0, 1].
ROUGHNESS_RANGES = {"alpha": (0.0, 4.0), "alpha_u": (0.0, 4.0), "alpha_v": (0.0, 4.0), "roughness": (0.0, 1.0)}


def _check_bsdf_values(spec: dict, path, field: str) -> None:
    """Every number of the (nested) BSDF table finite in float32, every roughness in range,
    every ``type`` a plugin name: one-line errors naming ``bsdf.key``."""
    from atlasgen.materials.params import fits_float32, shown

    plugin = spec.get("type")
    if not isinstance(plugin, str) or not plugin:
        raise MaterialError(path, f"{field}.type", f"expected a Mitsuba plugin name (a string), got {shown(plugin)}")
    for key, value in spec.items():
        where = f"{field}.{key}"
        if isinstance(value, dict):
            _check_bsdf_values(value, path, where)
            continue
        numbers = value if isinstance(value, list) else [value]
        for number in numbers:
            if isinstance(number, (int, float)) and not isinstance(number, bool) and not fits_float32(number):
                raise MaterialError(path, where, f"expected a finite float32 number, got {shown(value)}")
        if key in ROUGHNESS_RANGES and isinstance(value, (int, float)) and not isinstance(value, bool):
            lo, hi = ROUGHNESS_RANGES[key]
            ok = (value > lo or (key == "roughness" and value == lo)) and value <= hi
            if not ok:
                bounds = f"in [{lo:g}, {hi:g}]" if key == "roughness" else f"> {lo:g} and <= {hi:g}"
                raise MaterialError(path, where, f"expected a roughness {bounds}, got {shown(value)}")


def load_mitsuba_bsdf(spec: dict, path, field: str = "bsdf"):
    """Instantiate a Mitsuba BSDF from a dict (``mi.load_dict``).

    The table is checked first (numbers finite in float32, roughness in range, ``type``
    a name); the BSDF must reflect light diffusely or glossily, since smooth (delta)
    lobes and the ``null`` BSDF evaluate to zero everywhere and leave nothing to factor.

    Raises
    ------
    MaterialError
        The dict is not a BSDF Mitsuba accepts, or not one a bake can tabulate; the
        message quotes Mitsuba's own complaint (an unknown plugin, an unreferenced
        parameter, a bad value) where there is one, and names the file and the field.
    BackendError
        Mitsuba or its ``llvm_ad_rgb`` variant is missing.
    """
    if not isinstance(spec, dict) or "type" not in spec:
        from atlasgen.materials.params import shown

        raise MaterialError(path, field, f"expected a Mitsuba BSDF table with a 'type' key, got {shown(spec)}")
    _check_bsdf_values(spec, path, field)
    mi = _mitsuba()
    try:
        obj = mi.load_dict(dict(spec))
    except Exception as exc:
        raise MaterialError(path, field, f"Mitsuba rejected the BSDF {spec.get('type')!r}: {_one_line(exc)}") from None
    if not isinstance(obj, mi.BSDF):
        raise MaterialError(path, field, f"expected a Mitsuba BSDF plugin, got a {type(obj).__name__} ({spec.get('type')!r})")
    flags = obj.flags()
    if not (mi.has_flag(flags, mi.BSDFFlags.GlossyReflection) or mi.has_flag(flags, mi.BSDFFlags.DiffuseReflection)):
        raise MaterialError(path, f"{field}.type", f"expected a BSDF with a diffuse or glossy reflection, got {spec['type']!r}, "
                                                   "which has none (smooth and null lobes evaluate to zero)")  # fmt: skip
    return obj


def evaluate_mitsuba_f_cos(bsdf, l, v) -> np.ndarray:
    """f cos(theta_l) of a loaded Mitsuba BSDF for unit (l, v) in the local frame (n = +z).

    Mitsuba's ``si.wi`` is the direction towards the viewer and ``wo`` the one
    towards the light; ``BSDF.eval`` returns f cos(theta_wo), which is f cos(theta_l)
    here (Mitsuba 3 docs, "BSDF.eval"). One call evaluates every pair.
    """
    mi = _mitsuba()
    import drjit as dr

    l = np.ascontiguousarray(np.asarray(l, dtype=np.float32).reshape(-1, 3))
    v = np.ascontiguousarray(np.asarray(v, dtype=np.float32).reshape(-1, 3))
    count = l.shape[0]
    si = dr.zeros(mi.SurfaceInteraction3f, count)
    si.wi = mi.Vector3f(v[:, 0], v[:, 1], v[:, 2])
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    si.uv = mi.Point2f(0.5, 0.5)
    value = bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(l[:, 0], l[:, 1], l[:, 2]))
    out = np.asarray(value, dtype=np.float64)
    return out.T.reshape(count, 3)
