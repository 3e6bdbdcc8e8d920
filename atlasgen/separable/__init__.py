"""Kautz-McCool separable BRDF approximation: sampling, factorization, storage, rebuild, error.

One module per concept: :mod:`.parametrization` (pi1, pi2), :mod:`.analytic` and
:mod:`.mitsuba_source` (BRDF sources), :mod:`.source` (sampling), :mod:`.factorize`
(SVD / NMF / ND), :mod:`.storage` (8-bit layout), :mod:`.rebuild` (f from an atlas),
:mod:`.error` (error measures), :mod:`.report` (Markdown and plots).
"""

from __future__ import annotations

from atlasgen.separable.rebuild import evaluate_separable, read_separable_factors

__all__ = ["evaluate_separable", "read_separable_factors"]
