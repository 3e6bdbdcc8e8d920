"""Fixtures for the separable-BRDF tests: sources, a baked atlas on disk."""

from __future__ import annotations

import textwrap

import pytest


@pytest.fixture(scope="session")
def separable_atlas(tmp_path_factory):
    """An sRGB atlas with separable materials (f_cos and f_proxy targets) and a Lambert LUT, on disk."""
    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.materials.material import read_materials

    folder = tmp_path_factory.mktemp("separable_atlas")
    mats = folder / "materials"
    mats.mkdir()
    files = {
        "lut": 'type = "lambert"\ncolour = [0.5, 0.5, 0.5]\n',
        "sharp": 'type = "separable"\nsource = "ggx"\nalpha = 0.05\nterms = 3\ntarget = "f_cos"\n',
        "plastic": 'type = "separable"\nsource = "ggx"\nalpha = 0.3\nfresnel = "exact"\ndiffuse = [0.4, 0.1, 0.05]\nterms = 2\ntarget = "f_proxy"\n',
        "phong": 'type = "separable"\nsource = "blinn_phong"\nexponent = 40.0\nspecular = [0.9, 0.6, 0.3]\nterms = 2\nparametrization = "in_out"\n',
    }
    for name, text in files.items():
        (mats / f"{name}.toml").write_text(textwrap.dedent(text))
    materials = read_materials([mats])
    result = bake_atlas(materials)
    path = folder / "atlas.dds"
    write_bake(result, path)
    return path, result
