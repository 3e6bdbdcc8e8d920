"""Error of a separable approximation, measured on random (l, v) pairs in the cosine-weighted domain."""

from __future__ import annotations

import numpy as np
from atlasgen.separable.rebuild import sample_factors
from atlasgen.separable.parametrization import get_parametrization
from atlasgen.separable.rebuild import cached_on_pairs

__all__ = [
    "ERROR_PAIRS",
    "ERROR_SEED",
    "sample_hemisphere_pairs",
    "relative_rms",
    "log_error",
    "measure_errors",
    "errors_by_terms",
]

#: Number of (l, v) pairs and the seed every reported error uses.
ERROR_PAIRS = 100_000
ERROR_SEED = 20260101


def sample_hemisphere_pairs(count: int = ERROR_PAIRS, seed: int = ERROR_SEED):
    """``count`` independent (l, v) pairs, each uniform in solid angle on the upper hemisphere.

    z = xi_1, phi = 2 pi xi_2 (Archimedes' hat-box theorem; PBRT 3rd ed., sec. 13.6.1),
    from numpy's PCG64 with a fixed seed, so every run measures the same pairs.
    Returns unit vectors ``(count, 3)`` with n = +z.
    """
    rng = np.random.default_rng(seed)
    xi = rng.random((2, 2, count))
    out = []
    for k in range(2):
        z = xi[k, 0]
        phi = 2.0 * np.pi * xi[k, 1]
        r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
        d = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)
        d.flags.writeable = False  # shared by every material's error measurement
        out.append(d)
    return out[0], out[1]


def relative_rms(reference: np.ndarray, approx: np.ndarray) -> float:
    """sqrt(sum (approx - ref)^2 / sum ref^2) over all pairs and channels.

    The values are f cos(theta_l). When the reference is zero everywhere the relative
    error is 0 if the approximation is zero too, else inf is avoided by returning the
    absolute RMS (there is nothing to be relative to).
    """
    diff = np.sum((approx - reference) ** 2)
    norm = np.sum(reference**2)
    if norm == 0.0:
        return float(np.sqrt(diff / max(reference.size, 1)))
    return float(np.sqrt(diff / norm))


def log_error(reference: np.ndarray, approx: np.ndarray) -> float:
    """Löw et al. 2012 log error: sqrt(mean (ln(1 + f cos) - ln(1 + f^ cos))^2).

    Löw et al. (2012, eq. 11) weight by sin(theta_i) on a grid uniform in angle; that
    weight is the solid-angle Jacobian, which pairs drawn uniformly in solid angle
    already carry. Negative approximations are clamped at 0, as the shader does.
    """
    a = np.log1p(np.maximum(approx, 0.0))
    r = np.log1p(np.maximum(reference, 0.0))
    return float(np.sqrt(np.mean((a - r) ** 2)))


def measure_errors(reference: np.ndarray, approx: np.ndarray) -> dict:
    """Both error measures as a dict (``relative_rms``, ``log_error``), rounded to 6 significant digits."""
    return {
        "relative_rms": float(f"{relative_rms(reference, approx):.6g}"),
        "log_error": float(f"{log_error(reference, approx):.6g}"),
    }


def errors_by_terms(factors, reference: np.ndarray, l: np.ndarray, v: np.ndarray, terms=None,
                    log: bool = True) -> list[dict]:
    """Errors of the first K terms at the pairs (l, v), n = +z, for each K in ``terms``.

    ``terms`` defaults to 1 .. factors.terms. One interpolation pass serves every K
    (a running sum over terms). Each dict also holds its ``terms``; ``log=False``
    leaves out ``log_error`` (the costlier measure, not needed to rank candidates).
    """
    wanted = sorted(set(range(1, factors.terms + 1) if terms is None else terms))
    if not wanted:
        return []
    products, valid = sample_factors(factors, None, l, v)
    weight = _pair_weights(factors.parametrization, factors.target, valid, l, v)
    ref = np.ascontiguousarray(np.asarray(reference, dtype=np.float64).T)
    # All K at once, channel-major like ``products``: cumulative sums over terms, then
    # the shader's clamp and weight, in place (these arrays are K x 3 x 100 000).
    approx = np.cumsum(products[: wanted[-1]], axis=0)
    if len(wanted) < approx.shape[0]:
        approx = approx[np.asarray(wanted) - 1]
    np.maximum(approx, 0.0, out=approx)
    approx *= weight
    logs = None
    if log:
        log_ref = np.log1p(np.maximum(ref, 0.0))
        diff = np.log1p(approx)
        diff -= log_ref
        logs = np.sqrt(np.mean(np.square(diff, out=diff), axis=(1, 2)))
    approx -= ref
    squared = np.sum(np.square(approx, out=approx), axis=(1, 2))
    norm = float(np.sum(ref**2))
    rel = np.sqrt(squared / norm) if norm > 0.0 else np.sqrt(squared / max(ref.size, 1))
    out = [{"terms": k, "relative_rms": float(f"{r:.6g}")} for k, r in zip(wanted, rel)]
    if logs is not None:
        for entry, g in zip(out, logs):
            entry["log_error"] = float(f"{g:.6g}")
    return out


def _pair_weights(parametrization: str, target: str, valid, l, v) -> np.ndarray:
    """What multiplies the clamped sum at each pair: 0 where invalid, n.l / proxy for f_proxy, else 1."""
    if target != "f_proxy":
        return valid.astype(np.float64)

    def make():
        proxy = get_parametrization(parametrization).proxy_at(np.array([0.0, 0.0, 1.0]), l, v)
        return np.maximum(l[:, 2], 0.0) / proxy

    cosine = cached_on_pairs(("proxy", parametrization), (l, v), make)
    return np.where(valid, cosine, 0.0)
