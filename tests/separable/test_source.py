"""Sources and sampling: the grid is the BRDF, non-finite samples are masked and counted."""

import numpy as np
import pytest

from atlasgen.separable.approximate import approximate_brdf
from atlasgen.separable.parametrization import get_parametrization
from atlasgen.separable.source import BrdfSource, sample_matrices
from tests.separable.separable_helpers import analytic


def test_matrix_entries_are_the_brdf_at_the_grid_directions():
    src = analytic("ggx", alpha=0.3, f0=(0.9, 0.5, 0.1))
    p = get_parametrization("half_diff")
    mats, bad = sample_matrices(src, p, 8, ("f_cos", "f_proxy"))
    assert bad == 0
    l, v = p.grid_directions(8, lift=False)
    expect = src.f_cos(l.reshape(-1, 3), v.reshape(-1, 3)).reshape(8, 64, 3).transpose(2, 0, 1)
    np.testing.assert_allclose(mats["f_cos"], expect, rtol=1e-12)
    c1, c2 = p.cosine_proxy(8)
    f = src.f(l.reshape(-1, 3), v.reshape(-1, 3)).reshape(8, 64, 3).transpose(2, 0, 1)
    np.testing.assert_allclose(mats["f_proxy"], f * np.outer(c1, c2)[None], rtol=1e-12)


def _poison(l, v):
    """Which (sample, channel) values the broken source returns as NaN or inf."""
    bad = np.zeros(np.shape(l)[:-1] + (3,), bool)
    bad[..., 0] = l[..., 0] > 0.9
    bad[..., 1] = v[..., 1] > 0.95
    return bad


@pytest.mark.slow
@pytest.mark.filterwarnings("error::RuntimeWarning")  # counted and masked, not warned about
def test_nonfinite_samples_are_masked_counted_and_reported():
    base = analytic("ggx", alpha=0.3)

    def f(l, v):
        out = base.f(l, v).copy()
        bad = _poison(l, v)
        out[..., 0][bad[..., 0]] = np.nan
        out[..., 1][bad[..., 1]] = np.inf
        return out

    src = BrdfSource("broken", evaluate_f=f)
    result = approximate_brdf(src, terms=2)
    l, v = get_parametrization("half_diff").grid_directions(32, lift=False)
    assert result.nonfinite_samples == int(_poison(l, v).sum()) > 0
    assert result.nonfinite_reference == int(_poison(*result.report.pairs).sum()) > 0
    assert np.all(np.isfinite(result.factors.g)) and np.all(np.isfinite(result.factors.h))
    for errs in result.errors_by_terms.values():
        assert all(np.isfinite(e["relative_rms"]) and np.isfinite(e["log_error"]) for e in errs)
    for errs in result.errors_8bit_by_terms.values():
        assert all(np.isfinite(e["relative_rms"]) for e in errs)
