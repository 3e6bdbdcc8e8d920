"""The renderer's environment data kept across processes: what is loaded is what would be built."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.materials.environment import Environment
from atlasgen.optics.sky import SkyParameters
from atlasgen.render.environment import EnvironmentData, cached_environment


@pytest.mark.slow
def test_a_cached_environment_is_the_one_built_and_is_built_again_when_damaged(tmp_path, monkeypatch):
    sky = Environment("sky", intensity=0.6, sky=SkyParameters())
    built = EnvironmentData.of(sky)
    first = cached_environment(sky, tmp_path)
    (entry,) = tmp_path.glob("environment-*.npz")
    monkeypatch.setattr(EnvironmentData, "of", classmethod(lambda cls, env: pytest.fail("built, not loaded")))
    loaded = cached_environment(sky, tmp_path)
    for got in (first, loaded):
        np.testing.assert_array_equal(got.image, built.image)
        np.testing.assert_array_equal(got.sh, built.sh)
        assert len(got.levels) == len(built.levels)
        for a, b in zip(got.levels, built.levels):
            np.testing.assert_array_equal(a, b)
    monkeypatch.undo()
    # Another intensity is another entry; a damaged entry is built again and replaced.
    cached_environment(Environment("sky", intensity=0.7, sky=SkyParameters()), tmp_path)
    assert len(list(tmp_path.glob("environment-*.npz"))) == 2
    entry.write_bytes(b"damaged")
    np.testing.assert_array_equal(cached_environment(sky, tmp_path).sh, built.sh)
    assert entry.read_bytes()[:2] == b"PK"


def test_a_file_environment_is_never_cached(tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(EnvironmentData, "of", classmethod(lambda cls, env: calls.append(env) or "built"))
    env = Environment("file", file=tmp_path / "sky.exr")
    assert cached_environment(env, tmp_path) == cached_environment(env, tmp_path) == "built"
    assert len(calls) == 2 and not list(tmp_path.iterdir())
