"""What every emitted unit may use, emitted once at the head of the include: ATLAS_PI and the half vector of l and v.

``ATLAS_PI`` (:data:`PI`) is the one pi of the generated code: every emitter, the renderer's
lighting pass and the documented shading line (``albedo * A.rgb / ATLAS_PI``) use it. It
carries the include's ``ATLAS_`` prefix because WGSL has no preprocessor to guard a name and
forbids declaring one twice, so an include that declared ``PI`` would not compile in an engine
that has its own (most do; atlasgen's renderer did).

``atlas_half_vector(l, v, fallback)`` = (l + v) / |l + v|, or ``fallback`` where
|l + v|^2 <= :data:`HALF_VECTOR_MIN_LENGTH2`: l and v (nearly) opposite, with no half vector.
The specular lobe, the separable rebuild's half/difference angles and the analytic BRDF all
call it, so the degenerate case is decided in one place.

**Why 1e-6 on |l + v| (1e-12 on its square).** The shaders work in f32, where a unit vector
carries a rounding error of up to about 6e-8 per component (half an ulp of 1). For l and v
that are opposite up to rounding, l + v is that noise, up to about 1e-7 long, and its direction
means nothing; 1e-6 is the first round length safely (ten times) above it. Testing the squared
length needs no square root, and 1e-12 is a normal f32 (the smallest is 1.2e-38), so no GPU
flushes it to zero. The lobe and the separable angles already used this value (as
``hv2 < 1e-12`` and ``length(hs) > 1e-6``, the thresholds of their NumPy twins
:func:`atlasgen.optics.specular.half_vector_cosine` and
:func:`atlasgen.separable.parametrization.angles_of_directions`). The analytic BRDF tested the
length against 1e-12, the float64 threshold of :mod:`atlasgen.separable.analytic` carried
into f32, where it lies below the noise and fires only for bitwise-opposite vectors. The
change is invisible in any image: each caller returns first unless N.L > 0 (the separable and
analytic ones also need N.V > 0), and |l + v| >= N.(l + v) = N.L + N.V, so a degenerate pair
lies within 1e-6 of the horizon.

**The fallback is the caller's**, because there the callers truly differ: the lobe has no
half vector and adds nothing (``splat3(0.0)``: N.H = 0, and ``specular`` returns 0, as the
NumPy lobe masks the case), while the separable and analytic angles take the limit from
above, h = n, as their NumPy rebuilds do.
"""

from __future__ import annotations

import numpy as np

from atlasgen.shaders.lang import Const, Function, If, Let, Return, float_literal

__all__ = ["PI", "HALF_VECTOR_MIN_LENGTH2", "HALF_VECTOR", "common_declarations"]

#: ``ATLAS_PI``: pi, as the nearest f32 in every language (:func:`~atlasgen.shaders.lang.float_literal`).
PI = Const("ATLAS_PI", "f32", float_literal(np.pi), "shade with albedo * A.rgb / ATLAS_PI (docs/atlas-format.md)")

#: |l + v|^2 at or below which ``atlas_half_vector`` returns its fallback: |l + v| <= 1e-6.
HALF_VECTOR_MIN_LENGTH2 = 1e-12

#: ``atlas_half_vector(l, v, fallback)``; prefixed like the include's other names, so that it
#: does not clash with an engine's own ``half_vector``.
HALF_VECTOR = Function("atlas_half_vector", "vec3", (("l", "vec3"), ("v", "vec3"), ("fallback", "vec3")), (
    Let("vec3", "s", "l + v"),
    Let("f32", "s2", "dot(s, s)"),
    If(f"s2 > {float_literal(HALF_VECTOR_MIN_LENGTH2)}", (Return("s * inverseSqrt(s2)"),)),
    Return("fallback"),
), "(l + v) / |l + v|, or `fallback` where |l + v| <= 1e-6: l = -v up to f32 rounding, no half vector.")  # fmt: skip


def common_declarations() -> list:
    """The declarations of this module, in the order the include emits them (before every user)."""
    return [PI, HALF_VECTOR]
