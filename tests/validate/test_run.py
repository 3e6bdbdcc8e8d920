"""End to end: the atlas through the GPU renderer against Mitsuba; the consistency gate; bad input."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from atlasgen.errors import BackendError, InputError, SceneError
from tests.validate.validation_fixtures import TINY


def _result(run, material, scene, kind="model"):
    (r,) = [r for r in run.runs if r.material == material and r.scene == scene]
    return r, r.references.get(kind)


@pytest.mark.parametrize("scene", ["front", "back"])
def test_consistency_gate_lambert_atlas_against_mitsubas_diffuse(validation_run, scene):
    """Units, pi, camera and tone map line up: the atlas path against Mitsuba's own ``diffuse``."""
    r, ref = _result(validation_run, "matte", scene, "physical")
    assert "diffuse" in ref.description
    assert float(np.max(r.atlas_image)) > 0.05  # the scene is lit: a black image would agree trivially
    assert ref.metrics.psnr >= 50.0


@pytest.mark.parametrize("material", ["matte", "coat", "film", "skin", "leaf"])
def test_smooth_lut_models_match_their_model_reference(validation_run, material):
    """For smooth tables only resolution, 8 bits and filtering separate atlas and model."""
    for r in [r for r in validation_run.runs if r.material == material]:
        ref = r.references["model"]
        assert ref.metrics.psnr >= 45.0, (material, r.scene, ref.metrics.psnr)
        assert ref.metrics.flip < 0.05


def test_toon_steps_are_softened_by_filtering_and_measured_not_hidden(validation_run):
    r, ref = _result(validation_run, "cel", "front")
    assert math.isfinite(ref.metrics.psnr) and 15.0 < ref.metrics.psnr < 80.0
    assert r.atlas_seconds > 0 and ref.seconds > 0


def test_physical_references_render_where_they_exist(validation_run):
    kinds = {(r.material, r.scene): set(r.references) for r in validation_run.runs}
    for material in ("matte", "coat", "film", "skin", "leaf"):
        assert kinds[(material, "front")] == {"model", "physical"}
    for material in ("cel",):
        assert kinds[(material, "front")] == {"model"}
    _, film = _result(validation_run, "film", "front", "physical")
    assert film.variant == "llvm_ad_spectral" and np.isfinite(film.image).all() and film.image.max() > 0
    _, skin = _result(validation_run, "skin", "front", "physical")
    # Rendered at 4 spp, then with the samples its floor needs while the floor is within 10 dB
    # of the error, up to 16x: it stops converged or at the cap.
    assert 4 <= skin.spp <= 64 and np.isfinite(skin.image).all()
    assert skin.noise_floor_ok or skin.spp == 64


@pytest.mark.slow
def test_unknown_material_and_material_without_reference_fail_before_rendering(validation_atlas, tmp_path):
    from atlasgen.validate.run import plan_validation

    with pytest.raises(InputError, match="no material 'nosuch'; known: cel, coat"):
        plan_validation(validation_atlas, ["nosuch"])
    # A manifest entry of a type this atlasgen has no model for (e.g. from a newer atlasgen): refused for the whole
    # atlas, naming the field, since the renderer's include needs every entry's model.
    odd = tmp_path / "odd.dds"
    odd.write_bytes(validation_atlas.read_bytes())
    manifest = json.loads(validation_atlas.with_suffix(".json").read_text())
    manifest["materials"][0]["type"] = "hologram"
    odd.with_suffix(".json").write_text(json.dumps(manifest))
    name = manifest["materials"][0]["name"]
    with pytest.raises(InputError, match=r"odd.json: field 'materials\[0\].type': expected one of the models atlasgen "
                                         r"knows \(.*\), got 'hologram'$"):  # fmt: skip
        plan_validation(odd, [name])


@pytest.mark.slow
def test_unknown_scene_and_scene_without_placeholder(validation_atlas, tmp_path):
    from atlasgen.validate.run import plan_validation

    with pytest.raises(InputError, match="unknown validation scene; expected one of front, back"):
        plan_validation(validation_atlas, ["matte"], ["sideways"])
    path = tmp_path / "fixed.toml"
    path.write_text('[camera]\nposition = [0, 0, 3]\ntarget = [0, 0, 0]\n[[objects]]\nshape = "sphere"\nmaterial = "matte"\n')
    with pytest.raises(SceneError, match="fixed.toml: field 'objects': no object uses material = '\\$material'"):
        plan_validation(validation_atlas, ["matte"], [str(path)])


@pytest.mark.slow
def test_two_scenes_of_one_name_are_refused(validation_atlas, tmp_path):
    """A scene's name names its rows and images: a second 'front' showed the first's images beside its own figures."""
    from atlasgen.validate.run import plan_validation

    own = tmp_path / "x" / "front.toml"
    own.parent.mkdir()
    own.write_text('[camera]\nposition = [0, 0, 3]\ntarget = [0, 0, 0]\n[[objects]]\nshape = "sphere"\nmaterial = "$material"\n')
    with pytest.raises(InputError) as info:
        plan_validation(validation_atlas, ["matte"], ["front", str(own)])
    assert str(info.value) == (f"--scene {own}: a second scene named 'front' (the first: --scene front); expected "
                               "scenes of distinct names")  # fmt: skip
    with pytest.raises(InputError, match="a second scene named 'back'"):
        plan_validation(validation_atlas, ["matte"], ["back", "back"])


@pytest.mark.mitsuba  # needs drjit
def test_missing_llvm_backend_names_libllvm19(monkeypatch):
    dr = pytest.importorskip("drjit")

    from atlasgen.validate.backend import load_mitsuba

    monkeypatch.setattr(dr, "has_backend", lambda backend: False)
    with pytest.raises(BackendError, match="install libllvm19"):
        load_mitsuba("llvm_ad_rgb")


@pytest.mark.slow
def test_atlas_baked_by_another_model_version_is_refused(validation_atlas, tmp_path):
    """The model reference runs today's model code: a manifest with other parameters would mislead."""
    from atlasgen.validate.run import plan_validation

    odd = tmp_path / "old.dds"
    odd.write_bytes(validation_atlas.read_bytes())
    manifest = json.loads(validation_atlas.with_suffix(".json").read_text())
    coat = next(e for e in manifest["materials"] if e["name"] == "coat")
    del coat["params"]["ior"]
    coat["params"]["gain"] = 2.0
    odd.with_suffix(".json").write_text(json.dumps(manifest))
    with pytest.raises(InputError, match=r"field 'materials\[\d+\]\.params': expected the current 'fresnel' model's "
                                         r"parameters, got others \(missing ior; unknown gain\).*re-run atlasgen bake"):  # fmt: skip
        plan_validation(odd, ["coat"])


@pytest.mark.slow
def test_custom_scene_objects_with_fixed_materials_must_exist_in_the_atlas(validation_atlas, tmp_path):
    from atlasgen.validate.run import plan_validation

    text = ('[camera]\nposition = [0, 1, 3]\ntarget = [0, 0, 0]\n'
            '[[objects]]\nshape = "sphere"\nmaterial = "$material"\n'
            '[[objects]]\nshape = "plane"\nmaterial = "{}"\n')  # fmt: skip
    good, bad = tmp_path / "good.toml", tmp_path / "bad.toml"
    good.write_text(text.format("matte"))
    bad.write_text(text.format("marble"))
    plan = plan_validation(validation_atlas, ["coat"], [str(good)])
    assert [o.material for o in plan.scenes[0][1].objects] == ["$material", "matte"]
    with pytest.raises(SceneError, match=r"bad.toml: field 'objects\[1\].material': unknown material 'marble'; .*coat"):
        plan_validation(validation_atlas, ["coat"], [str(bad)])


def test_stochastic_references_report_their_noise_floor(validation_run):
    """volpath and spectral references render twice (two seeds); deterministic ones have no floor."""
    for material in ("skin", "film"):
        _, ref = _result(validation_run, material, "front", "physical")
        assert ref.noise_floor_db is not None and 0.0 < ref.noise_floor_db < 80.0
        assert ref.noise_floor_ok == (ref.noise_floor_db >= ref.metrics.psnr + 10.0)
    for material in ("matte", "leaf"):
        _, ref = _result(validation_run, material, "front", "physical")
        assert ref.noise_floor_db is None and ref.noise_floor_ok is None


def test_a_medium_reference_renders_each_object_alone_with_the_plane_as_a_slab(validation_run, mitsuba_rgb):
    """Skin's reference masks nothing: the sphere holds the medium and the plane is the top of a slab of it,
    each rendered alone, so the sphere casts no shadow on the plane (the deferred renderer casts none) and
    every pixel of either object is compared."""
    from atlasgen.validate.mitsuba_scene import cast_shadow_mask, object_mask
    from atlasgen.validate.scenes import bind_material, load_validation_scene, resize_scene

    r, ref = _result(validation_run, "skin", "back", "physical")
    assert ref.mask is None and ref.masked is None
    _, scene = load_validation_scene("back")
    scene = bind_material(resize_scene(scene, *TINY), "skin")
    shadows = cast_shadow_mask(mitsuba_rgb, scene)
    plane = object_mask(mitsuba_rgb, scene, [o.index for o in scene.objects if o.shape == "plane"])
    sphere = object_mask(mitsuba_rgb, scene, [o.index for o in scene.objects if o.shape == "sphere"])
    assert plane.mean() > 0.2 and sphere.mean() > 0.2 and not (plane & sphere).any()
    lum = ref.image.sum(-1)
    # Only the two objects' pixels hold a render, and the slab is lit on the plane's pixels.
    assert (lum[~(plane | sphere)] == 0).all() and lum[plane].mean() > 0 and lum[sphere].mean() > 0
    # In the sphere's cast shadow the slab is lit as the plane around it: against the atlas (no shadows
    # either) the shadowed pixels are no darker than the plane's others, where volpath with the sphere
    # in the scene made them less than half as bright.
    shaded, lit = plane & shadows, plane & ~shadows
    assert shaded.sum() > 3
    ratio = lambda where: lum[where].mean() / r.atlas_image.sum(-1)[where].mean()  # noqa: E731
    assert ratio(shaded) > 0.7 * ratio(lit), (ratio(shaded), ratio(lit))
    for material in ("matte", "film"):  # atlasgen_direct traces no shadow rays: nothing to mask
        assert _result(validation_run, material, "back", "physical")[1].mask is None


@pytest.mark.parametrize("scene_name", ["front", "back"])
def test_a_medium_comparison_is_split_by_object_from_the_g_buffer(validation_run, scene_name):
    """The skin's pixels split into the sphere and the flat part (the plane), each drawn alone by the renderer:
    together they are the material's pixels, and each holds the pixels whose centre ray meets that object first,
    by an independent closed form (a ray against the sphere of radius 0.5 at (0, 0.5, 0) and the square plane
    y = 0 of half-width 1.6), to within the silhouette's pixels, which the tessellation and the raster decide."""
    from atlasgen.render.camera import pixel_rays
    from atlasgen.validate.scenes import load_validation_scene, resize_scene

    r, ref = _result(validation_run, "skin", scene_name, "physical")
    parts = ref.metrics.parts
    assert set(parts) == {"sphere", "flat part"} and set(ref.part_floors) == set(parts)
    assert sum(p["coverage"] for p in parts.values()) == pytest.approx(ref.metrics.coverage)
    _, scene = load_validation_scene(scene_name)
    scene = resize_scene(scene, *TINY)
    origin = np.asarray(scene.camera.position, dtype=np.float64)
    d = pixel_rays(scene.camera, scene.width, scene.height)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    oc = origin - np.array([0.0, 0.5, 0.0])
    b = (d * oc).sum(-1)
    disc = b * b - (oc @ oc - 0.25)
    t_sphere = np.where(disc > 0, -b - np.sqrt(np.maximum(disc, 0.0)), np.inf)
    t_plane = -origin[1] / d[..., 1]
    hit = origin + t_plane[..., None] * d
    on_plane = (t_plane > 0) & (np.abs(hit[..., 0]) <= 1.6) & (np.abs(hit[..., 2]) <= 1.6) & (t_plane < t_sphere)
    sphere = np.isfinite(t_sphere) & (t_sphere > 0)
    edge = 0.1 * np.sqrt(sphere.sum())  # a silhouette's worth of pixels: a fraction of its circumference
    assert abs(parts["sphere"]["pixels"] - sphere.sum()) <= max(2, edge), (parts["sphere"]["pixels"], sphere.sum())
    assert abs(parts["flat part"]["pixels"] - on_plane.sum()) <= max(2, edge), (parts["flat part"]["pixels"], on_plane.sum())
    # Every part has its own floor, and the reference's floor rule covers each.
    for name, floor in ref.part_floors.items():
        psnr_db = parts[name]["psnr_db"]
        if ref.noise_floor_ok:
            assert floor >= psnr_db + 10.0


def test_a_reference_short_of_its_floor_gets_the_samples_the_floor_needs():
    """F(m) = F(n) + 10 log10(m / n): from a 30 dB floor at 64 spp, a 35 dB error needs
    35 + 10 + 1 (headroom) = 46 dB, 64 * 10^1.6 = 2548 spp, whole passes of 64: 2560."""
    from atlasgen.validate.run import _samples_for_floor

    assert _samples_for_floor(64, 30.0, 35.0) == 2560
    # Never less than twice the last count, even when the prediction is barely short.
    assert _samples_for_floor(64, 45.5, 35.0) == 128
    assert _samples_for_floor(4, 40.0, 25.0) == 8
    assert _samples_for_floor(4, 30.0, 25.0) == 16  # 4 * 10^0.6 = 15.9
    assert _samples_for_floor(64, float("inf"), 35.0) is None
    assert _samples_for_floor(64, 30.0, None) is None


@pytest.mark.slow
def test_materials_with_the_same_physics_share_their_reference_render(tmp_path, mitsuba_rgb, gpu_context, monkeypatch):
    """A closed-form skin and a copy of it (the same physics) render their volpath reference once
    per scene in one run (one render per object: the sphere and the plane's slab, each alone), and
    both are measured against that one image."""
    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.materials.material import read_materials
    from atlasgen.validate import run as module

    folder = tmp_path / "materials"
    folder.mkdir()
    for name in ("skin-a", "skin-b"):
        (folder / f"{name}.toml").write_text('type = "sss"\ncolour = [0.9, 0.7, 0.6]\nradius = 8.0\n')
    dds = tmp_path / "atlas.dds"
    write_bake(bake_atlas(read_materials([folder])), dds)
    rendered = []
    render = module._render_physical_scene
    monkeypatch.setattr(module, "_render_physical_scene", lambda *a: rendered.append(a[0]) or render(*a))
    run = module.validate_atlas(dds, scenes=["front"], resolution=TINY, physical_spp=4, max_physical_spp=4)
    assert len(rendered) == 2
    a, b = (r.references["physical"] for r in run.runs)
    assert a.image is not b.image and np.array_equal(a.image, b.image) and a.spp == b.spp == 4
    # Nothing outlives the run: the next one renders its reference again.
    module.validate_atlas(dds, ["skin-a"], scenes=["front"], resolution=TINY, physical_spp=4, max_physical_spp=4)
    assert len(rendered) == 4


def test_every_comparison_covers_the_materials_pixels_and_splits_off_grazing_ones(validation_run):
    """The front scene's frame is partly background: each figure says which fraction it compared, and
    the whole-frame PSNR (the background counted as exact) reads higher than the material's own."""
    for run in validation_run.runs:
        if run.scene != "front":
            continue
        for kind in ("model", "physical"):
            ref = run.references.get(kind)
            if ref is None:
                continue
            m = ref.metrics
            own = 1.0 - (ref.masked_fraction or 0.0)
            assert 0.2 < m.coverage < own, (run.material, kind)
            g, rest = m.regions["grazing"], m.regions["rest"]
            assert g["pixels"] > 0 and rest["pixels"] > 0 and g["coverage"] + rest["coverage"] == pytest.approx(m.coverage)
            if math.isfinite(m.psnr):
                assert m.whole_frame_psnr >= m.psnr


def test_each_result_names_its_look_reference_or_why_it_has_none(validation_run):
    from atlasgen.validate.run import GOAL_LOOK_FLIP, GOAL_LOOK_PSNR_DB

    looks = {(r.material, r.scene): r.look for r in validation_run.runs}
    matte = looks[("matte", "front")]
    assert matte["reference"] == "physical" and matte["compared"] == "its physical reference, Mitsuba diffuse"
    assert matte["goal"] == {"psnr_db": GOAL_LOOK_PSNR_DB, "flip": GOAL_LOOK_FLIP} and matte["goal_source"] == "default"
    assert looks[("gloss", "front")]["reference"] == "model"  # a separable material: its source BSDF
    assert looks[("gloss", "front")]["compared"].endswith("it was factored from")
    cel = looks[("cel", "front")]
    assert cel["reference"] is None and cel["why_none"].startswith("an artistic model")


def test_a_materials_own_look_goal_replaces_the_default():
    from types import SimpleNamespace

    from atlasgen.validate.run import GOAL_LOOK_FLIP, _look_goal

    entry = SimpleNamespace(extra={"validate": {"psnr_db": 28.0}}, fit=SimpleNamespace(source="physical"))
    model = SimpleNamespace(no_physical_reference="", model_reference_is_physical=False)
    run = SimpleNamespace(references={"physical": SimpleNamespace(description="Mitsuba principled: sheen 1, as given")})
    look = _look_goal(entry, model, run, physical=True)
    assert look == {"goal": {"psnr_db": 28.0, "flip": GOAL_LOOK_FLIP}, "goal_source": "material", "reference": "physical",
                    "compared": "the Mitsuba principled it was fitted from"}  # fmt: skip


@pytest.mark.slow
def test_a_second_run_with_a_reference_cache_renders_nothing(tmp_path, validation_atlas, mitsuba_rgb, gpu_context, monkeypatch):
    """Model and physical references (a deterministic one and a stochastic one that grows) are stored
    by what decides them; the second run finds every one and gets the same figures."""
    from atlasgen.validate import run as module

    cache = tmp_path / "references"
    args = dict(scenes=["front"], resolution=TINY, physical_spp=4, max_physical_spp=16, reference_cache=cache)
    first = module.validate_atlas(validation_atlas, ["matte", "skin"], **args)
    assert first.environment["reference_renders_stored"] >= 4 and any(cache.glob("*.npz"))

    def refuse(*a, **k):
        raise AssertionError("rendered again")

    for name in ("render_mitsuba", "render_pixel_centres", "_render_physical_scene"):
        monkeypatch.setattr(module, name, refuse)
    second = module.validate_atlas(validation_atlas, ["matte", "skin"], **args)
    assert second.environment["reference_renders_from_cache"] == first.environment["reference_renders_stored"]
    for a, b in zip(first.runs, second.runs):
        for kind in a.references:
            x, y = a.references[kind], b.references[kind]
            assert x.spp == y.spp and np.array_equal(x.image, y.image) and x.metrics.psnr == y.metrics.psnr
    # The key holds the reference code: other code, other key, and the render happens again.
    monkeypatch.setattr(module, "render_key", lambda *a: None)
    with pytest.raises(AssertionError, match="rendered again"):
        module.validate_atlas(validation_atlas, ["matte"], **args)


def test_reference_keys_are_canonical_across_processes():
    """The key is canonical JSON, not pickle: a fresh interpreter with another hash seed gets the same one."""
    import os
    import subprocess
    import sys

    code = ("from atlasgen.validate.reference_cache import render_key; from atlasgen.validate.scenes import "
            "load_validation_scene; print(render_key('3.9.1', load_validation_scene('front')[1], {'b': {'alpha', 'beta', 'gamma', 'delta', 'eps'}, 'a': 1}))")  # fmt: skip
    keys = {subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                           env={**os.environ, "PYTHONHASHSEED": seed}).stdout.strip() for seed in ("1", "2")}  # fmt: skip
    assert len(keys) == 1 and len(next(iter(keys))) == 64


@pytest.mark.slow
def test_validation_reads_the_atlas_once_and_takes_fitted_slices_from_the_bake_cache(tmp_path, mitsuba_rgb, gpu_context,
                                                                                      monkeypatch):  # fmt: skip
    """Issue 21 item 7: one read and one hash of the atlas for two scenes; a fitted material's slice from the bake
    cache, so the physics fit never runs; a material file named by hashing its bytes, never parsed."""
    import atlasgen.io.atlas as atlas_io
    import atlasgen.models.physical_fit as physical_fit
    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.bake.workers import fill_cache
    from atlasgen.materials.material import read_materials
    from atlasgen.validate import run as module

    folder = tmp_path / "materials"
    folder.mkdir()
    (folder / "coat.toml").write_text('type = "fresnel"\ncolour = [0.6, 0.2, 0.1]\nior = 1.5\nfrom = "physical"\n')
    (folder / "clay.toml").write_text('type = "lambert"\ncolour = [0.7, 0.4, 0.3]\n')
    materials = read_materials([folder])
    cache, dds = tmp_path / "cache", tmp_path / "atlas.dds"
    fill_cache(cache, materials)
    write_bake(bake_atlas(materials, cache_dir=cache), dds)

    counts = {"read_dds": 0, "texel_sha256": 0}
    for name in counts:
        original = getattr(atlas_io, name)
        monkeypatch.setattr(
            atlas_io, name, lambda *a, _f=original, _n=name, **k: counts.__setitem__(_n, counts[_n] + 1) or _f(*a, **k)
        )

    def refuse(*a, **k):
        raise AssertionError("fitted again")

    monkeypatch.setattr(physical_fit.FittedSlice, "_tables", {})
    monkeypatch.setattr(physical_fit, "bake_from_physics", refuse)
    monkeypatch.setattr(physical_fit.Model, "bake", refuse)  # no float table is baked again either
    monkeypatch.setattr(module, "read_material_file", refuse)
    run = module.validate_atlas(dds, [folder / "coat.toml", folder / "clay.toml"], scenes=["front", "back"],
                                resolution=(24, 18), bake_cache=cache, physical=False)  # fmt: skip
    assert counts == {"read_dds": 1, "texel_sha256": 1}
    assert run.environment["float_slices_from_bake_cache"] == ["coat", "clay"]
    assert {r.material for r in run.runs} == {"coat", "clay"} and all(r.breakdown is not None for r in run.runs)
    # Without the cache, the fit runs (and is refused here).
    monkeypatch.setattr(physical_fit.FittedSlice, "_tables", {})
    with pytest.raises(AssertionError, match="fitted again"):
        module.validate_atlas(dds, ["coat"], scenes=["front"], resolution=(24, 18), physical=False)
