"""Low-rank factorization of the sampled BRDF matrix: truncated SVD, NMF, and Kautz-McCool ND.

Every method works on the weighted matrix W1^(1/2) M W2^(1/2), where W1, W2 are the
quadrature weights of the pi1 and pi2 texels for uniform (l, v) on the hemisphere
(:meth:`Parametrization.quadrature_weights`). The weighted Frobenius norm is then the
discrete form of the RMS error over uniform (l, v) pairs, which is what error.py
measures, so the rank-K SVD minimises (up to interpolation) the reported error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

__all__ = [
    "single_blas_thread",
    "matrix_errors",
    "Factors",
    "factorize",
    "factorize_svd",
    "factorize_nmf",
    "factorize_nd",
    "fix_signs",
    "FACTORIZATIONS",
]

FACTORIZATIONS = ("svd", "nmf", "nd")
#: Multiplicative updates of :func:`factorize_nmf`. At 300 a sharp GGX metal's 8-term NMF (MaterialX
#: gold, alpha 0.0625) was still far from converged in its weighted error and in the scenes' images;
#: 1000 takes most of what 3000 gains.
NMF_ITERATIONS = 1000


@dataclass
class Factors:
    """K separable terms per colour channel: f cos(theta_l) (or f) ~ sum_k g[k, c](pi1) h[k, c](pi2).

    ``g`` is ``(K, 3, n)`` (pi1 texels), ``h`` is ``(K, 3, n, n)`` indexed ``[y, x]``
    (pi2 texels), ``singular_values`` ``(3, K)`` (weighted; zeros for NMF/ND).
    ``transmission``: for a BRDF that transmits (a back-light), the linear RGB of its table
    slice ``(32, 64, 3)`` (u = N.L, v = N.V), f cos = rgb / pi where N.L <= 0 < N.V; else None.
    """

    g: np.ndarray
    h: np.ndarray
    parametrization: str
    singular_values: np.ndarray
    target: str = "f_cos"  # what sum_k g_k h_k approximates: "f_cos" or "f_proxy"
    transmission: np.ndarray | None = None

    @property
    def terms(self) -> int:
        return self.g.shape[0]

    @property
    def resolution(self) -> int:
        return self.g.shape[2]

    def truncated(self, terms: int) -> Factors:
        return Factors(self.g[:terms], self.h[:terms], self.parametrization, self.singular_values[:, :terms], self.target,
                       self.transmission)  # fmt: skip


def fix_signs(u: np.ndarray, vt: np.ndarray):
    """Make every singular pair's sign deterministic.

    Convention: the entry of largest magnitude of each left singular vector u_k is
    positive (the first such entry on a tie), flipping v_k with it so u_k v_k^T is
    unchanged. For a non-negative matrix the first pair is then non-negative
    (Perron-Frobenius), as a UNORM texture without bias wants.
    """
    pivot = np.argmax(np.abs(u), axis=0)
    signs = np.sign(u[pivot, np.arange(u.shape[1])])
    signs[signs == 0] = 1.0
    return u * signs[None, :], vt * signs[:, None]


def single_blas_thread():
    """A context that runs BLAS/LAPACK on one thread (threadpoolctl).

    The matrices here are tiny (32 x 1024); OpenBLAS's worker threads cost far more
    than they save, up to 100x on a loaded 2-core machine.
    """
    return threadpool_limits(1, user_api="blas")


def _top_singular(a: np.ndarray, terms: int):
    """The ``terms`` largest singular triplets of a short, wide matrix (rows <= columns).

    Eigenvectors of the small Gram matrix A A^T give U; V = A^T U / s. For the
    32 x 1024 matrices here this is far cheaper than a full SVD, and it avoids
    LAPACK's threaded bidiagonalisation, which is slow on a loaded 2-core machine.
    Singular values below 1e-10 of the largest are treated as 0 (their V would be noise).
    """
    gram = a @ a.T
    w, u = np.linalg.eigh(gram)
    order = np.argsort(-w, kind="stable")[:terms]
    u = u[:, order]
    vt = (a.T @ u).T
    s = np.linalg.norm(vt, axis=1)
    keep = s > 1e-10 * max(float(s[0]) if s.size else 0.0, 1e-300)
    s = np.where(keep, s, 0.0)
    vt = np.where(keep[:, None], vt / np.where(keep, s, 1.0)[:, None], 0.0)
    u = np.where(keep[None, :], u, 0.0)
    return u, s, vt


def _weighted(matrix, w1, w2):
    r1 = np.sqrt(w1)
    r2 = np.sqrt(w2)
    return matrix * r1[None, :, None] * r2[None, None, :], r1, r2


def _signed_top_singular(matrix: np.ndarray, terms: int):
    """The top ``terms`` singular triplets with the deterministic sign convention, and sqrt(s)."""
    u, s, vt = _top_singular(matrix, terms)
    u, vt = fix_signs(u, vt)
    return u, s, vt, np.sqrt(s)


def factorize_svd(matrix: np.ndarray, w1: np.ndarray, w2: np.ndarray, terms: int, parametrization: str) -> Factors:
    """Truncated SVD per colour channel (Kautz & McCool 1999, sec. 3; Eckart & Young 1936).

    With A = W1^(1/2) M W2^(1/2) = U S V^T, term k is
    g_k = s_k^(1/2) W1^(-1/2) u_k and h_k = s_k^(1/2) W2^(-1/2) v_k, so the rank-K sum
    is the best rank-K approximation of M in the weighted Frobenius norm and its error
    never grows with K. Terms beyond the matrix rank are zero.
    """
    channels, n1, n2 = matrix.shape
    side = int(round(np.sqrt(n2)))
    a, r1, r2 = _weighted(matrix, w1, w2)
    g = np.zeros((terms, channels, n1))
    h = np.zeros((terms, channels, n2))
    sv = np.zeros((channels, terms))
    for c in range(channels):
        if not np.any(a[c]):
            continue
        u, s, vt, root = _signed_top_singular(a[c], terms)
        keep = s.size
        g[:keep, c] = (u * root[None, :]).T / r1[None, :]
        h[:keep, c] = vt * root[:, None] / r2[None, :]
        sv[c, :keep] = s[:keep]
    return Factors(g, h.reshape(terms, channels, side, side), parametrization, sv)


def factorize_nmf(
    matrix: np.ndarray, w1: np.ndarray, w2: np.ndarray, terms: int, parametrization: str, iterations: int = NMF_ITERATIONS
) -> Factors:
    """Non-negative matrix factorization per channel (Lee & Seung 2001, multiplicative updates).

    Minimises the same weighted Frobenius error as :func:`factorize_svd` under
    g, h >= 0, so every factor fits UNORM8 without a bias. Initialised from the
    absolute values of the SVD factors (NNDSVD-like, Boutsidis & Gallopoulos 2008),
    so the result is deterministic.
    """
    channels, n1, n2 = matrix.shape
    side = int(round(np.sqrt(n2)))
    a, r1, r2 = _weighted(np.maximum(matrix, 0.0), w1, w2)
    g = np.zeros((terms, channels, n1))
    h = np.zeros((terms, channels, n2))
    eps = 1e-12
    active = [c for c in range(channels) if np.any(a[c])]
    if active:
        starts = [_signed_top_singular(a[c], terms) for c in active]
        keep = starts[0][1].size  # min(terms, n1) for every channel
        # Single precision: the updates reach the same factors as in double to five digits (the
        # weighted error of MaterialX gold, car paint, pearl and velvet at K = 4 and 8), in 0.6 of the time.
        wmat = np.stack([np.abs(u) * root[None, :] + eps for u, _, _, root in starts]).astype(np.float32)  # (C, n1, K)
        hmat = np.stack([np.abs(vt) * root[:, None] + eps for _, _, vt, root in starts]).astype(np.float32)  # (C, K, n2)
        x = a[active].astype(np.float32)
        eps32 = np.float32(eps)
        # The channels' updates as stacked products: one call for every channel.
        for _ in range(iterations):
            wt = wmat.transpose(0, 2, 1)
            hmat *= (wt @ x) / (wt @ wmat @ hmat + eps32)
            ht = hmat.transpose(0, 2, 1)
            wmat *= (x @ ht) / (wmat @ (hmat @ ht) + eps32)
        g[:keep, active] = (wmat / r1[None, :, None]).transpose(2, 0, 1)
        h[:keep, active] = (hmat / r2[None, None, :]).transpose(1, 0, 2)
    return Factors(g, h.reshape(terms, channels, side, side), parametrization, np.zeros((channels, terms)))


def factorize_nd(matrix: np.ndarray, w1: np.ndarray, w2: np.ndarray, parametrization: str) -> Factors:
    """Kautz & McCool's normalized decomposition (1999, sec. 3.2): one non-negative term.

    g(pi1) = ||M(pi1, .)|| (weighted row norm) and h(pi2) = the weighted mean over pi1
    of M(pi1, pi2) / g(pi1). One pass, no iteration; rows that are all zero are skipped.
    """
    channels, n1, n2 = matrix.shape
    side = int(round(np.sqrt(n2)))
    m = np.maximum(matrix, 0.0)
    g = np.sqrt(np.einsum("cij,j->ci", m * m, w2))  # (C, n1)
    safe = np.where(g > 0.0, g, 1.0)
    ratio = np.where(g[:, :, None] > 0.0, m / safe[:, :, None], 0.0)
    wsum = np.einsum("ci,i->c", (g > 0.0).astype(float), w1)
    h = np.einsum("cij,i->cj", ratio, w1) / np.where(wsum > 0.0, wsum, 1.0)[:, None]
    return Factors(g[None], h.reshape(1, channels, side, side), parametrization, np.zeros((channels, 1)))


def factorize(matrix, w1, w2, terms, parametrization, method="svd") -> Factors:
    """Dispatch on ``method`` (``"svd"``, ``"nmf"`` or ``"nd"``; ND is one term)."""
    with single_blas_thread():
        if method == "svd":
            return factorize_svd(matrix, w1, w2, terms, parametrization)
        if method == "nmf":
            return factorize_nmf(matrix, w1, w2, terms, parametrization)
        if method == "nd":
            return factorize_nd(matrix, w1, w2, parametrization)
    raise ValueError(f"unknown factorization {method!r}")


def matrix_errors(matrix: np.ndarray, w1: np.ndarray, w2: np.ndarray, factors: Factors) -> list[float]:
    """Relative weighted Frobenius residual of the first 1..K terms on the sampled grid.

    ||W1^(1/2) (M - sum_{k<=K} g_k h_k^T) W2^(1/2)||_F / ||W1^(1/2) M W2^(1/2)||_F, all
    channels together: the quantity the SVD minimises, so for SVD factors it never
    grows with K (Eckart & Young 1936). 0 for an all-zero matrix.
    """
    a, r1, r2 = _weighted(matrix, w1, w2)
    norm = float(np.sqrt(np.sum(a * a)))
    g = factors.g * r1[None, None, :]
    h = factors.h.reshape(factors.terms, factors.g.shape[1], -1) * r2[None, None, :]
    residual = a.copy()
    out = []
    for k in range(factors.terms):
        residual -= g[k][:, :, None] * h[k][:, None, :]
        out.append(float(np.sqrt(np.sum(residual * residual))) / norm if norm > 0 else 0.0)
    return out
