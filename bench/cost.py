"""Run-time cost of every representation: the lighting pass's time per pixel per light.

One in-memory atlas holds a LUT slice (a lambert material: every LUT material runs the same
shader, and a supersampled slice differs from a point-sampled one only in its texels, so one
measurement covers both), a GGX BRDF factored into K = 1..8 separable terms, and the analytic
GGX, Beckmann and Lambert closed forms evaluated in the lighting shader
(``representation = "analytic"``). Each is measured by
:func:`atlasgen.render.cost.measure_lighting_cost` with the material covering the frame.
Ratios are against the LUT slice of the same run. The table is also written to
``atlasgen/data/lighting_cost.json``: the cost model ``representation = "auto"`` bakes with.

Run alone: ``python bench/cost.py``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
COST_FILE = ROOT / "atlasgen" / "data" / "lighting_cost.json"
WIDTH, HEIGHT, LIGHTS, REPEATS, WARMUP = 256, 256, 8, 9, 2
TERMS = range(1, 9)

MATERIALS = {
    "lut": 'type = "lambert"\ncolour = [0.6, 0.5, 0.4]\n',
    **{f"separable-{k}": f'type = "separable"\nsource = "ggx"\nalpha = 0.3\nf0 = [0.9, 0.6, 0.3]\nterms = {k}\n' for k in TERMS},
    **{f"analytic-{s}": f'type = "separable"\nsource = "{s}"\nalpha = 0.3\nf0 = [0.9, 0.6, 0.3]\n'
                        f'diffuse = [0.1, 0.1, 0.1]\nrepresentation = "analytic"\n' for s in ("ggx", "beckmann", "lambert")},
}  # fmt: skip


def cost_key(name: str) -> str:
    """The cost table's key (atlasgen.separable.auto.cost_key) of a benchmark material."""
    if name == "lut":
        return "lut"
    kind, detail = name.split("-")
    return f"{kind}:{detail}"


def build_atlas(folder: Path):
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_materials
    from atlasgen.render.atlas_texture import RenderAtlas

    folder.mkdir(parents=True, exist_ok=True)
    for name, text in MATERIALS.items():
        (folder / f"{name}.toml").write_text(text)
    result = bake_atlas(read_materials([folder / f"{n}.toml" for n in MATERIALS]))
    return RenderAtlas(result.levels, result.dxgi_format == 29, result.manifest, result.include, "cost atlas")


def measure() -> dict:
    import tempfile

    from atlasgen.render.cost import measure_lighting_cost, relative_costs
    from atlasgen.render.renderer import Renderer

    with tempfile.TemporaryDirectory() as tmp:
        atlas = build_atlas(Path(tmp))
    renderer = Renderer(atlas)
    rows = {}
    for name in MATERIALS:
        cost = measure_lighting_cost(renderer, name, WIDTH, HEIGHT, LIGHTS, REPEATS, WARMUP)
        rows[cost_key(name)] = cost.to_json()
        print(f"bench cost: {name}: {cost.ns_per_pixel_per_light:.2f} ns per pixel per light", file=sys.stderr, flush=True)
    costs = {k: r["ns_per_pixel_per_light"] for k, r in rows.items()}
    return {"device": renderer.ctx.name, "unit": "ns per pixel per light", "width": WIDTH, "height": HEIGHT,
            "lights": LIGHTS, "repeats": REPEATS, "warmup": WARMUP, "costs": costs,
            "relative_to_lut": relative_costs(costs, "lut"), "rows": rows,
            "validation_errors": renderer.ctx.take_errors()}  # fmt: skip


def write_cost_model(data: dict, path: Path = COST_FILE) -> None:
    """The cost model the bake reads: costs rounded to 3 significant digits, the device named."""
    model = {"device": data["device"], "unit": data["unit"], "measured_by": "make bench (bench/cost.py)",
             "frame": f"{data['width']}x{data['height']}, {data['lights']} point lights, median of {data['repeats']}",
             "costs": {k: float(f"{v:.3g}") for k, v in data["costs"].items()}}  # fmt: skip
    path.write_text(json.dumps(model, indent=2) + "\n")


def run() -> dict:
    data = measure()
    write_cost_model(data)
    md = ["## Run-time cost per representation (lighting pass)", "",
          f"{WIDTH}x{HEIGHT}, the material covering the frame, {LIGHTS} point lights; median of {REPEATS} lighting "
          f"passes after {WARMUP} warm-up, submitted and waited for. Device: {data['device']}. Written to "
          "`atlasgen/data/lighting_cost.json` (the cost model of `representation = \"auto\"`).",
          "The LUT row stands for point-sampled and supersampled slices alike (same shader; only texels differ).", "",
          "| representation | ns per pixel per light | relative to LUT | device |", "|---|---:|---:|---|"]  # fmt: skip
    md += [f"| {k} | {v:.2f} | {data['relative_to_lut'][k]:.2f}x | {data['device']} |" for k, v in data["costs"].items()]
    md += ["", f"Device validation errors: {len(data['validation_errors'])}.", ""]
    return {"markdown": "\n".join(md), "data": data}


if __name__ == "__main__":
    print(run()["markdown"])
