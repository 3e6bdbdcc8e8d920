"""The lighting-cost harness: its arithmetic, with a stubbed timer (no timed assertions)."""

from __future__ import annotations

import itertools

import pytest

from atlasgen.render.cost import cost_per_pixel_per_light, measure_lighting_cost, relative_costs, time_runs


def _stub_timer(durations):
    """A timer whose consecutive (start, stop) reads are ``durations`` apart."""
    clock = itertools.accumulate(itertools.chain.from_iterable((1.0, d) for d in durations))
    return lambda: next(clock)


def test_time_runs_returns_each_timed_call_after_the_warmup():
    calls = []
    runs = time_runs(lambda: calls.append(1), repeats=3, warmup=2, timer=_stub_timer([0.5, 0.25, 2.0]))
    assert runs == [0.5, 0.25, 2.0]
    assert len(calls) == 5


def test_cost_is_the_median_per_pixel_per_light_in_ns():
    assert cost_per_pixel_per_light([3e-3, 1e-3, 2e-3], pixels=1000, lights=4) == pytest.approx(2e-3 * 1e9 / 4000)
    with pytest.raises(ValueError):
        cost_per_pixel_per_light([1e-3], pixels=0, lights=1)


def test_relative_costs_divide_by_the_baseline_of_the_same_run():
    assert relative_costs({"lut": 2.0, "separable:8": 10.0}, "lut") == {"lut": 1.0, "separable:8": 5.0}


@pytest.mark.slow
def test_measure_lighting_cost_covers_the_frame_and_divides_by_pixels_and_lights(gpu_device, write_material, tmp_path):
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_materials
    from atlasgen.render.atlas_texture import RenderAtlas
    from atlasgen.render.renderer import Renderer

    write_material("clay", 'type = "lambert"\ncolour = [0.5, 0.5, 0.5]\n')
    write_material("metal", 'type = "separable"\nsource = "ggx"\nalpha = 0.3\nrepresentation = "analytic"\n')
    result = bake_atlas(read_materials([tmp_path / "materials"]))
    renderer = Renderer(RenderAtlas(result.levels, True, result.manifest, result.include, "test"), gpu_device)
    for name in ("clay", "metal"):
        cost = measure_lighting_cost(renderer, name, width=32, height=24, lights=3, repeats=5, warmup=1,
                                     timer=_stub_timer([4e-3, 1e-3, 3e-3, 2e-3, 5e-3]))  # fmt: skip
        assert cost.pixels == 32 * 24 and cost.lights == 3 and cost.device == gpu_device.name
        assert cost.median_s == pytest.approx(3e-3)
        assert cost.ns_per_pixel_per_light == pytest.approx(3e-3 * 1e9 / (32 * 24 * 3))
