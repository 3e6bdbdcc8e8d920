"""Kautz-McCool separable BRDF approximation: sampling, factorization, storage, rebuild, error.

One module per concept: :mod:`.parametrization` (pi1, pi2), :mod:`.analytic` and
:mod:`.mitsuba_source` (BRDF sources), :mod:`.source` (sampling), :mod:`.factorize`
(SVD / NMF / ND), :mod:`.storage` (8-bit layout), :mod:`.rebuild` (f from an atlas),
:mod:`.error` (error measures). The report on them lives in :mod:`atlasgen.reports.separable`.
Nothing is imported here, so a module of the package loads only what it needs (a LUT-only
bake never pays for SciPy's sparse matrices, which the rebuild uses).
"""

__all__ = ["evaluate_separable"]


def __getattr__(name: str):
    # The documented entry point (docs/separable.md), imported on first use (PEP 562) so that the
    # package itself still imports nothing.
    if name == "evaluate_separable":
        from atlasgen.separable.rebuild import evaluate_separable

        return evaluate_separable
    raise AttributeError(f"module 'atlasgen.separable' has no attribute {name!r}")
