"""The shifted Halton sequence: its digits, its spread, and its extension."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.optics.low_discrepancy import PRIMES, halton_points, radical_inverse


def _digits_reversed(k: int, base: int) -> float:
    """phi_b(k) from k's digits written out, an independent statement of the radical inverse."""
    digits = np.base_repr(k, base)[::-1] if k else "0"
    return sum(int(d, base) * float(base) ** -(j + 1) for j, d in enumerate(digits))


@given(st.integers(0, 10**9), st.sampled_from(PRIMES))
def test_the_radical_inverse_mirrors_the_digits(k, base):
    assert radical_inverse(k, base) == pytest.approx(_digits_reversed(k, base), abs=1e-15)


def test_a_smooth_integral_converges_far_faster_than_monte_carlo():
    # int over the unit cube of exp(x + y + z) = (e - 1)^3: smooth, not periodic.
    def f(p):
        return np.prod(np.exp(p), axis=1)

    exact = (np.e - 1.0) ** 3
    errors = [abs(f(halton_points(0, 4096, 3, seed=s)).mean() - exact) / exact for s in range(4)]
    rng_errors = [abs(f(np.random.default_rng(s).random((4096, 3))).mean() - exact) / exact for s in range(4)]
    assert max(errors) < 2e-3 and np.mean(errors) < np.mean(rng_errors) / 5


def test_points_continue_the_sequence_and_a_shift_keeps_them_in_the_cube():
    whole = halton_points(0, 96, 7, seed=3)
    np.testing.assert_array_equal(np.concatenate([halton_points(0, 32, 7, seed=3), halton_points(32, 64, 7, seed=3)]), whole)
    assert whole.min() >= 0.0 and whole.max() < 1.0
    assert not np.allclose(halton_points(0, 96, 7, seed=4), whole)
    with pytest.raises(ValueError, match="at most"):
        halton_points(0, 4, len(PRIMES) + 1)
