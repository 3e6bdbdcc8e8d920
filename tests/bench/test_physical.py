"""bench/physical.py's generated materials: each set it bakes is read as atlasgen reads material files.

The section renders for an hour before it bakes its last set, so a set that no longer builds (a shipped
material without a back-light, whose film table holds no ``backlight``) lost the hour's figures with it.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"


@pytest.fixture
def physical(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCH))
    sys.modules.pop("physical", None)
    yield importlib.import_module("physical")
    sys.modules.pop("physical", None)


def test_every_generated_material_reads(physical, tmp_path):
    from atlasgen.materials.material import read_material

    sets = {**physical.fitted_materials(), **physical.iridescent_materials()}
    assert {f"{name}-k8" for name in physical.IRIDESCENT} <= set(sets)
    for name, (text, what) in sets.items():
        path = tmp_path / f"{name}.toml"
        path.write_text(text)
        assert read_material(path).name == name and what
    # The back-light's transmission slice is named where the film has one, and only there.
    assert "transmission slice" in sets["iridescent-backlit-k8"][1] and "transmission" not in sets["beetle-shell-k8"][1]
