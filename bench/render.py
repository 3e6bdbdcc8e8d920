"""Benchmark of the deferred renderer: ranged lights culled per tile, against the full loop, pass by pass.

Configurations at 1280x720: a floor and six opaque spheres (+ four translucent spheres), lit by
1, 16, 64, 256 or 1024 ranged point lights scattered over the scene. The single light's range
covers the whole scene; from 16 lights up, the ranges are chosen so that about
``TARGET_PER_PIXEL`` lights reach the mean pixel, and the mean and maximum are measured (lights
per pixel from the g-buffer read back, lights per tile from the culling pass's lists read back).

Each frame figure is the median of about ``REPEATS`` frames after ``WARMUP`` (shader compilation
and first-touch costs excluded): every pass from the g-buffer to the outlines, submitted and waited
for, no read-back. The baseline is the same frame with culling off (every light tested at every
pixel), in the same run; it gets fewer frames where it takes seconds. Culled and full-loop frames
are interleaved (:func:`paired_ms`): each full-loop frame follows a few culled ones and is divided
by their median, so a change in the machine's load between the two falls on both, and the spread
of those ratios is the figure's uncertainty. Pass times come from GPU timestamp queries where the
device has them, else from fences (each pass submitted and waited for alone); the section says
which. The machine is shared: the goals are ratios within one run.

Run alone: ``python bench/run.py render`` (or ``python bench/render.py`` to print it).
"""

from __future__ import annotations

import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
WIDTH, HEIGHT = 1280, 720
LIGHTS = (1, 16, 64, 256, 1024)
TRANSLUCENT = (0, 4)
# Eleven frames, not five: on a shared 2-CPU machine one frame in five can be slowed by another process, and the
# 1-light frame is every ratio's denominator.
WARMUP, REPEATS = 1, 11
#: Lights reaching the mean covered pixel, from 16 lights up.
TARGET_PER_PIXEL = 4.0
#: The issue's goals, as ratios of medians in one run (and one absolute figure on this machine).
GOAL_MS = 150.0  # 16 lights + 4 translucent objects on this machine's software GPU
GOAL_256_OVER_1 = 2.0
GOAL_1024_OVER_1 = 3.0
GOAL_BRUTE_OVER_CULLED_256 = 10.0
#: The goals on N lights over the 1-light frame (opaque scene): N -> at most this ratio.
GOAL_OVER_ONE = {256: GOAL_256_OVER_1, 1024: GOAL_1024_OVER_1}
#: Issue 22's goal for the lighting pass at 1280x720 with 256 ranged lights on a real GPU, and the talk's own figure
#: for its material-lookup lighting pass on the Xbox 360 (both quoted, in ms).
GOAL_GPU_LIGHTING_MS = 0.1
TALK_XBOX_360_MS = 0.5
#: Interleaved pairs of the N-light and 1-light frames behind the goals on N lights over one (:func:`paired_over_one`),
#: and the frames of each kind in a pair.
PAIRS_OVER_ONE = 5
FRAMES_PER_PAIR = 3
PASSES = ("gbuffer", "culling", "lighting", "translucency", "outlines")

# The scene's LUT materials, from build/atlas.dds, or baked in memory when it is absent.
SCENE_MATERIALS = ("terracotta", "red-plastic", "glazed-ceramic", "skin", "toon-hero", "beetle-shell")


def load_atlas():
    """build/atlas.dds with its manifest and include if baked, else a small in-memory bake."""
    from atlasgen.render.atlas_texture import RenderAtlas, read_render_atlas

    built = ROOT / "build" / "atlas.dds"
    if built.exists() and built.with_suffix(".wgsl").exists():
        atlas = read_render_atlas(built)
        if atlas.manifest.materials:
            return atlas, built.relative_to(ROOT).as_posix()
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_materials

    files = [ROOT / "materials" / f"{name}.toml" for name in SCENE_MATERIALS]
    # A bake cache under build/: the fitted slices (skin's volumetric fit takes minutes on a loaded
    # machine) are baked once per code version, not once per benchmark run.
    result = bake_atlas(read_materials([f for f in files if f.exists()]), cache_dir=ROOT / "build" / "bench-bake-cache")
    atlas = RenderAtlas(result.levels, result.dxgi_format == 29, result.manifest, result.include, "in-memory bake")
    return atlas, "in-memory bake of " + ", ".join(SCENE_MATERIALS)


def light_positions(count: int, seed: int = 22) -> np.ndarray:
    """``count`` points scattered over the visible floor and around the spheres (floor at y = -1)."""
    rng = np.random.default_rng(seed)
    return rng.uniform([-9.0, -0.8, -9.0], [9.0, 2.5, 5.0], size=(count, 3))


def bench_scene(materials: list[str], lights: int, translucent: int, light_range: float | None = None):
    """A floor, six opaque spheres, ``translucent`` glass spheres and ``lights`` ranged point lights
    (:func:`light_positions`), each of range ``light_range`` (default: the first guess of :func:`first_range`)."""
    from atlasgen.materials.scene import parse_scene

    lines = [
        "[camera]", "position = [0, 3, 10]", "target = [0, 0, 0]", "fov = 55",
        "[image]", f"width = {WIDTH}", f"height = {HEIGHT}",
        "[[objects]]", "shape = 'plane'", f"material = '{materials[0]}'", "translate = [0, -1, 0]", "scale = 12",
    ]  # fmt: skip
    for i in range(6):
        x = -5 + 2 * i
        lines += ["[[objects]]", "shape = 'sphere'", f"material = '{materials[i % len(materials)]}'",
                  f"translate = [{x}, 0, -1]", "gloss = 0.6"]  # fmt: skip
    for i in range(translucent):
        x = -3 + 2 * i
        lines += ["[[objects]]", "shape = 'sphere'", f"material = '{materials[(i + 1) % len(materials)]}'",
                  f"translate = [{x}, 0.2, 2]", "scale = 0.9", "opacity = 0.5"]  # fmt: skip
    r = first_range(lights) if light_range is None else light_range
    for p in light_positions(lights).tolist() if lights > 1 else [[0.0, 3.0, 2.0]]:
        # Intensity ~ r^2: a light is as bright at half its range whatever the count.
        lines += ["[[lights]]", "type = 'point'", f"position = [{p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}]",
                  f"intensity = {0.5 * r * r / max(lights, 1) ** 0.5:.6f}", f"range = {r:.6f}"]  # fmt: skip
    import tomllib

    return parse_scene(tomllib.loads("\n".join(lines)), "bench-scene")


def first_range(lights: int) -> float:
    """The range that would give TARGET_PER_PIXEL lights per floor point if the lights lay on it:
    N pi r^2 = TARGET A over the lights' area A (18 x 14); 40 for one light (the whole scene)."""
    if lights <= 1:
        return 40.0
    return math.sqrt(TARGET_PER_PIXEL * 18.0 * 14.0 / (math.pi * lights))


def per_pixel(renderer, scene):
    """(mean, max) lights reaching a covered pixel, (mean, max) lights per covered tile, overflowing tiles."""
    from atlasgen.render.culling import lights_reaching, overflowing_tiles
    from atlasgen.render.layout import TILE_SIZE

    result = renderer.render(scene, outlines=False)
    depth = result.aov("depth")
    covered = np.isfinite(depth)
    lists = result.tile_lists
    counts = lights_reaching(scene, depth, lists)[covered]
    tile_covered = np.zeros(lists.counts.shape, dtype=bool)
    ty, tx = np.nonzero(covered)
    tile_covered[ty // TILE_SIZE, tx // TILE_SIZE] = True
    tiles = lists.counts[tile_covered]
    return float(counts.mean()), int(counts.max()), float(tiles.mean()), int(tiles.max()), overflowing_tiles(lists)


def calibrated_range(renderer, names, lights: int, tolerance: float = 0.05, tries: int = 8) -> float:
    """The range giving TARGET_PER_PIXEL lights per covered pixel (opaque scene) within ``tolerance``:
    from the first guess, a secant step in log r, log mean at a time (a light above the floor reaches
    more of it as r grows than r^2 says, less when short), ``tries`` renders at most; the range of the
    closest mean if none is within."""
    r = first_range(lights)
    if lights <= 1:
        return r
    tried = []  # (|log(mean / target)|, log r, log mean)
    for _ in range(tries):
        mean = max(per_pixel(renderer, bench_scene(names, lights, 0, r))[0], 1e-3)
        miss = math.log(TARGET_PER_PIXEL / mean)
        if abs(mean / TARGET_PER_PIXEL - 1.0) <= tolerance:
            return r
        slope = 2.0  # mean ~ r^2 for lights on the floor
        if tried and tried[-1][1] != math.log(r) and tried[-1][2] != math.log(mean):
            slope = min(max((math.log(mean) - tried[-1][2]) / (math.log(r) - tried[-1][1]), 0.5), 4.0)
        tried.append((abs(miss), math.log(r), math.log(mean)))
        r *= math.exp(miss / slope)
    return math.exp(min(tried)[1])


def paired_ms(culled, brute, pairs: int, brute_warmup: int, warmup: int = WARMUP, repeats: int = REPEATS) -> dict:
    """Culled and full-loop frames interleaved: ``pairs`` times, ceil(``repeats`` / ``pairs``) culled frames then one
    full-loop frame, after ``warmup`` culled and ``brute_warmup`` full-loop frames (``culled``, ``brute``: functions
    that draw one frame and wait).

    Returns the frame times (ms) and, per pair, the full-loop frame over the median of the culled frames just before
    it: on a shared machine the load drifts over a run, and a ratio of two medians taken minutes apart would carry the
    drift, where each pair's frames see about the same load.
    """
    for _ in range(warmup):
        culled()
    for _ in range(brute_warmup):
        brute()
    per_pair = -(-repeats // pairs)
    culled_ms, brute_ms, ratios = [], [], []
    for _ in range(pairs):
        group = [_timed_ms(culled) for _ in range(per_pair)]
        full = _timed_ms(brute)
        culled_ms += group
        brute_ms.append(full)
        ratios.append(full / statistics.median(group))
    return {"culled": culled_ms, "brute": brute_ms, "ratios": ratios}


def paired_over_one(frame, one, pairs: int = PAIRS_OVER_ONE, per_pair: int = FRAMES_PER_PAIR) -> list[float]:
    """The frame ``frame`` over the 1-light frame ``one`` (functions that draw one frame and wait), ``pairs`` times:
    ``per_pair`` frames of each, interleaved, the ratio of their medians. The goals on N lights over one light are
    ratios of frames measured minutes apart otherwise, and the shared machine's load drifts in between."""
    ratios = []
    for _ in range(pairs):
        mine, base = [], []
        for _ in range(per_pair):
            mine.append(_timed_ms(frame))
            base.append(_timed_ms(one))
        ratios.append(statistics.median(mine) / statistics.median(base))
    return ratios


def _timed_ms(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return (time.perf_counter() - t0) * 1000.0


def pass_times(renderer, frame, repeats: int = REPEATS) -> tuple[dict, str]:
    """Median ms per pass label over ``repeats`` frames, and the method used (timestamps or fences)."""
    from atlasgen.render.timing import PassTimer, has_timestamps, time_passes

    timer = PassTimer(renderer.device) if has_timestamps(renderer.device) else None
    runs, method = [], ""
    for _ in range(repeats):
        times, method = time_passes(renderer, frame, timer=timer)
        runs.append(times)
    return {
        label: statistics.median(r.get(label, 0.0) for r in runs) for label in PASSES if any(label in r for r in runs)
    }, method


def _brute_repeats(lights: int) -> tuple[int, int]:
    """(warm-up, frames) of the full loop: one frame at 1024 lights, where it takes seconds on a software GPU
    (its pipelines are the culled frame's, already warm), three after one below, 256 included: its ratio is a goal."""
    return (0, 1) if lights >= 1024 else (1, 3)


def _gpu_goal_line(software: bool, device: str, lighting_ms: float, method: str, verdict: str) -> str:
    """The goal line for the lighting pass on a real GPU: measured where this run's adapter is one, else why not."""
    goal = f"goal: at most {GOAL_GPU_LIGHTING_MS:g} ms; the talk quotes about {TALK_XBOX_360_MS:g} ms on the Xbox 360"
    if software:
        return (f"- The lighting pass at {WIDTH}x{HEIGHT} with 256 ranged lights on a real GPU ({goal}): **not measured**, "
                f"this run's adapter is a software rasteriser ({device}).")  # fmt: skip
    timing = "GPU timestamps" if method == "timestamps" else "fences, submission overhead included"
    return (f"- The lighting pass at {WIDTH}x{HEIGHT} with 256 ranged lights on this GPU ({device}; {timing}): "
            f"{lighting_ms:.3f} ms ({goal}), {verdict}.")  # fmt: skip


def run() -> dict:
    import os

    from atlasgen.render.renderer import Renderer

    load, cpus = os.getloadavg()[0], os.cpu_count()
    atlas, atlas_source = load_atlas()
    renderer = Renderer(atlas)
    device = renderer.ctx.name
    software = renderer.ctx.is_software  # a CPU rasteriser (lavapipe) cannot measure the real-GPU goal
    # The same LUT materials whichever atlas was found, so that the scene is the same (toon-hero's
    # outlines included): LUT slices are the common case; separable ones cost more per pixel.
    names = [name for name in SCENE_MATERIALS if name in atlas.manifest.names] or atlas.manifest.names
    rows = []
    method = ""
    one_frame = renderer.prepare(bench_scene(names, 1, 0, first_range(1)))

    def one():
        renderer.submit(renderer.encode_frame(one_frame))

    for lights in LIGHTS:
        light_range = calibrated_range(renderer, names, lights)
        for translucent in TRANSLUCENT:
            scene = bench_scene(names, lights, translucent, light_range)
            mean_px, max_px, mean_tile, max_tile, overflow = per_pixel(renderer, scene)
            frame = renderer.prepare(scene)
            brute = renderer.prepare(scene, culling=False)
            brute_warmup, pairs = _brute_repeats(lights)
            draw = lambda: renderer.submit(renderer.encode_frame(frame))  # noqa: E731
            timed = paired_ms(draw, lambda: renderer.submit(renderer.encode_frame(brute)), pairs, brute_warmup)
            frame_ms, frame_min = statistics.median(timed["culled"]), min(timed["culled"])
            brute_ms, brute_min = statistics.median(timed["brute"]), min(timed["brute"])
            over_one = paired_over_one(draw, one) if translucent == 0 and lights in GOAL_OVER_ONE else []
            passes, method = pass_times(renderer, frame)
            # The full loop's passes once, at the goal's count: what the lighting pass alone gains.
            brute_passes = pass_times(renderer, brute, repeats=1)[0] if lights == 256 else {}
            rows.append({"lights": lights, "translucent": translucent, "range": light_range,
                         "lights_per_pixel_mean": mean_px, "lights_per_pixel_max": max_px,
                         "lights_per_tile_mean": mean_tile, "lights_per_tile_max": max_tile, "overflowing_tiles": overflow,
                         "frame_ms": frame_ms, "frame_min_ms": frame_min, "brute_ms": brute_ms, "brute_min_ms": brute_min,
                         "brute_repeats": pairs, "brute_warmup": brute_warmup, "frames": len(timed["culled"]), "ratios": timed["ratios"],
                         "over_one_ratios": over_one,
                         "passes_ms": passes, "brute_passes_ms": brute_passes,
                         "device": device})  # fmt: skip
            print(f"bench render: {lights} lights, {translucent} translucent: range {light_range:.2f}, "
                  f"{mean_px:.2f} lights/pixel (max {max_px}), frame {frame_ms:.1f} ms, full loop {brute_ms:.1f} ms, "
                  f"ratios {', '.join(f'{x:.2f}' for x in timed['ratios'])}, "
                  f"passes {passes}", file=sys.stderr, flush=True)  # fmt: skip
    errors = renderer.ctx.take_errors()
    data = {"device": device, "software": software, "load_average": load, "cpus": cpus, "width": WIDTH, "height": HEIGHT,
            "warmup": WARMUP, "repeats": REPEATS, "atlas": atlas_source, "timing": method, "rows": rows,
            "validation_errors": errors}  # fmt: skip
    goals = judge(data)
    lit_culled = _row(rows, 256, 0)["passes_ms"]["lighting"]
    data.update(goals=goals, goal_ms=GOAL_MS, goal_met=goals["frame_16_lights_4_translucent_ms"][2],
                real_gpu_lighting_ms=None if software else lit_culled)  # fmt: skip
    return {"markdown": markdown(data), "data": data}


def _row(rows, lights: int, translucent: int) -> dict:
    return next(r for r in rows if r["lights"] == lights and r["translucent"] == translucent)


def _software(data) -> bool:
    """Whether the run's adapter was a software rasteriser (older data: it then has no real-GPU goal)."""
    return data["software"] if "software" in data else "gpu_lighting_256_ms" not in data.get("goals", {})


def full_loop_ratio(row) -> float:
    """The full loop over the culled frame: the median of the interleaved pairs' ratios (:func:`paired_ms`), or, in
    data measured before the pairs, the ratio of the two medians."""
    return statistics.median(row["ratios"]) if row.get("ratios") else row["brute_ms"] / row["frame_ms"]


def over_one_ratio(rows, lights: int) -> float:
    """The opaque ``lights``-light frame over the 1-light frame: the median of the interleaved pairs' ratios
    (:func:`paired_over_one`), or, in data measured before the pairs, the ratio of the two rows' medians."""
    row = _row(rows, lights, 0)
    if row.get("over_one_ratios"):
        return statistics.median(row["over_one_ratios"])
    return row["frame_ms"] / _row(rows, 1, 0)["frame_ms"]


def _over_one_cell(rows, lights: int) -> str:
    """:func:`over_one_ratio` with the range of the pairs' ratios where there are several."""
    return f"{over_one_ratio(rows, lights):.2f}x{_spread(_row(rows, lights, 0).get('over_one_ratios'), '.2f')}"


def _spread(ratios, digits: str) -> str:
    """`` (low–high)`` of several pairs' ratios, else nothing."""
    ratios = ratios or []
    return f" ({min(ratios):{digits}}–{max(ratios):{digits}})" if len(ratios) > 1 else ""


def _ratio_cell(row) -> str:
    """The full loop over the culled frame, with the range of the pairs' ratios where there are several."""
    return f"{full_loop_ratio(row):.1f}x{_spread(row.get('ratios'), '.1f')}"


def judge(data) -> dict:
    """Each goal: [measured, goal, met], from the rows of one run."""
    rows = data["rows"]
    at_256 = _row(rows, 256, 0)
    over_one = {n: over_one_ratio(rows, n) for n in GOAL_OVER_ONE}
    speedup_256 = full_loop_ratio(at_256)
    goal_row = _row(rows, 16, 4)
    goals = {
        **{f"frame_{n}_over_1": [ratio, GOAL_OVER_ONE[n], ratio <= GOAL_OVER_ONE[n]] for n, ratio in over_one.items()},
        "brute_over_culled_256": [speedup_256, GOAL_BRUTE_OVER_CULLED_256, speedup_256 >= GOAL_BRUTE_OVER_CULLED_256],
        "frame_16_lights_4_translucent_ms": [goal_row["frame_ms"], GOAL_MS, goal_row["frame_ms"] <= GOAL_MS],
    }
    if not _software(data):
        lit = at_256["passes_ms"]["lighting"]
        goals["gpu_lighting_256_ms"] = [lit, GOAL_GPU_LIGHTING_MS, lit <= GOAL_GPU_LIGHTING_MS]
    return goals


def _frames_text(data) -> str:
    """How the frame figures were measured: interleaved pairs (:func:`paired_ms`), or, in older data, apart."""
    rows = data["rows"]
    if not all(r.get("ratios") for r in rows):
        return (f"Frames: median of {data['repeats']} after {data['warmup']} warm-up (the full loop: median of 3 after 1 "
                "up to 256 lights, one frame at 1024, where it takes seconds), submitted and waited for, no read-back."
                + _over_one_text(data))  # fmt: skip
    few = min(rows, key=lambda r: r["brute_repeats"])
    many = max(rows, key=lambda r: r["brute_repeats"])
    cold = few.get("brute_warmup", data["warmup"]) == 0  # data of the first paired run warmed the full loop too
    fewer = (f" ({few['brute_repeats']} time, {few['frames']} culled frames, at {few['lights']} lights, where the full "
             f"loop takes seconds{' and is not warmed up: its pipelines are the culled frames' if cold else ''})"
             if few["brute_repeats"] < many["brute_repeats"] else "")  # fmt: skip
    return (f"Frames, each submitted and waited for, no read-back, after {data['warmup']} warm-up of each kind: "
            f"{many['brute_repeats']} times, {many['frames'] // many['brute_repeats']} culled frames then one full-loop "
            f"frame{fewer}. The culled figure is the median of its {many['frames']} frames, the full loop's of its "
            f"{many['brute_repeats']}, and 'full loop / culled' the median of the pairs' ratios, each full-loop frame over "
            "the median of the culled frames just before it, so that a change in the shared machine's load falls on both; "
            "their range is in brackets." + _over_one_text(data))  # fmt: skip


def _over_one_text(data) -> str:
    """How the goals on N lights over one light were measured, where they were paired (:func:`paired_over_one`)."""
    paired = [r for r in data["rows"] if r.get("over_one_ratios")]
    if not paired:
        return ""
    counts = " and ".join(str(r["lights"]) for r in paired)
    n = len(paired[0]["over_one_ratios"])
    return (
        f" The goals on {counts} lights over one light are the median of {n} ratios, each of {FRAMES_PER_PAIR} frames "
        f"of the opaque scene with that many lights against {FRAMES_PER_PAIR} frames with one, interleaved; their range "
        "is in brackets."
    )


def markdown(data) -> str:
    """BENCHMARKS.md's section from one run's data (``bench/run.py --rewrite render`` re-words it, measuring nothing)."""
    rows, goals, software = data["rows"], judge(data), _software(data)
    at_256 = _row(rows, 256, 0)
    goal_row = _row(rows, 16, 4)
    lit_culled, lit_brute = at_256["passes_ms"]["lighting"], at_256["brute_passes_ms"]["lighting"]
    # What the culled frame spends on its lights (the culling pass builds the lists the lighting pass reads) against
    # what the full loop spends on them; the g-buffer and outline passes are the same in both frames.
    light_work = at_256["passes_ms"]["culling"] + lit_culled
    shared = at_256["passes_ms"]["gbuffer"] + at_256["passes_ms"].get("outlines", 0.0)

    def met(key):
        return "met" if goals[key][2] else "**not met**"

    # Milliseconds to a tenth on lavapipe; a real GPU's passes take hundredths or less.
    ms = ".1f" if software else ".3f"

    timing = ("GPU timestamp queries (`timestamp-query`, each pass's start and end)" if data["timing"] == "timestamps"
              else "fences (each pass submitted alone and waited for; includes submission overhead)")  # fmt: skip
    md = [
        "## Renderer (deferred, WebGPU): ranged lights culled per tile" + ("" if software else ", on a real GPU"),
        "",
        f"{data['width']}x{data['height']}, floor + 6 opaque spheres (+ 4 translucent spheres), ranged point lights "
        f"scattered over the scene (one light's range covers it all; from 16 up the range is calibrated to about "
        f"{TARGET_PER_PIXEL:.0f} lights per covered pixel). Culled: 16x16 tiles, lists built on the GPU against each "
        f"tile's depth bounds, each translucent layer culled again. Full loop: the same lights and frame with culling off, "
        f"in the same run (the baseline). {_frames_text(data)} "
        f"Lights per pixel are counted from the g-buffer read back, lights per "
        f"tile from the lists read back (covered tiles). Atlas: {data['atlas']}. Device: {data['device']}.",
        "",
        "| point lights | translucent | range | lights/pixel mean | max | lights/tile mean | max | overflowing tiles "
        "| frame, culled, median (ms) | fastest (ms) | full loop, median (ms) | full loop / culled |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    md += [
        f"| {r['lights']} | {r['translucent']} | {r['range']:.2f} | {r['lights_per_pixel_mean']:.2f} | {r['lights_per_pixel_max']} "
        f"| {r['lights_per_tile_mean']:.1f} | {r['lights_per_tile_max']} | {r['overflowing_tiles']} | {r['frame_ms']:{ms}} "
        f"| {r['frame_min_ms']:{ms}} | {r['brute_ms']:{ms}} | {_ratio_cell(r)} |"
        for r in rows
    ]
    md += [
        "",
        f"Per pass, culled frames, median of {data['repeats']} (ms), measured with {timing}. Translucency is each "
        "translucent object's g-buffer, culling and lighting passes; outlines run only where an outlined material is in "
        "view (– : none).",
        "",
        "| point lights | translucent | " + " | ".join(PASSES) + " |",
        "|---:|---:|" + "---:|" * len(PASSES),
    ]
    md += [
        f"| {r['lights']} | {r['translucent']} | "
        + " | ".join(f"{r['passes_ms'][p]:{ms}}" if p in r["passes_ms"] else "–" for p in PASSES)
        + " |"
        for r in rows
    ]
    load = f"load average {data['load_average']:.2f} on {data['cpus']} CPUs when the section started"
    gpu_line = _gpu_goal_line(software, data["device"], lit_culled, data["timing"],
                              met("gpu_lighting_256_ms") if not software else "")  # fmt: skip
    if not software:
        # The issue sets its ratio and 150 ms goals on lavapipe (the section measured here by `make bench`); on a real
        # GPU they are figures beside its own goal.
        md += [
            "",
            f"Goal ({load}):",
            "",
            gpu_line,
            "",
            f"Beside it (the issue judges these on lavapipe): 256 lights {goals['frame_256_over_1'][0]:.2f}x and 1024 "
            f"lights {goals['frame_1024_over_1'][0]:.2f}x the 1-light frame; the full loop at 256 lights "
            f"{goals['brute_over_culled_256'][0]:.1f}x the culled frame (lighting pass alone {lit_brute / lit_culled:.1f}x); "
            f"16 lights with 4 translucent objects {goal_row['frame_ms']:.2f} ms.",
        ]
    else:
        md += [
            "",
            f"Goals (medians, ratios within this run; {load}):",
            "",
            *(
                f"- {n} lights at most {goal:.0f}x the 1-light frame: {_over_one_cell(rows, n)}, {met(f'frame_{n}_over_1')}."
                for n, goal in GOAL_OVER_ONE.items()
            ),
            f"- Culled at least {GOAL_BRUTE_OVER_CULLED_256:.0f}x faster than the full loop at 256 lights, frame against "
            f"frame: {_ratio_cell(at_256)}, {met('brute_over_culled_256')}. The work on the lights "
            f"alone: the culling and lighting passes, {light_work:.1f} ms culled, against the full loop's lighting pass, "
            f"{lit_brute:.1f} ms (one frame), {lit_brute / light_work:.1f}x (the lighting pass alone "
            f"{lit_brute / lit_culled:.1f}x). The g-buffer and outline passes ({shared:.1f} ms) are the same in both frames: "
            "no culling scheme changes them, and they bound the frame's ratio.",
            f"- 16 lights with 4 translucent objects at most {GOAL_MS:.0f} ms: {goal_row['frame_ms']:.1f} ms "
            f"(fastest {goal_row['frame_min_ms']:.1f} ms), {met('frame_16_lights_4_translucent_ms')}.",
            gpu_line,
        ]
    md += [
        "",
        f"Device validation errors during the benchmark: {len(data['validation_errors'])}.",
        "",
    ]
    return "\n".join(md)


if __name__ == "__main__":
    print(run()["markdown"])
