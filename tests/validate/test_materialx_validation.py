"""`atlasgen validate` on a MaterialX material: the forward render is its model reference, the gold's
ratio to roughconductor is measured, and the page shows the document, representation and error ± SE."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from atlasgen.materials.scene import Light
from atlasgen.render.camera import pixel_rays
from atlasgen.validate.materialx_reference import forward_lights, gl_view_projection
from atlasgen.validate.rebuild import n_dot_v_image
from atlasgen.validate.run import facing_away_mask
from atlasgen.validate.scenes import load_validation_scene
from tests.validate.validation_fixtures import TINY

GOLD = """<?xml version="1.0"?>
<materialx version="1.39">
  <standard_surface name="SR_gold" type="surfaceshader">
    <input name="base_color" type="color3" value="0.944, 0.776, 0.373" />
    <input name="metalness" type="float" value="1.0" />
    <input name="specular_color" type="color3" value="0.998, 0.981, 0.751" />
    <input name="specular_roughness" type="float" value="0.25" />
  </standard_surface>
  <surfacematerial name="gold" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="SR_gold" />
  </surfacematerial>
</materialx>
"""


def test_the_gl_projection_puts_every_pixel_centre_where_the_renderers_ray_goes():
    """A point on the ray through pixel (i, j)'s centre projects to that centre in OpenGL's window coordinates."""
    _, scene = load_validation_scene("front")
    w, h = TINY
    rays = pixel_rays(scene.camera, w, h)
    world = np.asarray(scene.camera.position) + rays * 2.7
    clip = np.concatenate([world, np.ones((h, w, 1))], -1) @ gl_view_projection(scene.camera, w, h).T
    ndc = clip[..., :3] / clip[..., 3:]
    x, y = (ndc[..., 0] + 1.0) * 0.5 * w, (ndc[..., 1] + 1.0) * 0.5 * h  # OpenGL: y up from the bottom row
    jj, ii = np.meshgrid(np.arange(w), np.arange(h))
    np.testing.assert_allclose(x, jj + 0.5, atol=1e-9)
    np.testing.assert_allclose(y, h - ii - 0.5, atol=1e-9)
    assert np.all(np.abs(ndc[..., 2]) < 1.0)


def test_every_light_of_a_scene_is_handed_down_as_the_renderer_has_it():
    _, scene = load_validation_scene("front")
    spot = Light("spot", (1.0, 0.9, 0.8), 2.0, position=(0.0, 2.0, 0.0), direction=(0.0, -1.0, 0.0), range=4.0,
                 inner_angle=10.0, outer_angle=20.0)  # fmt: skip
    lights = forward_lights(dataclasses.replace(scene, lights=[*scene.lights, spot]))
    assert [light.type for light in lights] == ["point", "directional", "spot"] and math.isinf(lights[0].range)
    assert (lights[2].range, lights[2].inner_angle, lights[2].outer_angle, lights[2].colour) == (4.0, 10.0, 20.0, (1.0, 0.9, 0.8))
    assert lights[1].direction == tuple(scene.lights[1].direction) and lights[0].position == tuple(scene.lights[0].position)
    assert forward_lights(dataclasses.replace(scene, lights=[dataclasses.replace(spot, type="area")])) is None


def test_the_pixels_whose_normal_faces_away_from_the_camera_are_those_with_n_dot_v_at_most_0():
    """Normals built to make N.V = -0.3, -1e-3, 1e-3 and 0.5 with the pixel's own ray; only the first two are left
    out, and only where the material shows."""
    _, scene = load_validation_scene("back")
    w, h = scene.width, scene.height
    v = -pixel_rays(scene.camera, w, h)
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    side = np.cross(v, [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side, axis=-1, keepdims=True)
    wanted = np.resize(np.array([-0.3, -1e-3, 1e-3, 0.5]), (h, w))
    normal = wanted[..., None] * v + np.sqrt(1.0 - wanted**2)[..., None] * side
    own = np.ones((h, w), dtype=bool)
    own[:, : w // 2] = False
    mask = facing_away_mask(own, n_dot_v_image(scene, {"normal": normal, "depth": np.full((h, w), 3.0)}, own))
    np.testing.assert_array_equal(mask, own & (wanted <= 0.0))


@pytest.fixture(scope="module")
def gold_run(tmp_path_factory, mitsuba_rgb, gpu_context):
    pytest.importorskip("MaterialX")
    pytest.importorskip("moderngl")
    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.errors import BackendError
    from atlasgen.materials.material import read_material_file
    from atlasgen.separable.materialx_oracle import gl_context
    from atlasgen.validate.run import validate_atlas

    try:
        gl_context()
    except BackendError as exc:
        pytest.skip(str(exc))
    root = tmp_path_factory.mktemp("mtlx-validate")
    (root / "gold.mtlx").write_text(GOLD)
    dds = root / "atlas.dds"
    write_bake(bake_atlas(read_material_file(root / "gold.mtlx")), dds)
    run = validate_atlas(dds, scenes=["front"], resolution=TINY, physical_spp=4, max_physical_spp=4)
    assert gl_context().error == "GL_NO_ERROR"
    return run, root


@pytest.mark.slow  # a MaterialX bake and two shader compilations: seconds of CPU
def test_the_model_reference_is_the_forward_render_and_the_mitsuba_route_agrees(gold_run):
    run, _ = gold_run
    (result,) = run.runs
    model = result.references["model"]
    assert model.variant == "moderngl" and model.description.startswith("forward render of MaterialX's GLSL")
    x = result.materialx
    assert x["reference"] == "forward" and x["document"].endswith("gold.mtlx") and x["material"] == "gold"
    assert x["forward_vs_mitsuba_plugin"]["psnr_db"] > 60.0  # the same shading, rasterised against ray-traced
    assert result.claimed["relative_rms_8bit_se"] > 0.0


@pytest.mark.slow
def test_the_forward_reference_leaves_out_normals_facing_away_where_materialx_shades_them_as_grazing(gold_run):
    """At 128x96 the back scene's sphere has silhouette pixels whose interpolated normal faces away from the camera:
    MaterialX's shader clamps N.V there and lights them, the separable atlas gives 0. The comparison leaves exactly
    those out and says how many; without them the cross-check and the PSNR are those of the rest."""
    from atlasgen.validate.metrics import display_clip
    from atlasgen.validate.run import validate_atlas

    _, root = gold_run
    run = validate_atlas(root / "atlas.dds", scenes=["back"], resolution=(128, 96), physical=False)
    (result,) = run.runs
    model = result.references["model"]
    assert model.mask is not None and model.mask.any()
    count = int(model.mask.sum())
    assert model.masked.startswith(f"{count} of the material's pixels") and "N.V <= 0" in model.masked
    shown = model.image[model.mask].max(axis=-1)
    assert np.all(shown > 0.0) and np.all(result.atlas_image[model.mask] == 0.0)  # the two conventions differ there
    facing = result.materialx["facing_away"]
    assert facing["pixels"] == count and facing["psnr_db_counting_them"] < model.metrics.psnr
    # The two figures differ by exactly those pixels: the squared error counting them is the rest's plus theirs.
    e = result.exposure
    theirs = float(((display_clip(model.image, e) - display_clip(result.atlas_image, e))[model.mask] ** 2).mean(-1).sum())
    kept = round(model.metrics.coverage * model.mask.size)
    mse_rest, mse_all = 10.0 ** (-model.metrics.psnr / 10.0), 10.0 ** (-facing["psnr_db_counting_them"] / 10.0)
    assert mse_all * (kept + count) == pytest.approx(mse_rest * kept + theirs, rel=1e-6)
    from atlasgen.reports.validation import write_validation

    html = write_validation(run, root / "report-back")["html"].read_text()
    assert f"{count} pixel" in html and f"{facing['psnr_db_counting_them']:.1f} dB counting them" in html
    assert result.materialx["forward_vs_mitsuba_plugin"]["psnr_db"] > 60.0


@pytest.mark.slow
def test_the_gold_over_roughconductor_is_within_the_probes_range(gold_run):
    run, _ = gold_run
    ratio = run.runs[0].materialx["oracle_over_physical"]
    assert "roughconductor" in ratio["reference"] and ratio["pairs"] > 10_000 and ratio["pixels"] > 50
    low, high = ratio["bsdf_min_max"]
    assert 0.99 < low < 1.0 < high < 1.06  # the probe: 0.998 to 1.049
    assert ratio["within_probe_range"] == (ratio["probe_range"][0] <= low and high <= ratio["probe_range"][1])
    p1, p50, p99 = ratio["pixel_p1_p50_p99"]
    assert 0.99 < p1 <= p50 <= p99 < 1.06


@pytest.mark.slow
def test_the_page_shows_the_document_representation_error_and_ratio(gold_run):
    from atlasgen.reports.validation import write_validation

    run, root = gold_run
    written = write_validation(run, root / "report")
    html = written["html"].read_text()
    assert "Imported from MaterialX" in html and "gold.mtlx" in html and "separable" in html
    claimed = run.runs[0].claimed
    assert f"{claimed['relative_rms_8bit']:.4f} ± {claimed['relative_rms_8bit_se']:.4f}" in html
    assert "shading over its physical twin" in html  # the pair: over uniform pairs, and per pixel
    assert "roughconductor" in html and "probe measured 0.998 to 1.049" in html and "within it" in html
    row = written["data"]["results"][0]
    assert (
        row["materialx"]["oracle_over_physical"]["bsdf_min_max"] == run.runs[0].materialx["oracle_over_physical"]["bsdf_min_max"]
    )


@pytest.mark.slow  # one MaterialX bake: the oracle's shader
def test_a_document_baked_with_flatten_default_validates_by_its_file_name(tmp_path):
    """`atlasgen validate lib.mtlx` read the document without flattening, so a material baked with --flatten default
    was refused as "driven by node ...; ... atlasgen bake --flatten default", the way it had been baked. The manifest
    records what was flattened, and the document is read as it was baked."""
    from pathlib import Path

    from click.testing import CliRunner

    from atlasgen.cli.main import app
    from atlasgen.io.atlas import read_atlas
    from atlasgen.validate.run import _material_names

    document = Path(__file__).resolve().parents[1] / "resources" / "materialx" / "textured.mtlx"
    atlas_path = tmp_path / "x.dds"
    baked = CliRunner().invoke(app, ["bake", str(document), "--flatten", "default", "-o", str(atlas_path), "-q"])
    assert baked.exit_code == 0, baked.output
    atlas = read_atlas(atlas_path)
    entries = {e.name: e for e in atlas.manifest.materials}
    assert all(e.params["materialx"]["flattened"] for e in entries.values())
    assert _material_names(document, atlas, entries) == sorted(entries, key=lambda n: entries[n].first_slice)
