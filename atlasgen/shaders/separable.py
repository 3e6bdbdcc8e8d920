"""Shader code that rebuilds separable BRDFs from the atlas: one generic function and a data table.

The generated code mirrors :mod:`atlasgen.separable.rebuild` line by line: same
angles (atan2 of tangential length and cosine), same warps, same texel-centre
mapping inside each 32x32 half, same scale and bias, same clamp at 0.
"""

from __future__ import annotations

import re
import struct

import numpy as np

from atlasgen.contract import HEIGHT, WIDTH
from atlasgen.io.manifest import MaterialEntry
from atlasgen.io.sidecar import SIDECAR_FILE_VERSION, SIDECAR_MAGIC
from atlasgen.separable.parametrization import ANGLE_RANGES, PROXY_FLOOR, SYSTEM_ANGLES, Warp, get_parametrization
from atlasgen.separable.storage import FACTOR_RESOLUTION
from atlasgen.shaders.common import common_declarations
from atlasgen.shaders.lang import Array, Assign, Comment, For, Function, If, Let, Return, Var, emit, float_literal

__all__ = [
    "separable_declarations",
    "separable_table",
    "separable_table_bytes",
    "separable_wgsl",
    "wgsl_function_name",
    "SIDECAR_VERSION",
    "SYSTEMS",
    "UNWARP",
    "TARGETS",
]

#: Codes of the angle systems and targets in the table.
SYSTEMS = tuple(SYSTEM_ANGLES)  # ("half_diff", "in_out")
TARGETS = ("f_cos", "f_proxy")
#: The table layout's version (row 0 of the table, also in the include's SEPARABLE_TABLE).
#: 2: a directory row's w is the RGB scale of the material's transmission slice (first + K), 0 for none.
SIDECAR_VERSION = 2
#: Rows of a material's block before its terms: head, then the axes g, h.x, h.y.
_HEAD_ROWS = 4
#: Rows per term: g scale, g bias, h scale, h bias (RGB; w unused).
_TERM_ROWS = 4

_WARP_LEGEND = ", ".join(f"{int(w)} {w.name.lower()}" for w in Warp)


#: The one shader statement of the warps (their codes are Warp's, shared with the numpy rebuild).
UNWARP = Function("separable_unwarp", "f32", (("angle", "f32"), ("axis", "vec4")), (
        Let("f32", "s", "clamp((angle - axis.y) / (axis.z - axis.y), 0.0, 1.0)"),
        Let("i32", "warp", "i32(axis.w)"),
        If(f"warp == {int(Warp.COS)}", (Return("1.0 - cos(s * (0.5 * ATLAS_PI))"),)),
        If(f"warp == {int(Warp.SQRT)}", (Return("sqrt(s)"),)),
        If(f"warp == {int(Warp.SQRT_HI)}", (Return("1.0 - sqrt(1.0 - s)"),)),
        Return("s"),
    ), f"Normalised position in [0, 1] of an angle on an axis (angle component, lo, hi, warp: {_WARP_LEGEND}).")  # fmt: skip


def wgsl_function_name(name: str) -> str:
    """``gold-film`` -> ``gold_film``: a material name as a shader identifier."""
    return re.sub(r"[^a-z0-9_]", "_", name.lower())


def _separable(entries) -> list[MaterialEntry]:
    return sorted((e for e in entries if e.factors is not None), key=lambda e: e.first_slice)


def _transmission_scale(entry: MaterialEntry) -> float:
    """The RGB scale of an entry's transmission slice (its bias must be 0), or 0 without one."""
    if entry.factors.transmission is None:
        return 0.0
    (rgb_scale, _), (rgb_bias, _) = entry.scale[entry.factors.term_slices], entry.bias[entry.factors.term_slices]
    if rgb_bias != 0.0 or not rgb_scale > 0.0:
        raise ValueError(f"{entry.name}: a transmission slice needs a positive RGB scale and bias 0, got {rgb_scale}, {rgb_bias}")
    return float(rgb_scale)


def separable_table(entries: list[MaterialEntry]) -> np.ndarray:
    """The data the generic rebuild reads, ``(rows, 4)`` float32 (docs/engine-integration.md).

    Row 0: (M materials, rows, factor resolution, table version). Rows 1..M, one per
    material in first-slice order: (first slice, row of its block, K terms, T), T the RGB
    scale of its transmission slice first + K (light from below the surface: rgb = texel * T,
    the slice's own scale with bias 0), 0 without one. A block:
    (system, target, proxy angle component, proxy floor); then per axis g, h.x, h.y
    (angle component, lo, hi, warp); then per term k: g scale, g bias, h scale, h bias
    (RGB, w = 0). Every integer is below 2^24, so float32 holds it exactly.
    """
    entries = _separable(entries)
    directory, blocks = [], []
    row = 1 + len(entries)
    for e in entries:
        factors = e.factors
        p = get_parametrization(factors.parametrization)
        axes = SYSTEM_ANGLES[p.system]
        scale = np.asarray(factors.factor_scale, dtype=np.float64)
        bias = np.asarray(factors.factor_bias, dtype=np.float64)
        k = len(scale)
        directory.append((e.first_slice, row, k, _transmission_scale(e)))
        proxy = axes.index(p.proxy_angle) if factors.target == "f_proxy" else 0
        block = [(SYSTEMS.index(p.system), TARGETS.index(factors.target), proxy, PROXY_FLOOR)]
        for angle in (p.single, *p.pair):
            block.append((axes.index(angle), *ANGLE_RANGES[angle], int(p.warp_of(angle))))
        for t in range(k):
            block += [(*scale[t, 0], 0.0), (*bias[t, 0], 0.0), (*scale[t, 1], 0.0), (*bias[t, 1], 0.0)]
        blocks += block
        row += len(block)
    table = [(len(entries), row, FACTOR_RESOLUTION, SIDECAR_VERSION), *directory, *blocks]
    return np.asarray(table, dtype=np.float32).reshape(-1, 4)


def separable_table_bytes(entries: list[MaterialEntry], manifest_sha256: bytes = bytes(32)) -> bytes:
    """``X.separable.bin``: 48-byte header (b"ASEP", u32 file version 2, u32 rows, u32 32, the
    manifest's SHA-256), then the :func:`separable_table` rows as little-endian float32, 16
    bytes a row. The bake writes zeros for the digest and stamps it (:func:`stamp_sidecar`)
    once the manifest's bytes are known."""
    table = separable_table(entries)
    header = SIDECAR_MAGIC + struct.pack("<3I", SIDECAR_FILE_VERSION, table.shape[0], 32) + manifest_sha256
    return header + table.astype("<f4").tobytes()


def _vec4(row) -> str:
    return f"vec4({', '.join(float_literal(x) for x in row)})"


def separable_declarations(entries: list[MaterialEntry]) -> list:
    """The generic rebuild of every separable material among ``entries``, and its data table.

    ``separable_f_cos(atlas, samp, material, n, l, v)`` (f cos(theta_l), RGB, 0 for IDs
    that are not separable) and ``separable_f`` (f): one function for every material,
    reading terms, axes, warps and factor scales from ``SEPARABLE_TABLE``
    (:func:`separable_table`), so a re-bake changes data, not code.
    """
    entries = _separable(entries)
    if not entries:
        return []
    table = separable_table(entries)
    last = float_literal(FACTOR_RESOLUTION - 1)
    sample = "sample_array(atlas, samp, {uv}, first + k, 0.0).rgb * SEPARABLE_TABLE[r + {s}u].xyz + SEPARABLE_TABLE[r + {b}u].xyz"
    three = (("n", "vec3"), ("l", "vec3"), ("v", "vec3"))
    return [
        Comment("---- atlasgen: separable BRDFs (Kautz & McCool 1999), generated; see docs/separable.md ----\n"
                "f(l, v) cos(theta_l) = max(sum_k g_k(pi1) * h_k(pi2), 0); term k is slice first_slice + k:\n"
                "g_k in the left 32x32 half (1D, row 0), h_k in the right half; value = texel * scale + bias.\n"
                "Bind the atlas as a 2D array texture with a linear, clamp-to-edge sampler. The data\n"
                "(SEPARABLE_TABLE, also X.separable.bin) is laid out in docs/engine-integration.md."),
        Array("SEPARABLE_TABLE", "vec4", tuple(_vec4(r) for r in table)),
        Function("separable_azimuth", "f32", (("a", "vec3"), ("b", "vec3")), (
            Let("f32", "la", "length(a)"),
            Let("f32", "lb", "length(b)"),
            If("la <= 1e-6 || lb <= 1e-6", (Return("0.0"),)),
            Return("acos(clamp(dot(a, b) / (la * lb), -1.0, 1.0))"),
        )),
        Function("separable_angles_half_diff", "vec3", three, (
            Comment("l = -v (both on the horizon, opposite): h is the limit from above, n."),
            Let("vec3", "h", "atlas_half_vector(l, v, n)"),
            Let("f32", "nh", "dot(n, h)"),
            Let("f32", "lh", "dot(l, h)"),
            Let("vec3", "t", "n - nh * h"),
            Let("vec3", "p", "l - lh * h"),
            Return("vec3(atan2(length(t), nh), atan2(length(p), lh), separable_azimuth(t, p))"),
        ), "(theta_h, theta_d, phi_d), Rusinkiewicz 1998."),
        Function("separable_angles_in_out", "vec3", three, (
            Let("f32", "nl", "dot(n, l)"),
            Let("f32", "nv", "dot(n, v)"),
            Let("vec3", "lt", "l - nl * n"),
            Let("vec3", "vt", "v - nv * n"),
            Return("vec3(atan2(length(lt), nl), atan2(length(vt), nv), separable_azimuth(lt, vt))"),
        ), "(theta_l, theta_v, phi)."),
        UNWARP,
        Function("separable_f_cos", "vec3", (("atlas", "texture_array"), ("samp", "sampler"), ("material", "u32"), *three), (
            Var("u32", "block", "0u"),
            Var("u32", "terms", "0u"),
            Var("f32", "back", "0.0"),
            For("i", "0u", "u32(SEPARABLE_TABLE[0].x)", (
                Let("vec4", "d", "SEPARABLE_TABLE[1u + i]"),
                If("u32(d.x) == material", (Assign("block", "u32(d.y)"), Assign("terms", "u32(d.z)"),
                                            Assign("back", "d.w"))),
            )),
            If("terms == 0u || dot(n, v) <= 0.0", (Return("splat3(0.0)"),)),
            If("dot(n, l) <= 0.0", (
                Comment("Light from below: the transmission slice after the terms, a table slice at the atlas's\n"
                        "(N.L, N.V) texel centres, rgb = texel * back; f cos = rgb / pi."),
                If("back > 0.0", (
                    Let("vec2", "ut", f"vec2((0.5 + {float_literal(WIDTH - 1)} * (max(dot(n, l), -1.0) + 1.0) * 0.5) / {float_literal(WIDTH)}, "
                                      f"(0.5 + {float_literal(HEIGHT - 1)} * min(dot(n, v), 1.0)) / {float_literal(HEIGHT)})"),
                    Return("sample_array(atlas, samp, ut, material + terms, 0.0).rgb * (back / ATLAS_PI)"),
                )),
                Return("splat3(0.0)"),
            )),
            Let("vec4", "head", "SEPARABLE_TABLE[block]"),
            Var("vec3", "a", "separable_angles_half_diff(n, l, v)"),
            If("head.x > 0.5", (Assign("a", "separable_angles_in_out(n, l, v)"),)),
            Let("vec4", "ag", "SEPARABLE_TABLE[block + 1u]"),
            Let("vec4", "ahx", "SEPARABLE_TABLE[block + 2u]"),
            Let("vec4", "ahy", "SEPARABLE_TABLE[block + 3u]"),
            Comment("Texel centres of a 32x32 half: texel i at (0.5 + i) / 64 (+ 0.5 for the right half)."),
            Let("f32", "cg", f"separable_unwarp(a[u32(ag.x)], ag) * {last}"),
            Let("vec2", "ch", f"vec2(separable_unwarp(a[u32(ahx.x)], ahx), separable_unwarp(a[u32(ahy.x)], ahy)) * {last}"),
            Let("vec2", "ug", "vec2((0.5 + cg) / 64.0, 0.5 / 32.0)"),
            Let("vec2", "uh", "vec2((32.5 + ch.x) / 64.0, (0.5 + ch.y) / 32.0)"),
            Let("u32", "first", "material"),
            Var("vec3", "sum", "splat3(0.0)"),
            For("k", "0u", "terms", (
                Let("u32", "r", f"block + {_HEAD_ROWS}u + {_TERM_ROWS}u * k"),
                Let("vec3", "g", sample.format(uv="ug", s=0, b=1)),
                Let("vec3", "h", sample.format(uv="uh", s=2, b=3)),
                Assign("sum", "g * h", "+="),
            )),
            Var("vec3", "result", "max(sum, splat3(0.0))"),
            If("head.y > 0.5", (
                Comment("Target f_proxy: the terms hold f * max(cos(proxy angle), proxy floor)."),
                Assign("result", "result * (dot(n, l) / max(cos(a[u32(head.z)]), head.w))"),
            )),
            Return("result"),
        ), "f cos(theta_l) of the separable material whose first slice (g-buffer ID) is `material`;\n"
           "0 for other IDs and below the horizon, except a transmission slice's light from below."),
        Function("separable_f", "vec3", (("atlas", "texture_array"), ("samp", "sampler"), ("material", "u32"), *three),
                 (Return("separable_f_cos(atlas, samp, material, n, l, v) / max(dot(n, l), 1e-4)"),), "f, in 1/sr."),
    ]  # fmt: skip


def separable_wgsl(entries: list[MaterialEntry]) -> str:
    """:func:`separable_declarations` in WGSL after the helpers they call (:mod:`atlasgen.shaders.common`),
    on their own as the include holds them ("" without separable entries)."""
    decls = separable_declarations(entries)
    return emit("wgsl", [*common_declarations(), *decls]) if decls else ""
