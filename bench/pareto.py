"""Benchmark section: every shipped material's candidate representations, run-time cost against error
versus the physical reference (atlasgen/models/physical_error.py).

Cost: the lighting pass's time per pixel per light from the shipped cost table (measured by the
``cost`` section, ``atlasgen/data/lighting_cost.json``, device named). Error: relative RMS of
f cos against the physical reference on the importance-sampled report pairs, with its standard
error; a fitted slice's gloss and a separable candidate's grid and target are chosen on the
independent selection pairs. Materials without a projectable physical reference say why.
"""

from __future__ import annotations

import time


def run() -> dict:
    from atlasgen.bake.adaptive import bake_supersampled
    from atlasgen.io.package_data import shipped_library
    from atlasgen.materials.material import find_material_files, read_material
    from atlasgen.models.physical_error import physical_candidates
    from atlasgen.separable.auto import read_lighting_cost

    table = read_lighting_cost()
    lines = ["## Run-time cost against error versus the physical reference (shipped library)", "",
             f"Cost: lighting pass, {table.unit}, on {table.device} (`atlasgen/data/lighting_cost.json`). "
             "Error: relative RMS of f cos against the physical reference, ± its standard error "
             "(importance-sampled, 100 000 pairs, seed 20260101; parameters chosen on seed 20260102). "
             "**Bold**: on the material's Pareto front (nothing both cheaper and closer).", ""]  # fmt: skip
    data, without = {"device": table.device, "unit": table.unit, "materials": {}}, []
    for path in find_material_files([shipped_library()]):
        if path.suffix != ".toml":  # a MaterialX document's materials: bench/materialx.py measures them
            continue
        material = read_material(path)
        t0 = time.perf_counter()
        gloss = material.fit_gloss if material.fit_from == "physical" else None  # drawn at its fit gloss
        result = physical_candidates(material.model, material.params, bake_supersampled, gloss=gloss)
        seconds = time.perf_counter() - t0
        if not result.get("candidates"):
            without.append(f"- {material.name}: {result['reason']}")
            data["materials"][material.name] = {"reason": result["reason"]}
            continue
        from atlasgen.reports.pareto import front_flags

        front = front_flags(result["candidates"])
        coverage = (" The reference transmits: l covers the whole sphere (estimator "
                    f"`{result['estimator']}`)." if result.get("sphere") else "")  # fmt: skip
        skipped = "".join(f" No {k['representation']} candidate: {k['reason']}." for k in result.get("skipped", []))
        lines += [f"### {material.name}", "", f"Physical reference: {result['reference']}. "
                  f"LUT candidates drawn at renderer gloss {result['gloss']:g}; measured in {seconds:.1f} s.{coverage}{skipped}", "",
                  "| candidate | cost | error vs physical | ± SE |", "|---|---:|---:|---:|"]  # fmt: skip
        for c, on_front in zip(result["candidates"], front):
            name = f"**{c['representation']}**" if on_front else c["representation"]
            lines.append(f"| {name} | {c['cost']:.3g} | {c['error']:.4g} | {c['error_se']:.2g} |")
        lines.append("")
        data["materials"][material.name] = {"reference": result["reference"], "gloss": result["gloss"], "seconds": seconds,
                                            "sphere": result.get("sphere", False), "skipped": result.get("skipped", []),
                                            "candidates": result["candidates"]}  # fmt: skip
    if without:
        lines += ["Without a physical reference to measure against:", "", *without, ""]
    return {"markdown": "\n".join(lines), "data": data}
