"""WGSL that rebuilds separable BRDFs from the atlas, generated from the manifest entries.

The generated code mirrors :mod:`atlasgen.separable.rebuild` line by line: same
angles (atan2 of tangential length and cosine), same warps, same texel-centre
mapping inside each 32x32 half, same scale and bias, same clamp at 0.
"""

from __future__ import annotations

import re
from string import Template

from atlasgen.io.manifest import MaterialEntry
from atlasgen.separable.parametrization import ANGLE_RANGES, PROXY_FLOOR, SYSTEM_ANGLES, Warp, get_parametrization
from atlasgen.separable.storage import FACTOR_RESOLUTION

__all__ = ["separable_wgsl", "wgsl_function_name"]

_HEADER = Template("""\
// ---- atlasgen: separable BRDFs (Kautz & McCool 1999), generated; see docs/separable.md ----
// f(l, v) cos(theta_l) = max(sum_k g_k(pi1) * h_k(pi2), 0); term k is slice first_slice + k:
// g_k in the left 32x32 half (1D, row 0), h_k in the right half; value = texel * scale + bias.
// Bind the atlas as texture_2d_array<f32> with a linear, clamp-to-edge sampler.

fn separable_azimuth(a: vec3<f32>, b: vec3<f32>) -> f32 {
    let la = length(a);
    let lb = length(b);
    if (la <= 1e-6 || lb <= 1e-6) {
        return 0.0;
    }
    return acos(clamp(dot(a, b) / (la * lb), -1.0, 1.0));
}

// (theta_h, theta_d, phi_d), Rusinkiewicz 1998.
fn separable_angles_half_diff(n: vec3<f32>, l: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let hs = l + v;
    let hl = length(hs);
    let h = select(n, hs / max(hl, 1e-30), hl > 1e-6);
    let nh = dot(n, h);
    let lh = dot(l, h);
    let t = n - nh * h;
    let p = l - lh * h;
    return vec3<f32>(atan2(length(t), nh), atan2(length(p), lh), separable_azimuth(t, p));
}

// (theta_l, theta_v, phi).
fn separable_angles_in_out(n: vec3<f32>, l: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let nl = dot(n, l);
    let nv = dot(n, v);
    let lt = l - nl * n;
    let vt = v - nv * n;
    return vec3<f32>(atan2(length(lt), nl), atan2(length(vt), nv), separable_azimuth(lt, vt));
}

$unwarp
// Texel centres of a 32x32 half: texel i at (0.5 + i) / 64 (+ 0.5 for the right half).
fn separable_uv_g(x: f32) -> vec2<f32> {
    return vec2<f32>((0.5 + x) / 64.0, 0.5 / 32.0);
}

fn separable_uv_h(xy: vec2<f32>) -> vec2<f32> {
    return vec2<f32>((32.5 + xy.x) / 64.0, (0.5 + xy.y) / 32.0);
}
""")

# The warp codes come from Warp, the one definition the numpy rebuild also uses.
_WARP_LEGEND = ", ".join(f"{int(w)} {w.name.lower()}" for w in Warp)
_UNWARP = f"""\
// Normalised position in [0, 1] of an angle on a warped axis ({_WARP_LEGEND}).
fn separable_unwarp(angle: f32, lo: f32, hi: f32, warp: i32) -> f32 {{
    let s = clamp((angle - lo) / (hi - lo), 0.0, 1.0);
    if (warp == {int(Warp.COS)}) {{
        return 1.0 - cos(s * 1.5707963267948966);
    }}
    if (warp == {int(Warp.SQRT)}) {{
        return sqrt(s);
    }}
    if (warp == {int(Warp.SQRT_HI)}) {{
        return 1.0 - sqrt(1.0 - s);
    }}
    return s;
}}
"""


def wgsl_function_name(name: str) -> str:
    """``gold-film`` -> ``gold_film``: the suffix of the material's WGSL functions."""
    return re.sub(r"[^a-z0-9_]", "_", name.lower())


def _f(x: float) -> str:
    text = repr(float(x))
    if "e" in text or "E" in text:
        mantissa, exponent = text.lower().split("e")
        if "." not in mantissa:
            mantissa += ".0"
        return f"{mantissa}e{int(exponent)}"
    return text if "." in text or "inf" in text or "nan" in text else text + ".0"


def _vec3(values) -> str:
    return "vec3<f32>(" + ", ".join(_f(v) for v in values) + ")"


def _coords_function(name: str) -> str:
    p = get_parametrization(name)
    axes = SYSTEM_ANGLES[p.system]
    index = {a: "xyz"[i] for i, a in enumerate(axes)}
    last = FACTOR_RESOLUTION - 1

    def axis(angle):
        lo, hi = ANGLE_RANGES[angle]
        return f"separable_unwarp(a.{index[angle]}, {_f(lo)}, {_f(hi)}, {int(p.warp_of(angle))}) * {_f(last)}"

    return (
        f"// Texel coordinates (g: x, h: yz) of parametrization '{name}', from its angles.\n"
        f"fn separable_texels_{name}(a: vec3<f32>) -> vec3<f32> {{\n"
        f"    return vec3<f32>({axis(p.single)}, {axis(p.pair[0])}, {axis(p.pair[1])});\n"
        f"}}\n"
    )


def _material_function(entry: MaterialEntry) -> str:
    fn = wgsl_function_name(entry.name)
    first = entry.first_slice
    factors = entry.factors
    p = get_parametrization(factors.parametrization)
    target = factors.target
    scale = factors.factor_scale
    bias = factors.factor_bias
    lines = [
        f"// Material '{entry.name}': {len(scale)} term(s), slices {first}..{first + len(scale) - 1}, "
        f"parametrization '{factors.parametrization}'.",
        f"const SEPARABLE_{fn.upper()}_FIRST_SLICE: u32 = {first}u;",
        f"fn separable_f_cos_{fn}(atlas: texture_2d_array<f32>, samp: sampler, n: vec3<f32>, l: vec3<f32>, v: vec3<f32>) -> vec3<f32> {{",
        "    if (dot(n, l) <= 0.0 || dot(n, v) <= 0.0) {",
        "        return vec3<f32>(0.0);",
        "    }",
        f"    let a = separable_angles_{p.system}(n, l, v);",
        f"    let c = separable_texels_{p.name}(a);",
        "    let ug = separable_uv_g(c.x);",
        "    let uh = separable_uv_h(c.yz);",
        "    var sum = vec3<f32>(0.0);",
    ]
    for k in range(len(scale)):
        layer = first + k
        lines.append(
            f"    sum += (textureSampleLevel(atlas, samp, ug, {layer}, 0.0).rgb * {_vec3(scale[k][0])} + {_vec3(bias[k][0])})"
            f" * (textureSampleLevel(atlas, samp, uh, {layer}, 0.0).rgb * {_vec3(scale[k][1])} + {_vec3(bias[k][1])});"
        )
    if target == "f_proxy":
        component = "xyz"[SYSTEM_ANGLES[p.system].index(p.proxy_angle)]
        result = f"max(sum, vec3<f32>(0.0)) * (dot(n, l) / max(cos(a.{component}), {_f(PROXY_FLOOR)}))"
        comment = f"    // Target f_proxy: the terms hold f * max(cos({p.proxy_angle}), {PROXY_FLOOR:g})."
    else:
        result = "max(sum, vec3<f32>(0.0))"
        comment = "    // Target f_cos: the terms hold f cos(theta_l)."
    lines += [
        comment,
        f"    return {result};",
        "}",
        f"fn separable_f_{fn}(atlas: texture_2d_array<f32>, samp: sampler, n: vec3<f32>, l: vec3<f32>, v: vec3<f32>) -> vec3<f32> {{",
        f"    return separable_f_cos_{fn}(atlas, samp, n, l, v) / max(dot(n, l), 1e-4);",
        "}",
    ]
    return "\n".join(lines) + "\n"


def separable_wgsl(entries: list[MaterialEntry]) -> str:
    """The WGSL include for the entries among ``entries`` that store separable factors.

    Per material ``NAME``: ``separable_f_cos_NAME(atlas, samp, n, l, v)`` (f cos(theta_l),
    RGB, what a light's irradiance multiplies) and ``separable_f_NAME`` (f). And
    ``separable_f_cos(atlas, samp, material, n, l, v)``, which dispatches on the
    material's first slice (its g-buffer ID), 0 for other IDs.
    """
    entries = sorted((e for e in entries if e.factors is not None), key=lambda e: e.first_slice)
    if not entries:
        return ""
    used = sorted({e.factors.parametrization for e in entries})
    parts = [_HEADER.substitute(unwarp=_UNWARP)] + [_coords_function(name) for name in used]
    parts += [_material_function(e) for e in entries]
    cases = "\n".join(
        f"        case {e.first_slice}u: {{ return separable_f_cos_{wgsl_function_name(e.name)}(atlas, samp, n, l, v); }}"
        for e in entries
    )
    parts.append(
        "fn separable_f_cos(atlas: texture_2d_array<f32>, samp: sampler, material: u32, n: vec3<f32>, l: vec3<f32>, v: vec3<f32>) -> vec3<f32> {\n"
        "    switch material {\n"
        f"{cases}\n"
        "        default: { return vec3<f32>(0.0); }\n"
        "    }\n"
        "}\n"
    )
    return "\n".join(parts)
