"""Rebuild: f read back from an atlas file independently of the bake (the filtering: tests/optics)."""

import json

import numpy as np
import pytest

from atlasgen.errors import InputError
from atlasgen.materials.material import read_material
from atlasgen.separable.error import measure_errors, sample_error_pairs
from atlasgen.separable.rebuild import evaluate_separable, read_separable_factors
from atlasgen.separable.source import make_source
from tests.separable.separable_helpers import random_frames


def test_atlas_rebuild_reproduces_the_manifest_8bit_errors(separable_atlas):
    """Read the DDS + JSON back and measure the error ourselves: it matches what the bake recorded."""
    path, result = separable_atlas
    manifest = json.loads(path.with_suffix(".json").read_text())
    mats = {m["name"]: m for m in manifest["materials"]}
    folder = path.parent / "materials"
    for name in ("sharp", "plastic", "phong"):
        entry = mats[name]
        # The report sample, rebuilt from what the manifest records about it.
        errors = entry["errors"]
        sample = sample_error_pairs(errors["pairs"], errors["seed"], errors.get("lobe_alpha"))
        assert errors["estimator"] == sample.estimator == "defensive-ggx-mixture"
        l, v = sample.pairs
        n = np.broadcast_to([0.0, 0.0, 1.0], l.shape)
        ref = make_source(read_material(folder / f"{name}.toml").params).f_cos(l, v)
        got = evaluate_separable(path, name, n, l, v, cosine=True)
        assert np.all(np.isfinite(got))
        ours = measure_errors(ref, got, sample.weight)
        assert ours["relative_rms_se"] == pytest.approx(entry["errors_8bit"]["relative_rms_se"], rel=1e-2)
        assert ours["relative_rms"] == pytest.approx(entry["errors_8bit"]["relative_rms"], rel=1e-4)
        assert ours["log_error"] == pytest.approx(entry["errors_8bit"]["log_error"], rel=1e-4)
        # And 8 bits cost little on top of the float factors.
        assert entry["errors_8bit"]["relative_rms"] - entry["errors"]["float"]["relative_rms"] < 0.01


def test_rebuild_in_any_frame_matches_the_local_frame(separable_atlas):
    """f depends on n, l, v only through their angles: rotate everything, get the same f."""
    path, _ = separable_atlas
    n, l, v = random_frames(2000)
    # Build local-frame copies: rotate each triple so that n -> +z.
    z = np.array([0.0, 0.0, 1.0])
    local_l, local_v = np.empty_like(l), np.empty_like(v)
    for i in range(len(n)):
        axis = np.cross(n[i], z)
        s, c = np.linalg.norm(axis), n[i] @ z
        if s < 1e-12:
            rot = np.eye(3) * np.sign(c) if c < 0 else np.eye(3)
            if c < 0:
                rot = np.diag([1.0, -1.0, -1.0])
        else:
            k = axis / s
            kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
            rot = np.eye(3) + s * kx + (1 - c) * kx @ kx
        local_l[i], local_v[i] = rot @ l[i], rot @ v[i]
    for name in ("sharp", "plastic", "phong"):
        world = evaluate_separable(path, name, n, l, v)
        local = evaluate_separable(path, name, z, local_l, local_v)
        np.testing.assert_allclose(world, local, rtol=1e-6, atol=1e-9)
        below = (np.sum(n * l, 1) <= 0) | (np.sum(n * v, 1) <= 0)
        assert below.any() and not world[below].any()


def test_unknown_or_non_separable_material_is_an_input_error(separable_atlas):
    path, _ = separable_atlas
    with pytest.raises(InputError, match="no material 'nope'"):
        read_separable_factors(path, "nope")
    with pytest.raises(InputError, match="not 'separable'"):
        read_separable_factors(path, "lut")
    with pytest.raises(InputError, match="missing.dds: no such atlas"):
        read_separable_factors(path.with_name("missing.dds"), "sharp")
