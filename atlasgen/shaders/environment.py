"""Environment lighting as shader declarations, in every include language: SH diffuse, equirect uv, gloss to level.

The formulas and their NumPy twins are :mod:`atlasgen.optics` (docs/atlas-format.md, "Environment
lighting"); this module spells them for :mod:`atlasgen.shaders.lang`, and the include
(:mod:`atlasgen.shaders.include`) and the renderer's lighting pass call them:

- ``atlas_sh_diffuse(n, sh, lam)`` = max((1/pi) sum_l lam_l sum_m L_lm Y_lm(n), 0), the Funk-Hecke sum of
  :func:`atlasgen.optics.environment_tables.diffuse_environment` for 25 coefficients ``sh[k].rgb``
  (k = l*l + l + m, :func:`atlasgen.optics.spherical_harmonics.project_equirect`) and 5 zonal weights
  ``lam[l].rgb`` (a row of :func:`~atlasgen.optics.environment_tables.slice_sh_table`), the basis
  of :func:`~atlasgen.optics.spherical_harmonics.sh_basis` unrolled with its recurrence's constants;
- ``atlas_env_uv(d, height)``: Mitsuba's ``envmap`` (u, v) of a direction
  (:func:`atlasgen.optics.equirect.direction_to_uv`), with v moved to the texel centres of an image
  of ``height`` rows, v_tex = (1/2 + v (H - 1)) / H, as a hardware sampler (repeat in u,
  clamp-to-edge in v) needs it: Mitsuba puts row j at v = j / (H - 1), columns at (i + 1/2) / W;
- ``atlas_env_level(gloss, levels)`` = (1 - gloss) (levels - 1), the prefiltered level of a gloss
  (:func:`atlasgen.optics.prefilter.level_alpha`);
- ``atlas_env_prefiltered(env, samp, d, level, height, levels)``: Lpre(d) at a fractional level of
  the prefiltered levels uploaded as one texture's mip chain, as
  :func:`atlasgen.optics.prefilter.sample_prefiltered` reads them. It blends the two levels around
  ``level`` itself instead of letting the sampler filter between mips, because the Mitsuba rows of
  level k sit at v = j / (H_k - 1), which differs per level: one uv for both levels would misplace
  the coarser level's rows by up to half a row, (1 - H_k / H_0)(v - 1/2) rows.
"""

from __future__ import annotations

import math

from atlasgen.optics.spherical_harmonics import SH_ORDER, sh_count
from atlasgen.shaders.lang import Assign, Function, Let, Return, Var, float_literal

__all__ = ["environment_declarations", "sh_basis_statements"]


def sh_basis_statements(order: int = SH_ORDER) -> tuple[list, dict[int, str]]:
    """Statements computing Y_k(n) for k < (order + 1)^2, and the name of each k's value.

    The recurrence of :func:`atlasgen.optics.spherical_harmonics.sh_basis` unrolled: (x + i y)^m
    by complex multiplication, Q_lm = P_l^m / sin^m by Abramowitz & Stegun 8.5.3, with its
    integer constants and K_lm folded into literals.
    """
    f = float_literal
    body: list = [Let("f32", "shx", "n.x"), Let("f32", "shy", "n.y"), Let("f32", "shz", "n.z")]
    names: dict[int, str] = {}
    for m in range(order + 1):
        if m > 0:
            prev_re, prev_im = ("1.0", "0.0") if m == 1 else (f"re{m - 1}", f"im{m - 1}")
            if m == 1:
                body += [Let("f32", "re1", "shx"), Let("f32", "im1", "shy")]
            else:
                body += [Let("f32", f"re{m}", f"{prev_re} * shx - {prev_im} * shy"),
                         Let("f32", f"im{m}", f"{prev_re} * shy + {prev_im} * shx")]  # fmt: skip
        double_factorial = math.prod(range(1, 2 * m, 2)) if m > 0 else 1
        for l in range(m, order + 1):
            q = f"q{l}_{m}"
            if l == m:
                body.append(Let("f32", q, f(float(double_factorial))))
            elif l == m + 1:
                body.append(Let("f32", q, f"{f(float(2 * m + 1))} * shz * q{m}_{m}"))
            else:
                a, b = (2 * l - 1) / (l - m), (l + m - 1) / (l - m)
                body.append(Let("f32", q, f"{f(a)} * shz * q{l - 1}_{m} - {f(b)} * q{l - 2}_{m}"))
            k = math.sqrt((2 * l + 1) / (4.0 * math.pi) * math.factorial(l - m) / math.factorial(l + m))
            if m == 0:
                body.append(Let("f32", f"y{l * l + l}", f"{f(k)} * {q}"))
                names[l * l + l] = f"y{l * l + l}"
            else:
                body.append(Let("f32", f"y{l * l + l + m}", f"{f(math.sqrt(2.0) * k)} * {q} * re{m}"))
                body.append(Let("f32", f"y{l * l + l - m}", f"{f(math.sqrt(2.0) * k)} * {q} * im{m}"))
                names[l * l + l + m] = f"y{l * l + l + m}"
                names[l * l + l - m] = f"y{l * l + l - m}"
    return body, names


def _sh_diffuse(order: int = SH_ORDER) -> Function:
    body, names = sh_basis_statements(order)
    body.append(Var("vec3", "total", "splat3(0.0)"))
    for l in range(order + 1):
        terms = " + ".join(f"sh[{k}].xyz * {names[k]}" for k in range(l * l, (l + 1) * (l + 1)))
        body.append(Assign("total", f"lam[{l}].xyz * ({terms})", "+="))
    # Clamped at 0: an order-4 projection of a bright sun rings below 0 on the far side, and a negative radiance
    # reached the image (-1.1 under a sky with a sun of 300).
    body.append(Return("max(total / ATLAS_PI, splat3(0.0))"))
    return Function(
        "atlas_sh_diffuse",
        "vec3",
        (("n", "vec3"), ("sh", f"vec4[{sh_count(order)}]"), ("lam", f"vec4[{order + 1}]")),
        tuple(body),
        "max((1/pi) sum_l lam_l sum_m L_lm Y_lm(n), 0): an environment's diffuse light through a slice (Funk-Hecke;\n"
        "Ramamoorthi & Hanrahan 2001), clamped at 0 where the truncated series rings below it (a bright sun).\n"
        "sh[k].rgb = L_k, k = l*l + l + m (real SH, no Condon-Shortley phase); lam[l].rgb the slice's zonal\n"
        "weights at this N.V. Multiply by the albedo.",
    )


def environment_declarations() -> list:
    """The declarations of this module (after :mod:`atlasgen.shaders.common`, whose ATLAS_PI they use)."""
    return [
        _sh_diffuse(),
        Function("atlas_env_uv", "vec2", (("d", "vec3"), ("height", "f32")), (
            Let("f32", "u", "atan2(d.x, -d.z) / (2.0 * ATLAS_PI)"),
            Let("f32", "v", "atan2(length(vec2(d.x, d.z)), d.y) / ATLAS_PI"),
            Return("vec2(u - floor(u), (0.5 + v * (height - 1.0)) / height)"),
        ), "Texture uv of direction d in an equirect image of `height` rows, Mitsuba's envmap convention:\n"
           "u = atan2(d.x, -d.z) / 2pi, v = acos(d.y) / pi with row j at v = j / (H - 1); sample with\n"
           "repeat in u and clamp-to-edge in v."),
        Function("atlas_env_level", "f32", (("gloss", "f32"), ("levels", "f32")), (
            Return("(1.0 - clamp(gloss, 0.0, 1.0)) * (levels - 1.0)"),
        ), "The prefiltered level of a gloss: level k holds roughness k / (levels - 1)."),
        Function("atlas_env_prefiltered", "vec3", (("env", "texture_2d"), ("env_sampler", "sampler"), ("d", "vec3"),
                                                   ("level", "f32"), ("height", "f32"), ("levels", "f32")), (
            Let("f32", "lv", "clamp(level, 0.0, levels - 1.0)"),
            Let("f32", "k0", "min(floor(lv), levels - 2.0)"),
            Let("f32", "h0", "height / exp2(k0)"),
            Let("vec4", "a", "sample_2d(env, env_sampler, atlas_env_uv(d, h0), k0)"),
            Let("vec4", "b", "sample_2d(env, env_sampler, atlas_env_uv(d, 0.5 * h0), k0 + 1.0)"),
            Return("mix(a.xyz, b.xyz, lv - k0)"),
        ), "Prefiltered radiance towards d at a fractional level of a mip chain whose level 0 has `height` rows\n"
           "(levels >= 2): the two levels around it, each at its own rows' uv, blended linearly."),
    ]  # fmt: skip
