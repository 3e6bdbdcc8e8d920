"""Separable materials: the GPU image against the float64 CPU rebuild, and the manifest's claims beside them."""

from __future__ import annotations

import math

import numpy as np
import pytest


def test_cpu_rebuild_matches_the_gpu_image_of_a_separable_material(validation_run):
    (r,) = [r for r in validation_run.runs if r.material == "gloss"]
    rebuild = r.references["rebuild"]
    assert rebuild.image.max() > 0.01  # the material's pixels were found in the g-buffer
    assert np.all(rebuild.image[r.atlas_image.max(-1) == 0] == 0)
    # Same factors, same equation: only f32 texture filtering and half-float output differ.
    assert rebuild.metrics.psnr >= 45.0


def test_separable_results_carry_the_manifest_claims_and_the_measured_figures(validation_run, validation_atlas):
    import json

    (r,) = [r for r in validation_run.runs if r.material == "gloss"]
    entry = next(e for e in json.loads(validation_atlas.with_suffix(".json").read_text())["materials"] if e["name"] == "gloss")
    assert r.claimed["relative_rms_8bit"] == entry["errors_8bit"]["relative_rms"]
    assert r.claimed["terms"] == 2
    measured = r.claimed["measured_relative_rms_atlas_vs_source"]
    assert math.isfinite(measured) and measured == pytest.approx(r.references["model"].metrics.linear_relative_rms)
    assert any("manifest claims relative RMS" in note for note in r.notes)


def test_rebuild_leaves_other_materials_pixels_black(validation_run, validation_atlas):
    from atlasgen.io.atlas import read_atlas
    from atlasgen.models import get_model
    from atlasgen.validate.rebuild import rebuild_image
    from atlasgen.validate.scenes import bind_material, load_validation_scene

    entry = read_atlas(validation_atlas).material("gloss")
    _, scene = load_validation_scene("front")
    scene = bind_material(scene, "matte")
    ids = np.full((scene.height, scene.width), 0xFFFF, dtype=np.uint16)
    aovs = {
        "id": ids,
        "normal": np.zeros(ids.shape + (3,)),
        "depth": np.full(ids.shape, np.inf),
        "albedo": np.zeros(ids.shape + (3,)),
    }
    (rebuild,) = get_model(entry.type).radiance_rebuilds(entry, validation_atlas).values()
    image = rebuild_image(rebuild, entry, scene, aovs)
    assert image.shape == (scene.height, scene.width, 3) and not image.any()


def test_error_breakdown_separates_resolution_quantization_and_the_gpu(validation_run):
    for r in validation_run.runs:
        if r.type in ("lambert", "fresnel", "sss", "backlit", "iridescent"):
            b = r.breakdown
            # The float table differs from the model only by resolution and filtering:
            # for these smooth slices that is below what 8 bits add.
            assert b["table_float"]["psnr_db"] >= 55.0, (r.material, r.scene, b)
            assert b["table_8bit"]["psnr_db"] >= 45.0
            # The GPU renders what the CPU rebuild of the same 8-bit slice predicts.
            assert b["gpu_vs_8bit"]["psnr_db"] >= 50.0
        if r.type == "toon":
            # Steps on texel boundaries, sampled nearest: the float table is the model,
            # so only quantization is left to cost anything.
            b = r.breakdown
            assert b["table_float"]["psnr_db"] >= b["table_8bit"]["psnr_db"] + 3.0, b
            assert b["table_8bit"]["psnr_db"] >= 45.0, b


def test_n_dot_v_comes_from_the_g_buffer_normal_and_the_ray_through_each_pixel():
    """A normal facing the camera along each pixel's ray has N.V = 1; one at right angles to it, 0."""
    from atlasgen.render.camera import pixel_rays
    from atlasgen.validate.rebuild import n_dot_v_image
    from atlasgen.validate.scenes import load_validation_scene, resize_scene

    _, scene = load_validation_scene("front")
    scene = resize_scene(scene, 8, 6)
    rays = pixel_rays(scene.camera, 8, 6).reshape(6, 8, 3)
    rays = rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    side = np.cross(rays, [0.0, 1.0, 0.0])
    mask = np.ones((6, 8), dtype=bool)
    mask[0, 0] = False
    depth = np.full((6, 8), 3.0)
    facing = n_dot_v_image(scene, {"normal": -rays, "depth": depth}, mask)
    across = n_dot_v_image(scene, {"normal": side, "depth": depth}, mask)
    assert np.isnan(facing[0, 0]) and np.allclose(facing[mask], 1.0) and np.allclose(across[mask], 0.0, atol=1e-12)
