"""Issue 21's verdict on the look: the shipped library against its physical references, on the material's pixels.

The shipped library (``materials/``) is baked (its float slices from the bake cache, ``build/cache``) and
validated at 128x96 on the ``front`` and ``back`` scenes with :func:`atlasgen.validate.run.validate_atlas`,
stochastic references from ``PHYSICAL_SPP`` samples per pixel up to ``MAX_PHYSICAL_SPP``: the defaults of
``atlasgen validate``, so that a reference grows until its noise floor is 10 dB above the error it measures
(a look whose reference stops short is "not judged", with its spp and floor). Where the comparison is split
by object (skin's sphere and flat part), each part is a row of its own under its material's. Every comparison is measured twice from the same images: over the
whole frame, as reports before issue 21 did (black background counted as exact), and over the
material's own pixels (the g-buffer's material ID), with the grazing pixels (N.V < 0.2) apart.

The references are kept in ``build/cache/references`` (:mod:`atlasgen.validate.reference_cache`), and
the run is made twice: the second renders no reference, and its time is what a repeated
``atlasgen validate`` costs.

Run alone: ``python bench/run.py verdict``.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

SCENES = ("front", "back")


def _figures(ref, look: dict, parts: dict) -> dict:
    m = ref.metrics
    return {
        "parts": parts,
        "whole_frame_psnr_db": m.whole_frame_psnr,
        "psnr_db": m.psnr,
        "flip": m.flip,
        "coverage": m.coverage,
        "grazing_psnr_db": m.regions["grazing"]["psnr_db"],
        "grazing_coverage": m.regions["grazing"]["coverage"],
        "rest_psnr_db": m.regions["rest"]["psnr_db"],
        "clipped_pixels": m.clipped_pixels,
        "unclipped_psnr_db": m.unclipped_psnr,
        "spp": int(ref.spp),
        "noise_floor_db": ref.noise_floor_db,
        "compared": look["compared"],
        "meets_goal": look["meets_goal"],
        "not_judged": look["not_judged"],
    }


def measure() -> dict:
    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.materials.material import read_materials
    from atlasgen.reports.validation import report_dict

    # ``atlasgen validate``'s defaults: the verdict is the one a user gets.
    from atlasgen.validate.run import GOAL_LOOK_FLIP, GOAL_LOOK_PSNR_DB, MAX_PHYSICAL_SPP, PHYSICAL_SPP, validate_atlas

    bake_cache, reference_cache = ROOT / "build" / "cache", ROOT / "build" / "cache" / "references"
    with tempfile.TemporaryDirectory() as tmp:
        dds = Path(tmp) / "atlas.dds"
        write_bake(bake_atlas(read_materials([ROOT / "materials"]), cache_dir=bake_cache), dds)
        args = dict(scenes=list(SCENES), physical_spp=PHYSICAL_SPP, max_physical_spp=MAX_PHYSICAL_SPP,
                    bake_cache=bake_cache, reference_cache=reference_cache)  # fmt: skip
        t0 = time.perf_counter()
        run = validate_atlas(dds, **args)
        first_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        again = validate_atlas(dds, **args)
        second_s = time.perf_counter() - t0
    rows = report_dict(run)["results"]
    library = {}
    for r, row in zip(run.runs, rows):
        look = row["look"]
        if look["reference"] is None:
            library.setdefault(r.material, {})["none"] = look["why_none"]
            continue
        parts = {name: {**part, **(look.get("parts") or {}).get(name, {})}
                 for name, part in (row["references"][look["reference"]].get("parts") or {}).items()}  # fmt: skip
        library.setdefault(r.material, {})[r.scene] = _figures(r.references[look["reference"]], look, parts)
    return {
        "physical_spp": PHYSICAL_SPP,
        "max_physical_spp": MAX_PHYSICAL_SPP,
        "goal": {"psnr_db": GOAL_LOOK_PSNR_DB, "flip": GOAL_LOOK_FLIP},
        "library": library,
        "first_run_s": first_s,
        "second_run_s": second_s,
        "renders_stored_first": run.environment["reference_renders_stored"],
        "renders_from_cache_first": run.environment["reference_renders_from_cache"],
        "renders_from_cache_second": again.environment["reference_renders_from_cache"],
        "renders_stored_second": again.environment["reference_renders_stored"],
    }


def _db(x) -> str:
    return "inf" if x is None else f"{x:.1f}"


def _verdict(f: dict) -> str:
    if f["not_judged"]:
        return f"not judged ({f['not_judged']})"
    return "met" if f["meets_goal"] else "**missed**"


def markdown(data: dict) -> str:
    goal = data["goal"]
    lines = [
        "## The look against physics, on the material's pixels (issue 21)",
        "",
        f"The shipped library's atlas images against their physical references (a separable material: its source "
        f"BSDF), 128x96, `front` and `back`; stochastic references from {data['physical_spp']} spp up to "
        f"{data['max_physical_spp']} spp, `atlasgen validate`'s defaults (a reference grows until its noise floor is "
        f"10 dB above the error; where it stops short, the look is not judged). Skin's comparison is split by object "
        f"(its sphere and the flat part), each part a row under the whole, judged on its own and with its own floor. **Whole frame** is the PSNR earlier reports gave, the black background counted as "
        f"exact; **material** is the same comparison over the material's own pixels (the g-buffer's material ID), "
        f"**coverage** the fraction of the frame that is, **N.V < 0.2** and **rest** its grazing pixels and the "
        f"others. **Clipped** counts the reference's pixels that the display clips, with the PSNR at the exposure "
        f"that clips none (both must reach the goal). Look goal: PSNR >= {goal['psnr_db']:g} dB and mean FLIP <= "
        f"{goal['flip']:g} on the material's pixels.",
        "",
        "| material | scene | compared against | whole frame | material | FLIP | coverage | N.V < 0.2 (coverage) | rest "
        "| clipped (unclipped PSNR) | spp (floor) | look goal |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    none = []
    for name, scenes in data["library"].items():
        if "none" in scenes:
            none.append(f"{name} ({scenes['none'].split(':')[0]})")
            continue
        for scene in SCENES:
            f = scenes[scene]
            floor = "" if f["noise_floor_db"] is None else f" ({_db(f['noise_floor_db'])})"
            clipped = f"{f['clipped_pixels']}" + (f" ({_db(f['unclipped_psnr_db'])})" if f["clipped_pixels"] else "")
            lines.append(
                f"| {name} | {scene} | {f['compared']} | {_db(f['whole_frame_psnr_db'])} | {_db(f['psnr_db'])} | "
                f"{f['flip']:.3f} | {f['coverage']:.0%} | {_db(f['grazing_psnr_db'])} ({f['grazing_coverage']:.1%}) | "
                f"{_db(f['rest_psnr_db'])} | {clipped} | {f['spp']}{floor} | {_verdict(f)} |"
            )
            for part, p in (f.get("parts") or {}).items():
                part_floor = "" if p.get("noise_floor_db") is None else f" ({_db(p['noise_floor_db'])})"
                lines.append(
                    f"| {name}: {part} | {scene} | | | {_db(p.get('psnr_db'))} | {p['flip']:.3f} | "
                    f"{p['coverage']:.0%} | | | | {p.get('spp', f['spp'])}{part_floor} | {_verdict(p)} |"
                )
    lines += [
        "",
        f"No physical reference: {', '.join(none) or 'none'}.",
        "",
        f"The reference cache: the first run took {data['first_run_s']:.1f} s and stored "
        f"{data['renders_stored_first']} reference renders ({data['renders_from_cache_first']} found from an earlier "
        f"run); the second, the same validation again, took {data['second_run_s']:.1f} s, found "
        f"{data['renders_from_cache_second']} and rendered {data['renders_stored_second']}.",
        "",
    ]
    return "\n".join(lines)


def run() -> dict:
    data = measure()
    return {"markdown": markdown(data), "data": data}


if __name__ == "__main__":
    print(run()["markdown"])
