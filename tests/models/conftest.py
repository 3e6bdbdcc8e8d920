"""Fixtures shared by the model tests: reading a TOML through the real loader, checking slices."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.contract import HEIGHT, WIDTH
from atlasgen.materials.material import read_material


@pytest.fixture
def load(write_material):
    """Read a material from TOML text through atlasgen.materials.material.read_material."""

    def read(type_name: str, body: str = ""):
        return read_material(write_material("ok", f'type = "{type_name}"\n{body}\n'))

    return read


def _assert_valid_slice(model, params):
    values = model.bake(params).values
    assert values.shape == (model.slice_count(params), HEIGHT, WIDTH, 4)
    assert np.all(np.isfinite(values))
    assert np.all(values >= 0.0)
    return values


@pytest.fixture(scope="session")
def valid_slice():
    """Bake, and assert every texel is finite and non-negative, in the contract's shape."""
    return _assert_valid_slice
