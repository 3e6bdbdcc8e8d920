"""A Mitsuba 3 BSDF, given as a dict, evaluated vectorised with ``BSDF.eval`` in ``llvm_ad_rgb``.

Mitsuba and Dr.Jit are imported here only, inside functions: a LUT-only bake never loads them.
"""

from __future__ import annotations

import numpy as np

from atlasgen.errors import BackendError, MaterialError

__all__ = ["VARIANT", "load_mitsuba_bsdf", "evaluate_mitsuba_f_cos"]

VARIANT = "llvm_ad_rgb"


def _mitsuba():
    try:
        import mitsuba as mi
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise BackendError(f"Mitsuba 3 is not installed ({exc}); install the 'mitsuba' extra") from None
    if mi.variant() != VARIANT:
        try:
            mi.set_variant(VARIANT)
        except Exception as exc:  # pragma: no cover - depends on the installation
            raise BackendError(f"Mitsuba variant {VARIANT!r} is unavailable: {exc}") from None
    return mi


def _one_line(text: str) -> str:
    return "; ".join(part.strip() for part in str(text).splitlines() if part.strip())


def load_mitsuba_bsdf(spec: dict, path, field: str = "bsdf"):
    """Instantiate a Mitsuba BSDF from a dict (``mi.load_dict``).

    Raises
    ------
    MaterialError
        The dict is not a BSDF Mitsuba accepts; the message quotes Mitsuba's own
        complaint (an unknown plugin, an unreferenced parameter, a bad value) and names
        the file and the field.
    BackendError
        Mitsuba or its ``llvm_ad_rgb`` variant is missing.
    """
    mi = _mitsuba()
    if not isinstance(spec, dict) or "type" not in spec:
        raise MaterialError(path, field, f"expected a Mitsuba BSDF table with a 'type' key, got {spec!r}")
    try:
        obj = mi.load_dict(dict(spec))
    except Exception as exc:
        raise MaterialError(path, field, f"Mitsuba rejected the BSDF {spec.get('type')!r}: {_one_line(exc)}") from None
    if not isinstance(obj, mi.BSDF):
        raise MaterialError(path, field, f"expected a Mitsuba BSDF plugin, got a {type(obj).__name__} ({spec.get('type')!r})")
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
