"""bench/run.py's sections measured elsewhere: a lent GPU machine's render data, imported and kept.

The data here is made up, shaped as bench/render.py's run() returns it; what is checked is how it is
judged and worded, and that a full `make bench` keeps an imported section.
"""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[2] / "bench"


@pytest.fixture
def bench(monkeypatch):
    """bench/run.py and bench/render.py as modules, imported from bench/ as run.py imports its sections."""
    monkeypatch.syspath_prepend(str(BENCH))
    for name in ("run", "render", "render_gpu"):
        sys.modules.pop(name, None)
    yield importlib.import_module("run"), importlib.import_module("render")
    for name in ("run", "render", "render_gpu", "fake_section"):
        sys.modules.pop(name, None)


def render_data(render, software: bool, lighting_256_ms: float) -> dict:
    """A run's data: every (lights, translucent) row, each pass 1 ms but the 256-light lighting pass."""
    rows = []
    for lights in render.LIGHTS:
        for translucent in render.TRANSLUCENT:
            passes = {p: 1.0 for p in render.PASSES}
            if lights == 256:
                passes["lighting"] = lighting_256_ms
            rows.append({"lights": lights, "translucent": translucent, "range": 2.0, "lights_per_pixel_mean": 4.0,
                         "lights_per_pixel_max": 9, "lights_per_tile_mean": 6.0, "lights_per_tile_max": 40,
                         "overflowing_tiles": 0, "frame_ms": 5.0, "frame_min_ms": 4.5, "brute_ms": 60.0,
                         "brute_min_ms": 59.0, "brute_repeats": 3, "passes_ms": passes,
                         "brute_passes_ms": {"lighting": 50.0} if lights == 256 else {}})  # fmt: skip
    device = "Some GPU (Vulkan, DiscreteGPU)" if not software else "llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, CPU)"
    return {"device": device, "software": software, "load_average": 0.1, "cpus": 16, "width": 1280, "height": 720,
            "warmup": 1, "repeats": 11, "atlas": "build/atlas.dds", "timing": "timestamps", "rows": rows,
            "validation_errors": []}  # fmt: skip


@pytest.mark.parametrize(("lighting_ms", "verdict"), [(0.05, "met"), (0.2, "**not met**")])
def test_a_real_gpu_run_is_judged_on_its_lighting_pass(bench, lighting_ms, verdict):
    _, render = bench
    text = render.markdown(render_data(render, software=False, lighting_256_ms=lighting_ms))
    assert text.startswith("## Renderer (deferred, WebGPU): ranged lights culled per tile, on a real GPU\n")
    assert (f"on this GPU (Some GPU (Vulkan, DiscreteGPU); GPU timestamps): {lighting_ms:.3f} ms (goal: at most 0.1 ms; "
            f"the talk quotes about 0.5 ms on the Xbox 360), {verdict}.") in text  # fmt: skip
    # The lavapipe goals are figures beside it, not verdicts.
    assert "the full loop at 256 lights 12.0x the culled frame" in text and "at most 150 ms" not in text


def test_a_software_run_says_the_real_gpu_figure_is_not_measured(bench):
    _, render = bench
    text = render.markdown(render_data(render, software=True, lighting_256_ms=0.05))
    assert "**not measured**, this run's adapter is a software rasteriser" in text
    assert "on a real GPU\n" not in text and "at most 150 ms: 5.0 ms" in text


def test_an_imported_section_is_written_and_kept_by_a_full_run(bench, tmp_path, monkeypatch):
    run, render = bench
    monkeypatch.setattr(run, "ROOT", tmp_path)
    saved = tmp_path / "render-gpu.json"
    saved.write_text(json.dumps(render_data(render, software=False, lighting_256_ms=0.05)))
    assert run.main(["--import", "render_gpu", str(saved)]) == 0
    assert "0.050 ms" in (tmp_path / "BENCHMARKS.md").read_text()
    # Only the sections measured elsewhere can be imported.
    assert run.main(["--import", "render", str(saved)]) == 2

    # A full run (here of one made-up section) writes the files anew and keeps the imported section.
    fake = type(sys)("fake_section")
    fake.run = lambda: {"markdown": "## Fake\n", "data": {"x": 1}}
    monkeypatch.setitem(sys.modules, "fake_section", fake)
    monkeypatch.setattr(run, "SECTIONS", ["fake_section"])
    monkeypatch.setattr(sys, "argv", ["run.py"])
    assert run.main() == 0
    text = (tmp_path / "BENCHMARKS.md").read_text()
    assert "## Fake" in text and "0.050 ms" in text
    data = json.loads((tmp_path / "BENCHMARKS.json").read_text())
    assert data["fake_section"] == {"x": 1} and data["render_gpu"]["software"] is False


def test_paired_frames_interleave_and_divide_each_full_loop_frame_by_the_culled_frames_before_it(bench, monkeypatch):
    _, render = bench
    calls = []
    # Scripted frame times: the load doubles half-way, after the first pair.
    times = iter([10.0, 12.0, 11.0, 100.0, 20.0, 24.0, 22.0, 200.0])
    monkeypatch.setattr(render, "_timed_ms", lambda fn: (fn(), next(times))[1])
    timed = render.paired_ms(lambda: calls.append("c"), lambda: calls.append("b"), pairs=2, brute_warmup=1, warmup=1,
                             repeats=5)  # fmt: skip
    assert calls == ["c", "b"] + ["c", "c", "c", "b"] * 2
    assert timed["culled"] == [10.0, 12.0, 11.0, 20.0, 24.0, 22.0] and timed["brute"] == [100.0, 200.0]
    # Each pair sees one load: the ratio of each is 100 / 11, where the medians taken apart would give 150 / 16.5.
    assert timed["ratios"] == pytest.approx([100.0 / 11.0, 200.0 / 22.0])
    # Where the full loop takes seconds it is not warmed up (its pipelines are the culled frames').
    calls.clear()
    times = iter([1.0, 10.0])
    render.paired_ms(lambda: calls.append("c"), lambda: calls.append("b"), pairs=1, brute_warmup=0, warmup=1, repeats=1)
    assert calls == ["c", "c", "b"]


def test_the_256_light_goal_is_the_median_of_the_pairs_ratios_with_their_range(bench):
    _, render = bench
    data = render_data(render, software=True, lighting_256_ms=5.0)
    for row in data["rows"]:
        row["brute_repeats"], row["frames"], row["ratios"] = (1, 11, [12.0]) if row["lights"] == 1024 else (3, 12, [12.0] * 3)
    at_256 = next(r for r in data["rows"] if r["lights"] == 256 and r["translucent"] == 0)
    at_256["ratios"] = [9.0, 10.5, 30.0]  # the medians' ratio, 60 / 5, would be 12
    goal = render.judge(data)["brute_over_culled_256"]
    assert goal == [10.5, render.GOAL_BRUTE_OVER_CULLED_256, True]
    text = render.markdown(data)
    assert "frame against frame: 10.5x (9.0–30.0), met." in text
    assert "3 times, 4 culled frames then one full-loop frame (1 time, 11 culled frames, at 1024 lights" in text
    at_256["ratios"] = [9.0, 9.5, 30.0]
    assert render.judge(data)["brute_over_culled_256"][2] is False


def test_data_measured_before_the_pairs_is_judged_on_the_ratio_of_its_medians(bench):
    _, render = bench
    data = render_data(render, software=True, lighting_256_ms=5.0)
    assert render.judge(data)["brute_over_culled_256"][0] == pytest.approx(12.0)
    assert "Frames: median of 11 after 1 warm-up" in render.markdown(data)


@pytest.mark.parametrize("argv", [["--help"], ["render", "--only"], ["rendr"]])
def test_a_name_that_is_no_section_writes_nothing(bench, tmp_path, monkeypatch, capsys, argv):
    """`bench/run.py --help` used to run '--help' as a section, and write it into BENCHMARKS.md and
    BENCHMARKS.json as a failed one."""
    run, _ = bench
    monkeypatch.setattr(run, "ROOT", tmp_path)
    monkeypatch.setattr(run, "SECTIONS", ["render"])
    status = run.main(argv)
    assert status == (0 if argv == ["--help"] else 2)
    assert not (tmp_path / "BENCHMARKS.md").exists() and not (tmp_path / "BENCHMARKS.json").exists()
    printed = capsys.readouterr()
    assert "usage: bench/run.py" in printed.out + printed.err


def test_the_goals_over_one_light_are_judged_on_interleaved_pairs(bench):
    _, render = bench
    data = render_data(render, software=True, lighting_256_ms=0.05)
    for row in data["rows"]:
        if row["lights"] == 1:
            row["frame_ms"] = 2.0  # apart, 256 lights would be 2.5x the 1-light frame
        if row["lights"] == 256 and row["translucent"] == 0:
            row["over_one_ratios"] = [1.9, 1.4, 1.5, 1.6, 1.2]
    goals = render.judge(data)
    assert goals["frame_256_over_1"] == [1.5, 2.0, True]
    # 1024 lights has no pairs in this data: the ratio of the two rows' medians, as older data is judged.
    assert goals["frame_1024_over_1"] == [2.5, 3.0, True]
    text = render.markdown(data)
    assert "- 256 lights at most 2x the 1-light frame: 1.50x (1.20–1.90), met." in text
    assert "- 1024 lights at most 3x the 1-light frame: 2.50x, met." in text
    assert "The goals on 256 lights over one light are the median of 5 ratios" in text
