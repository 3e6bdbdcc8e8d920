"""Measured evidence behind the design choices in docs/separable.md.

``python -m atlasgen.reports.separable_evidence`` prints the Markdown tables:

* every parametrization on the same 32-texel grid and the same K (float error);
* per-channel SVD against a luminance-plus-colour factorization (one shared,
  colourless g per term; colour only in h) at the same K;
* the two targets (f cos, f times a cosine proxy), float and 8-bit.
"""

from __future__ import annotations

import numpy as np

from atlasgen.separable.approximate import _weights, approximate_brdf, reference_values
from atlasgen.separable.error import errors_by_terms, sample_hemisphere_pairs
from atlasgen.separable.factorize import Factors, _top_singular, factorize_svd, fix_signs, single_blas_thread
from atlasgen.separable.parametrization import PARAMETRIZATIONS, get_parametrization
from atlasgen.separable.source import make_source, sample_matrices

__all__ = ["EVIDENCE_MATERIALS", "factorize_shared_g", "parametrization_table", "channel_table", "target_table", "main"]

_BASE = dict(
    alpha=0.2,
    fresnel="schlick",
    f0=(0.04, 0.04, 0.04),
    ior=1.5,
    specular=(1.0, 1.0, 1.0),
    diffuse=(0.0, 0.0, 0.0),
    exponent=100.0,
    bsdf=None,
)

#: name -> separable params; the set every table is measured on.
EVIDENCE_MATERIALS = {
    "GGX a=0.05 (Schlick 0.04)": {**_BASE, "source": "ggx", "alpha": 0.05},
    "GGX a=0.2 (Schlick 0.04)": {**_BASE, "source": "ggx", "alpha": 0.2},
    "GGX a=0.5 (Schlick 0.04)": {**_BASE, "source": "ggx", "alpha": 0.5},
    "Beckmann a=0.3, exact Fresnel + red Lambert": {
        **_BASE,
        "source": "beckmann",
        "alpha": 0.3,
        "fresnel": "exact",
        "diffuse": (0.5, 0.05, 0.03),
    },
    "Blinn-Phong m=60, copper-coloured": {**_BASE, "source": "blinn_phong", "exponent": 60.0, "specular": (0.95, 0.64, 0.54)},
    "Ward a=0.15": {**_BASE, "source": "ward", "alpha": 0.15},
    "Mitsuba roughconductor Au a=0.2": {
        **_BASE,
        "source": "mitsuba",
        "bsdf": {"type": "roughconductor", "distribution": "ggx", "alpha": 0.2, "material": "Au"},
    },
}


def _sources(include_mitsuba=True):
    out = {}
    for name, params in EVIDENCE_MATERIALS.items():
        if params["source"] == "mitsuba" and not include_mitsuba:
            continue
        out[name] = make_source(params)
    return out


def factorize_shared_g(matrix, w1, w2, terms, parametrization) -> Factors:
    """Luminance-plus-colour: SVD of the channels side by side, [M_r | M_g | M_b].

    Term k is one colourless g_k(pi1) times a coloured h_k(pi2); it would store g in one
    channel and h in three, the same texture budget as per-channel SVD.
    """
    channels, n1, n2 = matrix.shape
    r1, r2 = np.sqrt(w1), np.sqrt(w2)
    a = np.concatenate([matrix[c] * r1[:, None] * r2[None, :] for c in range(channels)], axis=1)
    with single_blas_thread():
        u, s, vt = _top_singular(a, terms)
    u, vt = fix_signs(u, vt)
    root = np.sqrt(s)
    g1 = (u * root[None, :]).T / r1[None, :]
    h = (vt * root[:, None]).reshape(terms, channels, n2) / r2[None, None, :]
    side = int(round(np.sqrt(n2)))
    g = np.repeat(g1[:, None, :], channels, axis=1)
    return Factors(g, h.reshape(terms, channels, side, side), parametrization, np.zeros((channels, terms)))


def _pct(x):
    return f"{100 * x:.2f}%"


def parametrization_table(ks=(1, 2, 4), include_mitsuba=True) -> str:
    pairs = sample_hemisphere_pairs()
    lines = [
        "| material | " + " | ".join(f"{p} K={k}" for p in ("half_diff", "in_out") for k in ks) + " | best other (K=4) |",
        "|---|" + "---|" * (2 * len(ks) + 1),
    ]
    for name, src in _sources(include_mitsuba).items():
        ref, _ = reference_values(src, pairs)
        best = {}
        for pname in PARAMETRIZATIONS:
            r = approximate_brdf(src, pname, terms=max(ks), reference=ref, pairs=pairs, measure_8bit=False)
            best[pname] = [min(e[k - 1]["relative_rms"] for e in r.errors_by_terms.values()) for k in ks]
        others = {p: v for p, v in best.items() if p not in ("half_diff", "in_out")}
        top = min(others, key=lambda p: others[p][-1])
        lines.append(
            f"| {name} | "
            + " | ".join(_pct(x) for p in ("half_diff", "in_out") for x in best[p])
            + f" | {top}: {_pct(others[top][-1])} |"
        )
    return "\n".join(lines)


def channel_table(ks=(1, 2, 4), include_mitsuba=True) -> str:
    pairs = sample_hemisphere_pairs()
    l, v = pairs
    p = get_parametrization("half_diff")
    w1, w2 = _weights(p.name, 32)
    lines = [
        "| material (f cos target) | " + " | ".join(f"per-channel K={k} | lum+colour K={k}" for k in ks) + " |",
        "|---|" + "---|---|" * len(ks),
    ]

    for name, src in _sources(include_mitsuba).items():
        ref, _ = reference_values(src, pairs)
        mats, _ = sample_matrices(src, p, 32, ("f_cos",))
        per = errors_by_terms(factorize_svd(mats["f_cos"], w1, w2, max(ks), p.name), ref, l, v, ks)
        lum = errors_by_terms(factorize_shared_g(mats["f_cos"], w1, w2, max(ks), p.name), ref, l, v, ks)
        lines.append(
            f"| {name} | " + " | ".join(f"{_pct(a['relative_rms'])} | {_pct(b['relative_rms'])}" for a, b in zip(per, lum)) + " |"
        )
    return "\n".join(lines)


def target_table(ks=(2, 4), include_mitsuba=True) -> str:
    pairs = sample_hemisphere_pairs()
    lines = [
        "| material | " + " | ".join(f"{t} K={k} float / 8-bit" for t in ("f_cos", "f_proxy") for k in ks) + " |",
        "|---|" + "---|" * (2 * len(ks)),
    ]
    for name, src in _sources(include_mitsuba).items():
        ref, _ = reference_values(src, pairs)
        r = approximate_brdf(src, terms=max(ks), reference=ref, pairs=pairs)
        cells = []
        for t in ("f_cos", "f_proxy"):
            for k in ks:
                cells.append(
                    f"{_pct(r.errors_by_terms[t][k - 1]['relative_rms'])} / {_pct(r.errors_8bit_by_terms[t][k - 1]['relative_rms'])}"
                )
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    try:
        import mitsuba  # noqa: F401

        include = True
    except ImportError:
        include = False
    print("### Parametrizations (float, best target, 32-texel grid)\n")
    print(parametrization_table(include_mitsuba=include))
    print("\n### Per channel against luminance plus colour (float)\n")
    print(channel_table(include_mitsuba=include))
    print("\n### Targets (half_diff)\n")
    print(target_table(include_mitsuba=include))


if __name__ == "__main__":
    main()
