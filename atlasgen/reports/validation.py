"""The validation report: ``index.html``, ``report.json``, the images and one speed/error plot.

Everything is built in memory as ``{path: bytes}`` and written in one all-or-nothing
step (:func:`atlasgen.io.atomic.write_files_atomically`). Every figure in the report is a
measured value from the run; nothing is typed in.

The page and the plot are made from the JSON dict alone, so that
:func:`merge_validation_reports` can combine per-material runs (``make validate`` runs
one process per material) into one page without rendering anything again.
"""

from __future__ import annotations

import json
import math
from pathlib import Path, PurePosixPath

import numpy as np

from atlasgen.errors import FieldError, InputError, describe_failure, shorten
from atlasgen.io.atomic import write_files_atomically
from atlasgen.io.field_reads import FieldReads, expected_written
from atlasgen.io.fields import is_number, shown
from atlasgen.io.images import encode_png, is_png_file
from atlasgen.io.report_files import (
    check_merge_output,
    check_number,
    read_report_json,
    rebase_path,
    report_json_paths,
)
from atlasgen.models import get_model
from atlasgen.optics.display import display_clip
from atlasgen.optics.quantize import quantize_rgba
from atlasgen.reports.comparisons import validation_pairs
from atlasgen.reports.environment import ENVIRONMENT_COLUMNS, environment_rows
from atlasgen.reports.html import Chart, figure_chart, label_points, pareto_front, plot_style, render_page
from atlasgen.reports.report_kind import refuse_another_report, report_kind
from atlasgen.validate.metrics import NO_PIXELS, NOISE_FLOOR_MARGIN_DB, finite_or_none, flip_heatmap

__all__ = [
    "write_validation",
    "build_report",
    "report_dict",
    "plot_speed_error",
    "image_name",
    "merge_validation_reports",
    "summary_line",
    "describe_materials",
    "missed_goals",
    "noise_floor_failures",
    "read_validation_report",
    "check_result_figures",
    "look_verdict",
    "materialx_summary",
    "not_measured",
]

#: Figure size of the speed/error plot in inches (shown at 100 CSS px per inch).
_PLOT_SIZE = (7.5, 5.0)

_KIND_LABEL = {
    "atlas": "atlas (deferred renderer)",
    "model": "model reference",
    "physical": "physical reference",
    "rebuild": "CPU rebuild from the atlas",
}


def _relative_cache(environment: dict, out_dir) -> dict:
    """``environment`` with its ``reference_cache`` folder given from ``out_dir`` (the report's folder), as ``atlas`` is:
    as typed, it was a path from the working folder, wrong when read from the report and other bytes from elsewhere."""
    cache = environment.get("reference_cache")
    if out_dir is None or not isinstance(cache, str):
        return environment
    return {**environment, "reference_cache": rebase_path(cache, ".", out_dir)}


def _display_png(rgb01) -> bytes:
    """PNG bytes of an ``(h, w, 3)`` display image in [0, 1] (already sRGB-encoded), 8 bits per channel."""
    return encode_png(quantize_rgba(np.asarray(rgb01, dtype=np.float64), srgb=False))


def image_name(material: str, scene: str, what: str) -> str:
    """Relative path of one report image, e.g. ``images/skin.front.atlas.png``.

    Dots part the three: a material name holds none, and ``what`` is one of a few words, so two results never share
    an image. With ``__`` instead, material ``x`` on scene ``y__z`` and material ``x__y`` on scene ``z`` both wrote
    ``x__y__z__atlas.png``, and one row showed the other material's render.

    >>> image_name("x", "y__z", "atlas"), image_name("x__y", "z", "atlas")
    ('images/x.y__z.atlas.png', 'images/x__y.z.atlas.png')
    """
    return f"images/{material}.{scene}.{what}.png"


def _goal(run, ref, goals) -> bool | None:
    """Whether a material meets the model-reference goals (None where they don't apply:
    other references, and models whose manifest claims its own error, ``Model.validation_goals``;
    and where the comparison measures nothing, :func:`_unmeasured_verdict`)."""
    if ref.kind != "model" or not run.goals:
        return None
    met = _storage_met(ref.metrics.psnr, ref.metrics.flip, goals, getattr(run, "goal_psnr_db", None))
    return _unmeasured_verdict(met, getattr(ref.metrics, "not_measured", None), ref.metrics.psnr)


def _storage_met(psnr_db: float, flip: float, goals: dict, goal_psnr_db: float | None = None) -> bool:
    """Whether a model comparison meets the storage goals: PSNR and FLIP against ``goals``, or an environment
    map's own PSNR goal alone (``goal_psnr_db``, issue #20).

    >>> _storage_met(46.0, 0.005, {"psnr_db": 45, "flip": 0.01}), _storage_met(46.0, 0.02, {"psnr_db": 45, "flip": 0.01})
    (True, False)
    >>> _storage_met(31.0, 0.5, {"psnr_db": 45, "flip": 0.01}, goal_psnr_db=30.0)
    True
    """
    if goal_psnr_db is not None:
        return bool(psnr_db >= goal_psnr_db)
    return bool(psnr_db >= goals["psnr_db"] and flip <= goals["flip"])


def _unmeasured_verdict(met: bool, not_measured: str | None, psnr_db) -> bool | None:
    """``met`` where the comparison measures the material; else None (not measured), or False where its figures
    miss even so (the atlas shows light where the reference is black): never met on nothing.

    >>> _unmeasured_verdict(True, None, 50.0), _unmeasured_verdict(True, "black", None), _unmeasured_verdict(False, "black", 9.0)
    (True, None, False)
    >>> _unmeasured_verdict(False, "no pixel", float("nan")) is None
    True
    """
    if not_measured is None:
        return met
    measured = psnr_db is not None and not (isinstance(psnr_db, float) and math.isnan(psnr_db))
    return False if measured and not met else None


def not_measured(ref: dict | None) -> str | None:
    """Why a report.json comparison measures nothing of the material (``not_measured``: no pixel compared, or a
    black reference), or None; a report written before the field says it by a ``coverage`` of 0."""
    if not ref:
        return None
    if ref.get("not_measured"):
        return str(ref["not_measured"])
    return NO_PIXELS if ref.get("coverage") == 0 else None


def look_verdict(look: dict, ref: dict | None) -> dict:
    """The verdict on a material's look on one scene: ``{"meets_goal", "not_judged"}`` from its look goal
    (``MaterialRun.look``) and the figures of the reference it names (a report.json reference dict).

    Judged on the material's pixels: PSNR >= the goal's and mean FLIP <= the goal's; where the
    reference clips on display (``clipped_pixels`` > 0), the PSNR at the exposure that clips none of
    it (``unclipped_psnr_db``) must reach the goal too, so saturation cannot hide error. A
    stochastic reference whose noise floor is not 10 dB above the PSNR cannot show a miss: the
    reference's noise only adds to the error measured against it (E|R - Y|^2 = |R - T|^2 + E|N|^2
    for a reference Y = T + N with zero-mean noise N), so the measured PSNR is a lower bound on the
    PSNR against the converged reference T. A look that meets its goal even so is met, and
    ``bound`` says against what; one that does not is not judged: ``meets_goal`` is None and
    ``not_judged`` says why ("reference at N spp, floor F dB"). No reference: both None.

    >>> look = {"reference": "physical", "goal": {"psnr_db": 30.0, "flip": 0.05}}
    >>> look_verdict(look, {"psnr_db": 44.1, "flip": 0.02, "clipped_pixels": 0})
    {'meets_goal': True, 'not_judged': None}
    >>> look_verdict(look, {"psnr_db": 44.1, "flip": 0.02, "clipped_pixels": 9, "unclipped_psnr_db": 28.0})["meets_goal"]
    False
    >>> look_verdict(look, {"psnr_db": 28.0, "flip": 0.02, "noise_floor_ok": False, "noise_floor_db": 31.3, "spp": 16})
    {'meets_goal': None, 'not_judged': 'reference at 16 spp, floor 31.3 dB'}
    >>> look_verdict(look, {"psnr_db": 38.0, "flip": 0.02, "noise_floor_ok": False, "noise_floor_db": 41.3, "spp": 16})
    {'meets_goal': True, 'not_judged': None, 'bound': 'a lower bound: reference at 16 spp, floor 41.3 dB'}

    Where the comparison is split by object (``parts``: a sphere and the flat part), every part is
    judged as the whole is, and the look meets its goal only where the whole and every part do: a
    part that misses is not hidden in the average. ``parts`` then gives each part's ``meets_goal`` and
    ``not_judged``, by the same rule.

    >>> parts = {"sphere": {"psnr_db": 42.0, "flip": 0.03}, "flat part": {"psnr_db": 27.0, "flip": 0.06}}
    >>> v = look_verdict(look, {"psnr_db": 31.0, "flip": 0.045, "parts": parts})
    >>> v["meets_goal"], v["parts"]["sphere"], v["parts"]["flat part"]
    (False, {'meets_goal': True, 'not_judged': None}, {'meets_goal': False, 'not_judged': None})
    >>> parts["flat part"].update(noise_floor_ok=False, noise_floor_db=33.0, spp=64)
    >>> v = look_verdict(look, {"psnr_db": 31.0, "flip": 0.045, "parts": parts, "noise_floor_ok": False,
    ...                         "noise_floor_db": 36.0, "spp": 64})
    >>> v["meets_goal"], v["not_judged"], v["parts"]["flat part"]
    (None, 'reference at 64 spp, floor 36.0 dB (flat part: floor 33.0 dB at 64 spp)', {'meets_goal': None, 'not_judged': 'floor 33.0 dB at 64 spp'})
    """
    if not look or look.get("reference") is None or ref is None:
        return {"meets_goal": None, "not_judged": None}
    goal = look["goal"]
    whole = _meets_look_goal(goal, ref)
    why = not_measured(ref)
    if why is not None:  # nothing of the material measured: no verdict, unless the figures miss even so
        met = _unmeasured_verdict(whole, why, ref.get("psnr_db") if ref.get("coverage") != 0 else None)
        return {"meets_goal": met, "not_judged": None if met is False else f"not measured: {why}"}
    floors = {name: _short_floor(p, ref.get("spp")) for name, p in (ref.get("parts") or {}).items()}
    parts = {name: _part_verdict(goal, p, floors[name]) for name, p in (ref.get("parts") or {}).items()}
    whole_short = ref.get("noise_floor_ok") is False
    short_parts = [f"{name}: {p['not_judged']}" for name, p in parts.items() if p["not_judged"]]
    short_floors = [f"{name}: {floor}" for name, floor in floors.items() if floor]
    short = f"reference at {ref.get('spp')} spp, floor {_psnr_text(ref.get('noise_floor_db'))} dB" + (
        f" ({', '.join(short_floors)})" if short_floors else ""
    )
    if any(p["meets_goal"] is False for p in parts.values()) or (not whole and not whole_short):
        out = {"meets_goal": False, "not_judged": None}  # a miss the floor can show stands
    elif not whole or short_parts:
        out = {"meets_goal": None, "not_judged": short if whole_short else ", ".join(short_parts)}
    elif whole_short:
        out = {"meets_goal": True, "not_judged": None, "bound": f"a lower bound: {short}"}
    else:
        out = {"meets_goal": True, "not_judged": None}
    if parts:
        out["parts"] = parts
    return out


def _short_floor(part: dict, spp) -> str | None:
    """The text 'floor F dB at N spp' where a part's reference is short of its noise floor, else None."""
    if part.get("noise_floor_ok") is not False:
        return None
    return f"floor {_psnr_text(part.get('noise_floor_db'))} dB at {part.get('spp', spp)} spp"


def _part_verdict(goal: dict, part: dict, short: str | None) -> dict:
    """One part's ``{"meets_goal", "not_judged"}``, by :func:`look_verdict`'s rule: a part short of its
    noise floor (``short``, :func:`_short_floor`) that misses is not judged; one that meets its goal even
    so is met (a lower bound)."""
    if part.get("pixels") == 0:  # an object out of view: nothing of it measured, no verdict
        return {"meets_goal": None, "not_judged": None}
    met = _meets_look_goal(goal, part)
    if short and not met:
        return {"meets_goal": None, "not_judged": short}
    return {"meets_goal": met, "not_judged": None}


def _meets_look_goal(goal: dict, figures: dict) -> bool:
    """PSNR (and, where the reference clips, the unclipped PSNR) >= the goal's, and FLIP <= the goal's."""
    psnrs = [math.inf if figures.get("psnr_db") is None else figures["psnr_db"]]
    if figures.get("clipped_pixels"):
        psnrs.append(math.inf if figures.get("unclipped_psnr_db") is None else figures["unclipped_psnr_db"])
    flip = figures.get("flip")
    return bool(min(psnrs) >= goal["psnr_db"] and (flip is None or not math.isfinite(flip) or flip <= goal["flip"]))


def report_dict(run, out_dir=None) -> dict:
    """The JSON report: settings, environment, and per material and scene every measured figure.

    ``atlas`` is the atlas's path from ``out_dir`` (the report's folder), as the report's images are; as typed
    where no folder is given.
    """
    goals = run.settings["goals"]
    rows = []
    for r in run.runs:
        refs = {}
        for kind, ref in r.references.items():
            refs[kind] = {
                "description": ref.description,
                "variant": ref.variant,
                "spp": ref.spp,
                "seconds": ref.seconds,
                "speed_ratio": finite_or_none(ref.seconds / r.atlas_seconds if r.atlas_seconds > 0 else math.inf),
                **ref.metrics.as_dict(),
                "meets_goal": _goal(r, ref, goals),
                "images": {
                    "reference": image_name(r.material, r.scene, kind),
                    "flip": image_name(r.material, r.scene, f"flip-{kind}"),
                },  # fmt: skip
            }
            floor = getattr(ref, "noise_floor_db", None)
            if floor is not None:  # a stochastic reference: two seeds against each other
                refs[kind]["noise_floor_db"] = finite_or_none(floor)
                refs[kind]["noise_floor_ok"] = ref.noise_floor_ok
                for name, part_floor in (getattr(ref, "part_floors", None) or {}).items():
                    part = refs[kind]["parts"][name]
                    part["noise_floor_db"] = finite_or_none(part_floor)
                    psnr_db = math.inf if part["psnr_db"] is None else part["psnr_db"]
                    # An object that shows no pixel has no error for its floor to clear.
                    part["noise_floor_ok"] = bool(part_floor >= psnr_db + NOISE_FLOOR_MARGIN_DB) if part.get("pixels") else None
                    part["spp"] = (getattr(ref, "part_spp", None) or {}).get(name, ref.spp)
            if getattr(ref, "mask", None) is not None:
                refs[kind]["masked_fraction"] = ref.masked_fraction
                refs[kind]["masked"] = ref.masked
        look = getattr(r, "look", None)
        if look is not None:
            look = {**look, **look_verdict(look, refs.get(look.get("reference") or ""))}
            if look["reference"] is not None:
                refs[look["reference"]]["look_goal"] = look["meets_goal"]
        row = {
            "material": r.material,
            "type": r.type,
            "scene": r.scene,
            "exposure": r.exposure,
            "atlas_seconds": r.atlas_seconds,
            "atlas_image": image_name(r.material, r.scene, "atlas"),
            "references": refs,
            "notes": list(r.notes),
        }
        if r.claimed is not None:
            row["claimed_errors"] = r.claimed
        if r.breakdown is not None:
            row["error_breakdown"] = r.breakdown
        if getattr(r, "environment_breakdown", None) is not None:
            row["environment_breakdown"] = r.environment_breakdown
        if getattr(r, "goal_psnr_db", None) is not None:
            row["goal_psnr_db"] = r.goal_psnr_db
        if look is not None:
            row["look"] = look
        if getattr(r, "materialx", None) is not None:
            row["materialx"] = r.materialx
        identity = (getattr(run, "identity", None) or {}).get(r.material)
        if identity is not None:  # what the figures were measured on (atlasgen.validate.identity)
            row["atlas_identity"] = identity
        rows.append(row)
    return {
        # From the report's folder: the path as typed made the same inputs write other bytes from another folder.
        "atlas": run.atlas if out_dir is None else rebase_path(run.atlas, ".", out_dir),
        "settings": run.settings,
        "environment": _relative_cache(run.environment, out_dir),
        "total_seconds": run.seconds,
        "summary": _summary(rows),
        "results": rows,
    }


def _summary(rows: list) -> dict:
    """The goals line, from the JSON rows (so a merged report recomputes it the same way): over
    the model-reference results the goals apply to (``meets_goal`` not null), and the comparisons
    that measure nothing of the material (``not_measured``), which meet no goal."""
    lut = [ref for row in rows if (ref := row["references"].get("model")) is not None and ref["meets_goal"] is not None]
    looks = [row for row in rows if (row.get("look") or {}).get("reference") is not None]
    measured = [x for x in lut if not_measured(x) is None]
    return {
        "lut_results": len(lut),
        "lut_meeting_goals": sum(1 for x in lut if x["meets_goal"]),
        "worst_lut_psnr_db": min((x["psnr_db"] for x in measured if x["psnr_db"] is not None), default=None),
        "worst_lut_flip": max((x["flip"] for x in measured if x["flip"] is not None), default=None),
        "not_measured": [
            f"{row['material']}/{row['scene']} ({kind})"
            for row in rows
            for kind, ref in row["references"].items()
            if not_measured(ref) is not None
        ],  # fmt: skip
        "look_results": len(looks),
        "look_meeting_goals": sum(1 for row in looks if row["look"]["meets_goal"]),
        "look_not_judged": [f"{row['material']}/{row['scene']}" for row in looks if row["look"]["not_judged"]],
        "no_physical_reference": list(
            dict.fromkeys(
                row["material"]
                for row in rows
                if (row.get("look") or {}).get("reference", "") is None and not row["look"].get("skipped")
            )
        ),  # fmt: skip
        "short_of_noise_floor": [
            f"{row['material']}/{row['scene']} ({kind}, {ref.get('spp')} spp, floor {_psnr_text(ref.get('noise_floor_db'))} dB)"
            for row in rows
            for kind, ref in row["references"].items()
            if ref.get("noise_floor_ok") is False
        ],  # fmt: skip
    }


def summary_line(data: dict, html_path) -> str:
    """The one line ``atlasgen validate`` prints: where the page is and how many results meet the goals."""
    s = _summary(data["results"])  # recomputed: a report written before the look goals has none of its fields
    parts = [f"{len(data['results'])} material/scene results"]
    parts.append(f"{s['lut_meeting_goals']}/{s['lut_results']} LUT results meet the storage goals" if s["lut_results"]
                 else "no LUT goal judged" if s["not_measured"] else "no LUT goals apply")  # fmt: skip
    if s["look_results"]:
        judged = s["look_results"] - len(s["look_not_judged"])
        parts.append(f"{s['look_meeting_goals']}/{judged} looks meet their goal against physics"
                     + (f" ({len(s['look_not_judged'])} not judged)" if s["look_not_judged"] else ""))  # fmt: skip
    if s["no_physical_reference"]:
        parts.append(f"no physical reference: {', '.join(s['no_physical_reference'])}")
    if s["short_of_noise_floor"]:
        parts.append(f"{len(s['short_of_noise_floor'])} reference(s) short of their noise floor: "
                     f"{', '.join(s['short_of_noise_floor'])}")  # fmt: skip
    if s["not_measured"]:
        parts.append(f"{len(s['not_measured'])} comparison(s) measure nothing of the material: {', '.join(s['not_measured'])}")
    parts.append(f"{data['total_seconds']:.1f} s")
    return f"{Path(html_path).as_posix()} ({', '.join(parts)})"


def _rows_by_material(data: dict) -> dict:
    """``material -> [rows]`` in the report's order."""
    out = {}
    for row in data["results"]:
        out.setdefault(row["material"], []).append(row)
    return out


def _goals_text(goals: dict) -> str:
    return f"PSNR >= {goals['psnr_db']:g} dB, FLIP <= {goals['flip']:g}"


def _psnr_text(psnr) -> str:
    return "inf" if psnr is None else f"{psnr:.1f}"


def _ref_psnr_text(ref: dict) -> str:
    """A comparison's PSNR: "n/a" where it measures nothing of the material (:func:`not_measured`), not "inf"."""
    return "n/a" if _unmeasured_match(ref) else _psnr_text(ref.get("psnr_db"))


def _unmeasured_match(ref: dict) -> bool:
    """Whether a comparison measures nothing and finds no difference either (no pixel, or black against black):
    its PSNR and FLIP say nothing of the material, and the lines print n/a for them."""
    return ref.get("psnr_db") is None and not_measured(ref) is not None


def _separable_figures(rows: list) -> tuple:
    """``(claimed 8-bit error, budget, worst measured atlas-against-source error)`` of a separable material."""
    claims = [row.get("claimed_errors") or {} for row in rows]
    measured = [c["measured_relative_rms_atlas_vs_source"] for c in claims
                if c.get("measured_relative_rms_atlas_vs_source") is not None]  # fmt: skip
    return claims[0].get("relative_rms_8bit"), claims[0].get("error_budget"), max(measured, default=None)


def _look_text(rows: list) -> tuple[str, str]:
    """``(verdict, text)`` of a material's look over its scenes: ``"met"``, ``"missed"``, ``"not judged"``
    or ``"none"``, and e.g. ``look against the Mitsuba roughplastic it was fitted from: 44.1 / 44.2 dB,
    FLIP 0.021 / 0.030 (goal >= 30 dB, FLIP <= 0.05): met``."""
    looks = [(row, row["look"]) for row in rows if row.get("look")]
    if not looks:
        return "none", ""
    if all(look.get("reference") is None for _, look in looks):
        if looks[0][1].get("skipped"):
            return "none", f"look not measured: physical reference {looks[0][1].get('why_none')}"
        return "none", f"no physical reference ({looks[0][1].get('why_none') or 'none'})"
    judged = [(row, look) for row, look in looks if look.get("reference") is not None]
    figures = [row["references"][look["reference"]] for row, look in judged]
    compared = judged[0][1]["compared"]
    goal = judged[0][1]["goal"]
    psnrs = " / ".join(_ref_psnr_text(f) for f in figures)
    flips = " / ".join("n/a" if _unmeasured_match(f) else _fmt(f["flip"], ".3f") for f in figures)
    own = ", the material's own" if judged[0][1].get("goal_source") == "material" else ""
    text = f"look against {compared}: {psnrs} dB, FLIP {flips}{_parts_text(figures)} (goal >= {goal['psnr_db']:g} dB, FLIP <= {goal['flip']:g}{own})"
    missed = [row["scene"] + _missed_parts(look) for row, look in judged if look["meets_goal"] is False]
    unjudged = [f"{row['scene']}: {look['not_judged']}" for row, look in judged if look["not_judged"]]
    if missed:
        return "missed", text + f": missed on {', '.join(missed)}" + (
            f"; not judged on {'; '.join(unjudged)}" if unjudged else ""
        )
    if unjudged:
        unmeasured = all(look["not_judged"].startswith("not measured") for _, look in judged if look["not_judged"])
        return "not measured" if unmeasured else "not judged", text + f": not judged on {'; '.join(unjudged)}"
    bounds = [f"{row['scene']}: {look['bound']}" for row, look in judged if look.get("bound")]
    return "met", text + ": met" + (f" ({'; '.join(bounds)})" if bounds else "")


def _parts_text(figures: list) -> str:
    """``; sphere: 42.2 / 37.8 dB, FLIP 0.031 / 0.040, 27% / 31% of the frame; flat part: ...``: the figures of
    each part of the comparisons (``parts``, by object), scene after scene; "" where none is split."""
    names = list(dict.fromkeys(name for f in figures for name in (f.get("parts") or {})))
    out = []
    for name in names:
        parts = [(f.get("parts") or {}).get(name) or {} for f in figures]
        out.append(f"{name}: {' / '.join(_psnr_text(p.get('psnr_db')) if p else 'n/a' for p in parts)} dB, "
                   f"FLIP {' / '.join(_fmt(p.get('flip'), '.3f') for p in parts)}, "
                   f"{' / '.join(_fmt(p.get('coverage'), '.0%') for p in parts)} of the frame")  # fmt: skip
    return "".join(f"; {x}" for x in out)


def _missed_parts(look: dict) -> str:
    """`` (flat part)``: the parts of a missed look that miss its goal, or ""."""
    missed = [name for name, p in (look.get("parts") or {}).items() if p.get("meets_goal") is False]
    return f" ({', '.join(missed)})" if missed else ""


def _storage_goals_text(judged: list, goals: dict) -> str:
    """Each storage goal the ``judged`` (row, model reference) pairs were held to, with the worst figures of the
    comparisons held to it: the settings' PSNR and FLIP, and an environment map's own PSNR goal (its scene named),
    which the line gave as the default goal beside an environment's worst figure ("PSNR >= 45 dB; worst 41.4 dB" for
    4/4 met). E.g. ``PSNR >= 45 dB, FLIP <= 0.01; worst 52.1 dB, FLIP 0.0031; env-sky: PSNR >= 35 dB; worst 41.4 dB``."""
    groups: dict = {}
    for row, m in judged:
        own = row.get("goal_psnr_db")
        groups.setdefault(own if is_number(own) else None, []).append((row, m))
    texts = []
    for own, pairs in sorted(groups.items(), key=lambda item: item[0] is not None):
        figures = [m for _, m in pairs if not_measured(m) is None]
        psnrs = [m["psnr_db"] for m in figures if m["psnr_db"] is not None]
        worst = f"worst {_psnr_text(min(psnrs) if psnrs else None)} dB"
        if own is None:
            flips = [m["flip"] for m in figures if m["flip"] is not None]
            texts.append(f"{_goals_text(goals)}; {worst}, FLIP {_fmt(max(flips) if flips else None, '.4f')}")
        else:
            scenes = ", ".join(dict.fromkeys(row["scene"] for row, _ in pairs))
            texts.append(f"{scenes}: PSNR >= {own:g} dB; {worst}")
    return "; ".join(texts)


def describe_materials(data: dict) -> list[str]:
    """One line per material: its verdict, then what was measured against which goal.

    The verdict leads: ``all goals met`` only where every goal that applies is met and the look
    was judged against physics on every scene; else ``goals missed: look, storage`` (what missed), or
    ``look not judged`` (a reference short of its noise floor), or ``storage goals met`` followed by
    ``no physical reference (why)`` (toon). Then the storage goal, e.g. ``storage 2/2 met (PSNR >= 45 dB, FLIP <= 0.01;
    worst 52.1 dB, FLIP 0.0031)`` for a LUT material (its image against the model reference), the
    look (:func:`_look_text`), and for a separable material the error its manifest claims (relative
    RMS of f cos at 8 bits, the figure its ``error_budget`` bounds), the budget, and the worst
    error measured in the scenes.
    """
    goals = data["settings"]["goals"]
    lines = []
    for name, rows in _rows_by_material(data).items():
        parts, missed = [], []
        models = [(row, row["references"]["model"]) for row in rows if "model" in row["references"]]
        judged = [(row, m) for row, m in models if m.get("meets_goal") is not None]
        checked = [m for _, m in judged]
        # Model comparisons that measure nothing of the material (no goal judged on them): said, never met.
        unmeasured = [f"{row['scene']}: {not_measured(m)}" for row, m in models
                      if m.get("meets_goal") is None and not_measured(m) is not None]  # fmt: skip
        if checked:
            met = sum(1 for m in checked if m["meets_goal"])
            if met < len(checked):
                missed.append("storage")
            parts.append(f"storage {met}/{len(checked)} met ({_storage_goals_text(judged, goals)})"
                         + (f", not measured on {'; '.join(unmeasured)}" if unmeasured else ""))  # fmt: skip
        elif unmeasured:
            parts.append(f"nothing measured against its model reference on {'; '.join(unmeasured)}")
        look, look_text = _look_text(rows)
        if look_text:
            parts.append(look_text)
        if look == "missed":
            missed.insert(0, "look")
        claimed, budget, measured = _separable_figures(rows)
        if not checked and claimed is not None:
            verdict = "none" if budget is None else f"{budget:.2%}, {'met' if claimed <= budget else 'missed'}"
            if budget is not None and claimed > budget:
                missed.append("separable budget")
            line = f"separable error {claimed:.2%} (8-bit, claimed; budget {verdict})"
            if measured is not None:
                line += f", {measured:.2%} measured in the scenes (worst, atlas against source)"
            parts.append(line)
        if not parts:
            lines.append(f"{name}: no goals apply ({rows[0]['type']})")
            continue
        unjudged = (["model reference"] if unmeasured else []) + (["look"] if look == "not measured" else [])
        if missed:
            head = f"goals missed: {', '.join(missed)}"
        elif unjudged:
            head = f"not measured: {', '.join(unjudged)}"
        elif look == "not judged":
            head = "look not judged"
        elif look == "none" and look_text:
            head = "storage goals met" if checked else "no goals judged"
        elif look == "none":  # a report without look goals (written before them)
            head = "storage goals met" if checked else "no LUT goals apply"
        else:
            head = "all goals met"
        lines.append(f"{name}: {head}; {'; '.join(parts)}")
    return lines


def noise_floor_failures(data: dict) -> list[str]:
    """One text per comparison whose stochastic reference is too noisy to measure its error:
    ``noise_floor_ok`` false (the floor is not 10 dB above the PSNR measured against it)."""
    out = []
    for row in data.get("results", []):
        for kind, ref in row["references"].items():
            if ref.get("noise_floor_ok") is False:
                # The figures short of the floor: the whole comparison's, and each part's (by object).
                short = [(name, p) for name, p in (ref.get("parts") or {}).items() if p.get("noise_floor_ok") is False]
                if not short or not _whole_floor_ok(ref):
                    short.insert(0, (None, ref))
                for name, figures in short:
                    where, there = ("", "") if name is None else (f" on the {name}", " there")
                    out.append(f"{row['material']} on {row['scene']}: the {kind} reference's noise floor{where} "
                               f"{_psnr_text(figures.get('noise_floor_db'))} dB is not 10 dB above the PSNR it measures{there} "
                               f"({_psnr_text(figures.get('psnr_db'))} dB) at {figures.get('spp', ref.get('spp'))} spp; "
                               f"raise --max-physical-spp")  # fmt: skip
    return out


def _whole_floor_ok(ref: dict) -> bool:
    """Whether a reference dict's noise floor clears its whole comparison's PSNR by the margin (null = inf)."""
    floor = math.inf if ref.get("noise_floor_db") is None else ref["noise_floor_db"]
    psnr_db = math.inf if ref.get("psnr_db") is None else ref["psnr_db"]
    return bool(floor >= psnr_db + NOISE_FLOOR_MARGIN_DB)


def missed_goals(data: dict) -> list[str]:
    """Each goal a report misses, one short text each; empty when all are met.

    A LUT result misses when its model-reference PSNR or mean FLIP misses the goals; a
    separable material misses when the error its manifest claims exceeds its budget; any
    comparison misses when its stochastic reference's noise floor is not 10 dB above the
    error it measures (:func:`noise_floor_failures`); and a model comparison, or the one a look is
    judged on, that measures nothing of the material (:func:`not_measured`) is no goal met.
    """
    goals = data["settings"]["goals"]
    missed = noise_floor_failures(data)
    for name, rows in _rows_by_material(data).items():
        for row in rows:
            for kind, ref in row["references"].items():  # no goal is met on nothing: --strict counts it
                if not_measured(ref) is not None and ref.get("meets_goal") is not False and (
                        kind == "model" or kind == (row.get("look") or {}).get("reference")):  # fmt: skip
                    missed.append(f"{name} on {row['scene']}: nothing measured against the {kind} reference "
                                  f"({not_measured(ref)})")  # fmt: skip
            model = row["references"].get("model") or {}
            if model.get("meets_goal") is False:
                missed.append(f"{name} on {row['scene']}: PSNR {_ref_psnr_text(model)} dB, "
                              f"FLIP {_fmt(model['flip'], '.4f')} ({_goals_text(goals)})")  # fmt: skip
            look = row.get("look") or {}
            if look.get("meets_goal") is False:
                ref = row["references"][look["reference"]]
                parts = "".join(f"; {part}: PSNR {_psnr_text(p['psnr_db'])} dB, FLIP {_fmt(p['flip'], '.4f')}"
                                + ("" if (look.get("parts") or {}).get(part, {}).get("meets_goal") is not False else " (missed)")
                                for part, p in (ref.get("parts") or {}).items())  # fmt: skip
                missed.append(f"{name} on {row['scene']}: look against {look['compared']}: PSNR {_ref_psnr_text(ref)} dB "
                              f"(at the unclipped exposure {_psnr_text(ref.get('unclipped_psnr_db'))} dB), FLIP {_fmt(ref['flip'], '.4f')}{parts} "
                              f"(goal >= {look['goal']['psnr_db']:g} dB, FLIP <= {look['goal']['flip']:g})")  # fmt: skip
        claimed, budget, _ = _separable_figures(rows)
        if claimed is not None and budget is not None and claimed > budget:
            missed.append(f"{name}: separable error {claimed:.2%} over its budget {budget:.2%}")
    return missed


def plot_speed_error(data: dict) -> bytes:
    """The PNG of :func:`speed_error_chart` (its labels are the page's, over the image)."""
    return speed_error_chart(data).png


def speed_error_chart(data: dict) -> Chart:
    """One PNG plot and its point labels (:func:`atlasgen.reports.html.figure_chart`): the *reference render cost*, how many atlas frames one reference render costs (x, log), against
    the atlas image's mean FLIP against that reference (y, log), one point per material and scene.

    ``data`` is a report dict (:func:`report_dict`, or a merged one): the plot reads only
    its measured ``speed_ratio`` and ``flip`` figures. This is not the run-time cost of a
    representation: that is the lighting pass's time per pixel per light, set against the error
    versus the physical reference in the library report's Pareto charts (:mod:`atlasgen.reports.pareto`)."""
    with plot_style() as plt:
        fig, ax = plt.subplots(figsize=_PLOT_SIZE)
        markers = {"model": ("o", "tab:blue"), "physical": ("s", "tab:orange")}
        points = []
        for kind, (marker, colour) in markers.items():
            xs, ys = [], []
            for row in data["results"]:
                ref = row["references"].get(kind)
                # No ratio where the atlas frame took no measurable time (report_dict stores None), and no FLIP
                # where no pixel of the material was scored (a frame too small to show it: the mean of nothing).
                if ref is None or ref["speed_ratio"] is None or ref["flip"] is None:
                    continue
                xs.append(ref["speed_ratio"])
                ys.append(max(ref["flip"], 1e-4))  # log axis: a perfect match still gets a point
                points.append((-xs[-1], ys[-1], f"{row['material']}/{row['scene']}"))
            if xs:
                ax.scatter(xs, ys, marker=marker, color=colour, label=f"atlas vs {kind} reference", alpha=0.8)
        # Only the front (no result both faster and closer) is labelled; the metrics table lists every result.
        front = [points[i] for i in pareto_front([p[:2] for p in points])]
        label_points(ax, [(-p[0], p[1]) for p in front], [p[2] for p in front])
        goals = data["settings"]["goals"]
        # Two goals, not one: a LUT's storage against its model reference, and the look (a LUT's against physics,
        # a separable's against its source BSDF) at a looser FLIP.
        ax.axhline(goals["flip"], color="tab:blue", linestyle="--", linewidth=1,
                   label=f"storage goal (a LUT against its model): mean FLIP <= {goals['flip']}")  # fmt: skip
        if "look_flip" in goals:
            ax.axhline(goals["look_flip"], color="tab:orange", linestyle="--", linewidth=1,
                       label=f"look goal (against physics or a source): mean FLIP <= {goals['look_flip']}")  # fmt: skip
        if points:
            ax.set_xscale("log")
        else:  # no result with both figures (a frame too small to show the material): a log axis would have no value
            ax.text(0.5, 0.5, "no result has both a speed ratio and a FLIP", transform=ax.transAxes, ha="center")
        ax.set_yscale("log")
        ax.set_xlabel("reference render cost: Mitsuba render time / atlas frame time")
        ax.set_ylabel("mean FLIP of the atlas image (lower is better)")
        ax.set_title(
            "Reference render cost against error (labelled: its Pareto front)\n"
            "run-time cost vs error: the library report's Pareto charts",
            fontsize="medium",
        )
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        return figure_chart(fig)


def _fmt(x, spec):
    return "n/a" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


#: The figures of every result, in this order, whatever references a material has.
_FIGURE_KINDS = ("model", "physical", "rebuild")


def _anchor(material: str) -> str:
    """The HTML id of a material's section."""
    return "material-" + "".join(c if c.isalnum() or c in "-_" else "-" for c in material)


def _figures(row: dict, size: tuple) -> list[dict]:
    """The fixed row of figures of one result: the atlas, then per reference kind its
    image and its FLIP map, or an empty place where the material has no such reference."""
    width, height = size
    figures = [{"src": row["atlas_image"], "caption": _KIND_LABEL["atlas"], "width": width, "height": height}]
    for kind in _FIGURE_KINDS:
        ref = row["references"].get(kind)
        if ref is None:
            figures += [
                {"src": None, "caption": f"no {_KIND_LABEL[kind]}", "width": width, "height": height},
                {"src": None, "caption": f"no FLIP map against a {kind} reference", "width": width, "height": height},
            ]
            continue
        figures.append({"src": ref["images"]["reference"], "caption": f"{_KIND_LABEL[kind]}: {ref['description']}{_noise(ref)}",
                        "width": width, "height": height})  # fmt: skip
        figures.append({"src": ref["images"]["flip"], "caption": f"FLIP atlas vs {kind}: {_fmt(ref['flip'], '.4f')}",
                        "width": width, "height": height})  # fmt: skip
    return figures


def _noise(ref: dict) -> str:
    """What a stochastic reference's image carries: its samples per pixel and noise floor (two seeds
    against each other), and each object's of a comparison split by object; "" for an exact reference."""
    if ref.get("noise_floor_db") is None:
        return ""
    parts = [f"{name} {p['spp']} spp, {_fmt(p.get('noise_floor_db'), '.1f')} dB"
             for name, p in (ref.get("parts") or {}).items() if p.get("noise_floor_db") is not None]  # fmt: skip
    return (f" ({ref['spp']} spp, noise floor {_fmt(ref['noise_floor_db'], '.1f')} dB"
            + (f"; {', '.join(parts)}" if parts else "") + ")")  # fmt: skip


def materialx_summary(rows: list) -> dict | None:
    """What the page says of a material imported from MaterialX, from its rows' ``materialx`` records:
    its source document and name in it, its surface model, the representation chosen, its error against
    the oracle ± SE (the manifest's: 8-bit relative RMS of f cos on a sample independent of the fit),
    what the table could not hold or was flattened, the per-scene PSNR against the oracle's image (with the
    pixels it leaves out, normals facing away from the camera, and the PSNR counting them), and where there is
    one its shading over its physical reference's; ``None`` for any other material."""
    records = [(row, row["materialx"]) for row in rows if row.get("materialx")]
    if not records:
        return None
    first = records[0][1]
    claimed = records[0][0].get("claimed_errors") or {}
    error = claimed.get("relative_rms_8bit")
    se = claimed.get("relative_rms_8bit_se")
    out = {
        "document": first.get("document"), "material": first.get("material"), "category": first.get("category"),
        "representation": first.get("representation"),
        "error": "n/a" if error is None else f"{error:.4f}" + ("" if se is None else f" ± {se:.4f}"),
        "not_in_table": first.get("not_in_table") or [], "flattened": first.get("flattened") or [],
        "scenes": [{"scene": row["scene"], "psnr": _psnr_text((row["references"].get("model") or {}).get("psnr_db")),
                    "reference": m.get("reference"),
                    "agreement": _psnr_text((m.get("forward_vs_mitsuba_plugin") or {}).get("psnr_db"))
                    if m.get("forward_vs_mitsuba_plugin") else None,
                    "facing_away": (m.get("facing_away") or {}).get("pixels") or 0,
                    "counting_them": _psnr_text((m.get("facing_away") or {}).get("psnr_db_counting_them"))}
                   for row, m in records],
        "ratio": None,
    }  # fmt: skip
    ratios = [(row["scene"], m["oracle_over_physical"]) for row, m in records if m.get("oracle_over_physical")]
    if ratios:
        r = ratios[0][1]
        pixels = "; ".join(f"{scene} {' / '.join(f'{x:.3f}' for x in q['pixel_p1_p50_p99'])}" for scene, q in ratios
                           if q.get("pixel_p1_p50_p99"))  # fmt: skip
        out["ratio"] = {"reference": r.get("reference"), "pairs": r.get("pairs"), "pixels": pixels,
                        "bsdf": " / ".join(f"{x:.3f}" for x in r.get("bsdf_p1_p50_p99") or []),
                        "bsdf_range": " to ".join(f"{x:.3f}" for x in r.get("bsdf_min_max") or []),
                        "probe": " to ".join(f"{x:.3f}" for x in r.get("probe_range") or []),
                        "within": r.get("within_probe_range")}  # fmt: skip
    return out


def _claimed_text(kind: str, row: dict) -> str:
    c = row.get("claimed_errors")
    if kind != "model" or not c:
        return ""
    se = f" ± {c['relative_rms_8bit_se']:.4f}" if c.get("relative_rms_8bit_se") is not None else ""
    return (f"claimed rel. RMS {_fmt(c['relative_rms_8bit'], '.4f')}{se} (8-bit, K={c['terms']}); "
            f"measured {_fmt(c['measured_relative_rms_atlas_vs_source'], '.4f')}")  # fmt: skip


def _region_text(ref: dict, region: str) -> str:
    """``PSNR dB / FLIP (coverage)`` of one of a comparison's regions (grazing N.V and the rest), or ""."""
    r = (ref.get("regions") or {}).get(region)
    if r is None:
        return ""
    return f"{_fmt(r['psnr_db'], '.2f')} / {_fmt(r['flip'], '.4f')} ({r['coverage']:.1%})"


def _html(data: dict, plot: Chart | None = None) -> bytes:
    s = data["settings"]
    sizes = {sc["name"]: (sc.get("width"), sc.get("height")) for sc in s.get("scenes", [])}
    metric_rows, breakdown, materials = [], [], []
    for row in data["results"]:
        for kind, ref in row["references"].items():
            metric_rows.append({
                "material": row["material"], "anchor": _anchor(row["material"]), "type": row["type"],
                "scene": row["scene"], "atlas_ms": f"{1000 * row['atlas_seconds']:.1f}", "kind": kind,
                "seconds": f"{ref['seconds']:.3f}", "speed": _fmt(ref["speed_ratio"], ".1f"), "rmse": _fmt(ref["rmse"], ".5f"),
                "psnr": _fmt(ref["psnr_db"], ".2f"), "flip": _fmt(ref["flip"], ".4f"),
                "goal": ref["meets_goal"] if ref.get("meets_goal") is not None else ref.get("look_goal"),
                "not_measured": not_measured(ref),
                "whole_frame": _fmt(ref.get("whole_frame_psnr_db"), ".2f"),
                "coverage": _fmt(ref.get("coverage"), ".1%"),
                "clipped": "" if ref.get("clipped_pixels") is None else
                           f"{ref['clipped_pixels']} ({_fmt(ref.get('unclipped_psnr_db'), '.2f')} dB unclipped)",
                "grazing": _region_text(ref, "grazing"), "rest": _region_text(ref, "rest"),
                "parts": "; ".join(f"{name}: {_fmt(p['psnr_db'], '.2f')} / {_fmt(p['flip'], '.4f')} ({p['coverage']:.1%})"
                                   + (f", floor {_fmt(p.get('noise_floor_db'), '.1f')} at {p.get('spp')} spp"
                                      + (" (too noisy)" if p.get("noise_floor_ok") is False else "")
                                      if "noise_floor_db" in p else "")
                                   for name, p in (ref.get("parts") or {}).items()),
                # A floor is the floor at some sample count: a budgeted run (make demo) stops short.
                "floor": f"{_fmt(ref.get('noise_floor_db'), '.1f')} at {ref.get('spp')} spp" if "noise_floor_db" in ref else "",
                "floor_ok": ref.get("noise_floor_ok"),
                "masked": f"{ref['masked_fraction']:.1%} ({ref['masked']})" if "masked_fraction" in ref else "",
                "claimed": _claimed_text(kind, row),
            })  # fmt: skip
        b = row.get("error_breakdown")
        if b:
            model = row["references"]["model"]
            breakdown.append(
                {
                    "material": row["material"],
                    "scene": row["scene"],
                    "figures": [
                        _fmt(b["table_float"]["psnr_db"], ".2f"),
                        _fmt(b["table_float"]["flip"], ".4f"),
                        _fmt(b["table_8bit"]["psnr_db"], ".2f"),
                        _fmt(b["table_8bit"]["flip"], ".4f"),
                        _fmt(model["psnr_db"], ".2f"),
                        _fmt(model["flip"], ".4f"),
                        _fmt(b["gpu_vs_8bit"]["psnr_db"], ".2f"),
                    ],
                }
            )
    for name, rows in _rows_by_material(data).items():
        materials.append({
            "name": name, "type": rows[0]["type"], "anchor": _anchor(name),
            "page": next((r["page"] for r in rows if "page" in r), None), "materialx": materialx_summary(rows),
            "results": [{"scene": r["scene"], "figures": _figures(r, sizes.get(r["scene"], (None, None))),
                         "notes": r["notes"]} for r in rows],
        })  # fmt: skip
    columns = [_KIND_LABEL["atlas"]] + [f"{_KIND_LABEL[k]} and its FLIP map" for k in _FIGURE_KINDS]
    return render_page(
        "validation.html.j2",
        data=data,
        settings=s,
        merged="merged_from" in data,
        goals_text=_goals_text(s["goals"]),
        worst_psnr=_fmt(data["summary"]["worst_lut_psnr_db"], ".2f"),
        worst_flip=_fmt(data["summary"]["worst_lut_flip"], ".4f"),
        material_lines=describe_materials(data),
        plot=plot if plot is not None else speed_error_chart(data),
        pairs=validation_pairs(data),
        metric_rows=metric_rows,
        breakdown=breakdown,
        environment_rows=environment_rows(data),
        environment_columns=[heading for heading, _ in ENVIRONMENT_COLUMNS],
        materials=materials,
        columns=columns,
    )


def build_report(run, out_dir) -> dict:
    """``{path: bytes}`` of every report file under ``out_dir``."""
    out_dir = Path(out_dir)
    files = {}
    for r in run.runs:
        files[out_dir / image_name(r.material, r.scene, "atlas")] = _display_png(display_clip(r.atlas_image, r.exposure))
        for kind, ref in r.references.items():
            files[out_dir / image_name(r.material, r.scene, kind)] = _display_png(display_clip(ref.image, r.exposure))
            files[out_dir / image_name(r.material, r.scene, f"flip-{kind}")] = _display_png(flip_heatmap(ref.metrics.flip_map))
    files.update(_page_files(report_dict(run, out_dir), out_dir))
    return files


def _page_files(data: dict, out_dir: Path) -> dict:
    """``{path: bytes}`` of the plot, the JSON and the page of one report dict."""
    plot = speed_error_chart(data)
    return {
        out_dir / "speed_error.png": plot.png,
        out_dir / "report.json": (json.dumps(data, indent=2, allow_nan=False) + "\n").encode(),
        out_dir / "index.html": _html(data, plot),
    }


def read_validation_report(path: Path) -> dict:
    """A ``report.json`` of ``atlasgen validate``, its figures checked finite (one line naming the field otherwise)."""
    data = read_report_json(path, "validation", "atlasgen validate")
    missing = (
        [k for k in ("atlas", "settings", "environment", "total_seconds", "results") if k not in data]
        if isinstance(data, dict)
        else ["everything"]
    )
    if missing:
        if report_kind(data) == "separable":  # "missing everything" did not say what the folder holds
            raise InputError(f"{path.as_posix()}: a separable report (atlasgen report separable), not a validation "
                             "report; expected the folder of an atlasgen validate run")  # fmt: skip
        raise InputError(f"{path.as_posix()}: not a validation report (missing {', '.join(missing)})")
    _check_figures(path, data)
    return data


#: The keys of ``environment`` and ``settings`` the merged page prints.
_ENVIRONMENT_KEYS = ("gpu", "mitsuba", "atlas_timing", "mitsuba_timing")
_SETTINGS_KEYS = ("spp", "physical_spp")
#: The numbers of a report.json (each finite, or null) that a merge adds, compares or prints, with the (least,
#: greatest) each can be where it has bounds: a merge printed a FLIP of -1 as the worst, a coverage of 5 and an spp
#: of 0 (a hostile sweep).
_ROW_NUMBERS = {"exposure": (0.0, None), "atlas_seconds": (0.0, None), "goal_psnr_db": (None, None)}
_REFERENCE_NUMBERS = {"seconds": (0.0, None), "speed_ratio": (0.0, None), "rmse": (0.0, None), "psnr_db": (None, None),
                      "flip": (0.0, 1.0), "linear_rmse": (0.0, None), "linear_relative_rms": (0.0, None),
                      "noise_floor_db": (None, None), "masked_fraction": (0.0, 1.0), "spp": (1.0, None),
                      "coverage": (0.0, 1.0), "clipped_pixels": (0.0, None), "whole_frame_psnr_db": (None, None),
                      "unclipped_psnr_db": (None, None), "unclipped_exposure": (0.0, None)}  # fmt: skip
#: A comparison's figures over one region (grazing N.V, the rest) and one part of the error's breakdown: a merge copied
#: a FLIP of -1, a coverage of 500% and a PSNR of true into its page.
_REGION_NUMBERS = {"coverage": (0.0, 1.0), "pixels": (0.0, None), "psnr_db": (None, None), "flip": (0.0, 1.0)}
_BREAKDOWN_NUMBERS = {"psnr_db": (None, None), "flip": (0.0, 1.0), "linear_relative_rms": (0.0, None)}


def _check_figures(path: Path, data: dict) -> None:
    """Refuse a report whose figures are not finite numbers (or null), naming the field."""
    if not isinstance(data["atlas"], str) or not data["atlas"]:  # the page and a merge print it as the atlas's path
        raise FieldError(path.as_posix(), "atlas", f"expected the atlas's path as atlasgen validate writes it, "
                                                   f"got {shorten(repr(data['atlas']))}")  # fmt: skip
    check_number(path, "total_seconds", data["total_seconds"], allow_none=False, minimum=0)
    for part, keys in (("environment", _ENVIRONMENT_KEYS), ("settings", _SETTINGS_KEYS)):
        if not isinstance(data[part], dict):
            raise FieldError(path.as_posix(), part, f"expected an object, got {type(data[part]).__name__}")
        missing = [k for k in keys if k not in data[part]]
        if missing:
            raise FieldError(path.as_posix(), f"{part}.{missing[0]}", "missing; expected the key atlasgen validate writes")
    for key in _SETTINGS_KEYS:  # the sample counts, compared between the merged runs and printed
        check_number(path, f"settings.{key}", data["settings"][key], minimum=1)
    scenes = data["settings"].get("scenes", [])
    if not isinstance(scenes, list) or not all(isinstance(s, dict) and isinstance(s.get("name"), str) for s in scenes):
        raise FieldError(path.as_posix(), "settings.scenes", f"expected a list of scenes, each an object with a 'name', "
                         f"got {shorten(repr(scenes))}")  # fmt: skip
    check_result_figures(path, data["results"], merged=True)
    names = [s["name"] for s in scenes]
    for i, row in enumerate(data["results"]):
        # The page sizes each result's images by its scene's entry: a result on a scene the report did not render
        # merged with no size, beside settings that never named it.
        if names and row["scene"] not in names:
            raise FieldError(path.as_posix(), f"results[{i}].scene", f"expected a scene of settings.scenes "
                             f"({', '.join(shorten(repr(n)) for n in names)}), got {shorten(repr(row['scene']))}")  # fmt: skip
    _check_verdicts(path, data)


def _check_verdicts(path: Path, data: dict) -> None:
    """Refuse a model reference whose recorded verdict is not what its figures and the goals give (:func:`_goal`'s
    rule): a merge prints the verdicts it reads, so an edited ``meets_goal`` (true beside 20 dB) passed as "all goals
    met". A null PSNR is an infinite one (JSON has no inf); a verdict beside no FLIP, or "met" where nothing of the
    material was measured, is refused too."""
    goals = data["settings"].get("goals")
    if not isinstance(goals, dict) or not all(is_number(goals.get(k)) for k in ("psnr_db", "flip")):
        return  # the page's own check names such goals
    for i, row in enumerate(data["results"]):
        ref = row["references"].get("model")
        if not isinstance(ref, dict) or not _verdict_to_check(path, i, row, ref):
            continue
        psnr, flip, own = ref.get("psnr_db"), ref.get("flip"), row.get("goal_psnr_db")
        _refuse_verdict_without_flip(path, f"results[{i}].references.model", ref, ref["meets_goal"])
        if not (is_number(psnr) or psnr is None) or not is_number(flip):
            if not_measured(ref) is None or ref["meets_goal"] is not True:
                continue
            expected = None  # nothing measured, and figures that cannot say otherwise
        else:
            # A null PSNR is an infinite one (identical images: JSON has no inf), met whatever the goal.
            met = _storage_met(math.inf if psnr is None else psnr, flip, goals, own if is_number(own) else None)
            expected = _unmeasured_verdict(met, not_measured(ref), psnr)
        if expected != ref["meets_goal"]:
            goal = f"PSNR >= {own:g} dB" if is_number(own) else _goals_text(goals)
            raise FieldError(path.as_posix(), f"results[{i}].references.model.meets_goal", f"expected "
                             f"{_verdict_text(expected)} from its figures (PSNR {_psnr_text(psnr)} dB, FLIP {_fmt(flip, '.4f')}) and the goals "
                             f"({goal}), got {_verdict_text(ref['meets_goal'])}; re-run atlasgen validate")  # fmt: skip
    for i, row in enumerate(data["results"]):
        _check_look_verdict(path, f"results[{i}]", row)
        for kind, ref in row["references"].items():
            # The storage goals judge the model reference alone (_goal): an edited "missed" on a physical comparison
            # was printed beside "all goals met".
            if kind != "model" and ref.get("meets_goal") is not None:
                raise FieldError(path.as_posix(), f"results[{i}].references.{kind}.meets_goal", "expected null (the "
                                 f"goals judge the model reference alone), got {_verdict_text(ref['meets_goal'])}")  # fmt: skip


def _goals_apply(row: dict) -> bool | None:
    """Whether the storage goals judge a result's model reference (:func:`_goal`: its model's
    ``validation_goals``), or None where the report's ``type`` names no model this atlasgen knows."""
    try:
        return bool(get_model(row["type"]).validation_goals) if isinstance(row.get("type"), str) else None
    except KeyError:
        return None


def _verdict_to_check(path: Path, i: int, row: dict, ref: dict) -> bool:
    """Whether a model reference's recorded verdict is checked against its figures (:func:`_check_verdicts`): a
    true or false, or a null where the goals judge the model (a verdict nulled by hand dropped the result from the
    summary's count); a true or false where they do not (a model that claims its own error) is refused."""
    verdict, applies = ref.get("meets_goal"), _goals_apply(row)
    if isinstance(verdict, bool) and applies is False:
        raise FieldError(path.as_posix(), f"results[{i}].references.model.meets_goal", f"expected null (a {row['type']} "
                         f"material claims its own error, which the goals do not judge), got {_verdict_text(verdict)}")  # fmt: skip
    return isinstance(verdict, bool) or (verdict is None and applies is True)


def _refuse_verdict_without_flip(path: Path, where: str, ref: dict, verdict) -> None:
    """Refuse a verdict recorded beside a comparison that measured the material but has no FLIP: a null PSNR is an
    infinite one, but a null FLIP is no figure at all (identical images give 0), and a merge printed "met" on a
    comparison whose figures were all null, and "inf / inf dB" for a look."""
    if isinstance(verdict, bool) and not_measured(ref) is None and not is_number(ref.get("flip")):
        raise FieldError(path.as_posix(), f"{where}.flip", f"expected a number beside the verdict it gives "
                         f"(meets_goal {_verdict_text(verdict)}), got {shown(ref.get('flip'))}; re-run atlasgen validate")  # fmt: skip


def _verdict_text(value) -> str:
    return "null" if value is None else str(value).lower()


def _check_look_verdict(path: Path, where: str, row: dict) -> None:
    """Refuse a look whose recorded verdict is not what :func:`look_verdict` gives from its goal and the figures of
    the reference it names, as the page would judge them: a merge passed "met" beside a physical PSNR of 10 dB (an
    edited psnr_db, flip or goal), and printed a miss beside figures that meet the goal (an edited meets_goal)."""
    look = row.get("look")
    if not isinstance(look, dict) or not isinstance(look.get("goal"), dict):
        return
    ref = row["references"].get(look.get("reference") or "")
    if look.get("meets_goal") is not None and (look.get("reference") is None or look.get("skipped")):
        # A look with no reference (not rendered, or none exists) was kept as "met" in the merged report.json.
        raise FieldError(path.as_posix(), f"{where}.look.meets_goal", "expected null for a look compared with nothing "
                         f"({look.get('why_none') or 'no reference'}), got {_verdict_text(look.get('meets_goal'))}; "
                         "re-run atlasgen validate")  # fmt: skip
    if not isinstance(ref, dict) or not all(is_number(look["goal"].get(k)) for k in ("psnr_db", "flip")):
        return
    _refuse_verdict_without_flip(path, f"{where}.references.{look['reference']}", ref, look.get("meets_goal"))
    expected = look_verdict(look, ref)["meets_goal"]
    figures = f"PSNR {_psnr_text(ref.get('psnr_db'))} dB, FLIP {_fmt(ref.get('flip'), '.4f')}"
    goal = f"PSNR >= {look['goal']['psnr_db']:g} dB, FLIP <= {look['goal']['flip']:g}"
    if expected != look.get("meets_goal"):
        raise FieldError(path.as_posix(), f"{where}.look.meets_goal", f"expected {_verdict_text(expected)} from the "
                         f"{look['reference']} reference's figures ({figures}) and the look goal ({goal}), got "
                         f"{_verdict_text(look.get('meets_goal'))}; re-run atlasgen validate")  # fmt: skip
    if "look_goal" in ref and ref["look_goal"] != look.get("meets_goal"):
        raise FieldError(path.as_posix(), f"{where}.references.{look['reference']}.look_goal", f"expected "
                         f"{_verdict_text(look.get('meets_goal'))}, the look's verdict, got {_verdict_text(ref['look_goal'])}")  # fmt: skip


#: Per key of a result (and of each of its references), what a merge or the library page reads it as:
#: (the type, its name in a refusal, whether it may be absent or null).
_ROW_FIELDS = {"material": (str, "a material name", False), "scene": (str, "a scene name", False),
               "atlas_image": (str, "an image path", True), "page": (str, "a page path", True),
               "notes": (list, "a list of notes", True), "look": (dict, "an object", True),
               "error_breakdown": (dict, "an object", True), "atlas_identity": (dict, "an object", True),
               "type": (str, "a material type", True)}  # fmt: skip
_REFERENCE_FIELDS = {"images": (dict, "an object of image paths", True)}
#: A look's words, which the page prints and tests as text: a hand-edited ``not_judged: true`` failed deep in the
#: page ("'bool' object has no attribute 'startswith'").
_LOOK_FIELDS = {key: (str, what, True) for key, what in (("reference", "a reference name"), ("compared", "a description"),
                                                         ("why_none", "a reason"), ("not_judged", "a reason"),
                                                         ("bound", "a description"), ("goal_source", "a word"))}  # fmt: skip
#: What a merge needs besides: the images whose paths it rebases (the library page links none of them).
_MERGED_FIELDS = ("atlas_image", "images")


def _check_fields(path, where: str, data: dict, table: dict, required=()) -> None:
    for key, (kind, expected, optional) in table.items():
        value = data.get(key)
        if (value is None and optional and key not in required) or (isinstance(value, kind) and value != ""):
            continue
        got = "missing" if key not in data else f"got {shorten(repr(value))}"
        raise FieldError(Path(path).as_posix(), f"{where}.{key}", f"expected {expected} as atlasgen validate writes it, {got}")


def check_result_figures(path, results, merged: bool = False) -> None:
    """Refuse validation ``results`` whose figures are not finite numbers (or null), or whose names, paths
    and parts are not of the types atlasgen validate writes, naming the field; with ``merged``, also
    results without the image paths a merge rebases."""
    required = _MERGED_FIELDS if merged else ()
    if not isinstance(results, list):
        raise FieldError(Path(path).as_posix(), "results", f"expected a list of results, got {type(results).__name__}")
    for i, row in enumerate(results):
        if not isinstance(row, dict) or not isinstance(row.get("references"), dict):
            raise FieldError(Path(path).as_posix(), f"results[{i}]", "expected a result with 'references'")
        _check_fields(path, f"results[{i}]", row, _ROW_FIELDS, required)
        if not all(isinstance(note, str) for note in row.get("notes") or []):
            raise FieldError(Path(path).as_posix(), f"results[{i}].notes", "expected a list of strings")
        for key, (low, high) in _ROW_NUMBERS.items():
            check_number(path, f"results[{i}].{key}", row.get(key), minimum=low, maximum=high)
        _check_claimed(path, f"results[{i}].claimed_errors", row.get("claimed_errors"))
        for kind, ref in row["references"].items():
            if not isinstance(ref, dict):
                raise FieldError(Path(path).as_posix(), f"results[{i}].references.{kind}", "expected an object of figures")
            _check_fields(path, f"results[{i}].references.{kind}", ref, _REFERENCE_FIELDS, required)
            if not all(isinstance(v, str) and v for v in (ref.get("images") or {}).values()):
                raise FieldError(Path(path).as_posix(), f"results[{i}].references.{kind}.images", "expected image paths")
            for key, (low, high) in _REFERENCE_NUMBERS.items():
                check_number(path, f"results[{i}].references.{kind}.{key}", ref.get(key), minimum=low, maximum=high)
            _check_parts(path, f"results[{i}].references.{kind}.regions", ref.get("regions"), _REGION_NUMBERS)
            _check_verdict(path, f"results[{i}].references.{kind}", ref)
        _check_parts(path, f"results[{i}].error_breakdown", row.get("error_breakdown"), _BREAKDOWN_NUMBERS)
        look = row.get("look")
        if look is not None:
            _check_fields(path, f"results[{i}].look", look, _LOOK_FIELDS, ())
            _check_verdict(path, f"results[{i}].look", look)
            goal = look.get("goal")
            if goal is not None:
                if not isinstance(goal, dict):
                    raise FieldError(Path(path).as_posix(), f"results[{i}].look.goal",
                                     f"expected an object of goals, got {shorten(repr(goal))}")  # fmt: skip
                for key in ("psnr_db", "flip"):
                    check_number(path, f"results[{i}].look.goal.{key}", goal.get(key), minimum=0.0)
    _check_one_result_each(path, results)


def _check_parts(path, where: str, parts, numbers: dict) -> None:
    """An object of named parts (absent or null: none), each an object whose ``numbers`` are finite within bounds."""
    if parts is None:
        return
    if not isinstance(parts, dict):
        raise FieldError(Path(path).as_posix(), where, f"expected an object of parts, got {shorten(repr(parts))}")
    for name, part in parts.items():
        if not isinstance(part, dict):
            raise FieldError(
                Path(path).as_posix(), f"{where}.{name}", f"expected an object of figures, got {shorten(repr(part))}"
            )
        for key, (low, high) in numbers.items():
            check_number(path, f"{where}.{name}.{key}", part.get(key), minimum=low, maximum=high)


def _check_one_result_each(path, results: list) -> None:
    """One result per material and scene, each page inside the report's folder: the library page showed a second
    result of a material on a scene (PSNR 70.1 and 10.0, one edited) as two rows, where validate --merge refuses it,
    and linked a page of "/etc/passwd" as ../../../../etc/passwd."""
    seen: dict = {}
    for i, row in enumerate(results):
        key = (row["material"], row["scene"])
        if key in seen:
            raise FieldError(Path(path).as_posix(), f"results[{i}]", f"expected one result per material and scene, "
                             f"got a second of material {key[0]!r} on scene {key[1]!r} (results[{seen[key]}])")  # fmt: skip
        seen[key] = i
        page = row.get("page")
        if page is not None and (PurePosixPath(page).is_absolute() or ".." in PurePosixPath(page).parts):
            raise FieldError(Path(path).as_posix(), f"results[{i}].page", f"expected a page inside the report's folder "
                             f"(a relative path without '..'), got {shorten(repr(page))}")  # fmt: skip


def _check_verdict(path, where: str, part: dict) -> None:
    """A verdict as atlasgen validate writes it: ``meets_goal`` true, false or null. A merge copied "yes" into its report,
    and a summary counted it as met (the check of verdicts against figures reads only true and false)."""
    value = part.get("meets_goal")
    if value is not None and not isinstance(value, bool):
        raise FieldError(Path(path).as_posix(), f"{where}.meets_goal", f"expected true, false or null as atlasgen validate "
                         f"writes it, got {shorten(repr(value))}")  # fmt: skip


def _check_claimed(path, where: str, claimed) -> None:
    """A separable result's ``claimed_errors``: an object of figures that are finite numbers of at least 0 (or null),
    its ``terms`` a whole number: the library page printed "abc" as an internal error, and a list as another."""
    if claimed is None:
        return
    if not isinstance(claimed, dict):
        raise FieldError(Path(path).as_posix(), where, f"expected an object of figures, got {type(claimed).__name__}")
    for key, value in claimed.items():
        if key == "terms":
            if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
                raise FieldError(
                    Path(path).as_posix(), f"{where}.terms", f"expected a whole number of terms, got {shorten(repr(value))}"
                )
            continue
        check_number(path, f"{where}.{key}", value, minimum=0.0)


def _rebased_image(rel: str, report: Path, out_dir: Path, field: str) -> str:
    """:func:`~atlasgen.io.report_files.rebase_path` of an image path of the source ``report`` (read from ``field``), which must be one a validation
    writes: relative, a PNG that is there (a hand-edited "/etc/passwd", "../../x" or a .png link to /etc/passwd was
    linked from the merged page)."""
    if Path(rel).is_absolute() or Path(rel).suffix.lower() != ".png" or not is_png_file(report.parent / rel):
        raise FieldError(
            report.as_posix(), field, f"expected the path of a PNG image beside the report, got {shorten(repr(rel))}"
        )
    return rebase_path(rel, report.parent, out_dir)


def _total_seconds(paths, reports) -> float:
    """The runs' ``total_seconds`` added up, refused where the sum passes a double (1e308 twice): its inf failed the
    merged report.json's writing, and the line blamed another field."""
    total = sum(r["total_seconds"] for r in reports)
    if not math.isfinite(total):
        raise FieldError(", ".join(p.as_posix() for p in paths), "total_seconds", "expected run times whose sum a "
                         f"double holds, got {' + '.join(format(r['total_seconds'], 'g') for r in reports)}")  # fmt: skip
    return total


def _joined(values) -> str:
    """Distinct values in first-seen order; one value stays as it is."""
    return "; ".join(dict.fromkeys(str(v) for v in values))


def _combined(values):
    """The merged page's value of an environment field, of the type each run wrote: counts added up, lists joined
    (each item once, first-seen order), text as :func:`_joined` (the merge wrote "2" for 6 renders, and a list's
    Python repr); a run that lacks the field is left out.

    >>> _combined([2, 2, 2]), _combined([["a"], ["b"], ["a"]]), _combined(["3.9.1", "3.9.1"]), _combined([1, None])
    (6, ['a', 'b'], '3.9.1', 1)
    """
    present = [v for v in values if v is not None]
    if present and all(isinstance(v, int | float) and not isinstance(v, bool) for v in present):
        return sum(present)
    if present and all(isinstance(v, list) for v in present):
        return list(dict.fromkeys(item for v in present for item in v if isinstance(item, str | int | float)))
    return _joined(present) if present else None


#: What formatting a page raises on a field that is not what atlasgen validate writes.
_MALFORMED = (KeyError, TypeError, AttributeError, ValueError, IndexError)


def _page_error(data: dict, rows: list, out_dir: Path) -> Exception | None:
    """What summing up and formatting a page of ``data`` with only ``rows`` raises on a field atlasgen validate
    would not write, if anything."""
    try:
        _page_files({**data, "summary": _summary(rows), "results": rows}, out_dir)
    except _MALFORMED as exc:
        return exc
    return None


def _refuse_malformed(data: dict, paths: list, reports: list, out_dir: Path, exc: Exception) -> None:
    """Raise an InputError naming the first result of ``reports`` (read from ``paths``) that a page of its own
    cannot print either, and the field formatting it stopped on (:class:`~atlasgen.io.field_reads.FieldReads`), on
    one line; all the files where a page of no results fails too (a field every report shares, such as the
    settings), with that field. Only a failed merge pays for these pages."""
    reads = FieldReads()
    shared = _page_error(reads.track(data), [], out_dir)
    if shared is None:
        rows = iter(data["results"])  # the merged rows, in the order the merge took them from each report
        for path, report in zip(paths, reports):
            for i, _ in enumerate(report["results"]):
                row = next(rows)
                reads = FieldReads()
                own = _page_error(data, [reads.track(row, f"results[{i}]")], out_dir)
                if own is not None:
                    what = f"{row['material']} on {row['scene']}"
                    culprit = reads.culprit()
                    if culprit is None:
                        raise InputError(f"{path.as_posix()}: field 'results[{i}]' ({what}) is not a result as "
                                         "atlasgen validate writes it, so the merged page cannot be written "
                                         f"({describe_failure(own)})") from None  # fmt: skip
                    raise FieldError(
                        path.as_posix(), culprit[0], expected_written(culprit[1], own, "atlasgen validate", what)
                    ) from None
        exc = shared or exc
    shown = ", ".join(p.as_posix() for p in paths)
    culprit = reads.culprit() if shared is not None else None
    if culprit is not None:
        raise FieldError(shown, culprit[0], expected_written(culprit[1], shared, "atlasgen validate")) from None
    raise InputError(f"{shown}: a field is not what atlasgen validate writes, so the merged page cannot "
                     f"be written ({describe_failure(exc)})") from None  # fmt: skip


def merge_validation_reports(sources, out_dir) -> dict:
    """Merge per-material validation reports into one ``index.html``, ``report.json`` and plot.

    Nothing is rendered: every figure is read from the sources' ``report.json``. Image
    paths are rewritten to point into the source folders, and each result gains
    ``"page"``: its own material's ``index.html``, relative to ``out_dir``.

    Parameters
    ----------
    sources
        Folders written by ``atlasgen validate -o`` (or their ``report.json`` files), in
        the order the merged page lists them.
    out_dir
        Folder for the merged ``index.html``, ``report.json`` and ``speed_error.png``;
        nothing else in it is touched, so the sources may live inside it.

    Returns
    -------
    dict
        ``{"html", "json", "files", "data"}``: the written paths and the merged report dict.

    Raises
    ------
    InputError
        No sources, a missing or malformed ``report.json``, sources validated with
        different settings (their figures would not be comparable), or one material and
        scene in two sources.
    OutputError
        The merged files cannot be written (nothing is written then).
    """
    out_dir = Path(out_dir)
    paths = report_json_paths(sources, "validation", "atlasgen validate")
    check_merge_output(paths, out_dir)
    reports = [read_validation_report(p) for p in paths]
    first = reports[0]
    rows, seen = [], {}
    for path, report in zip(paths, reports):
        if report["settings"] != first["settings"]:
            differing = sorted(k for k in set(first["settings"]) | set(report["settings"])
                               if first["settings"].get(k) != report["settings"].get(k))  # fmt: skip
            raise InputError(f"{path.as_posix()}: validated with other settings than {paths[0].as_posix()} "
                             f"({', '.join(differing)} differ); re-run both with the same options")  # fmt: skip
        for i, row in enumerate(report["results"]):
            key = (row["material"], row["scene"])
            if key in seen:
                raise InputError(f"{path.as_posix()}: material {key[0]!r} on scene {key[1]!r} is also in {seen[key].as_posix()}")
            seen[key] = path
            row = json.loads(json.dumps(row))  # a copy: the rebased paths must not leak back
            row["atlas_image"] = _rebased_image(row["atlas_image"], path, out_dir, f"results[{i}].atlas_image")
            for kind, ref in row["references"].items():
                ref["images"] = {k: _rebased_image(v, path, out_dir, f"results[{i}].references.{kind}.images.{k}")
                                 for k, v in ref["images"].items()}  # fmt: skip
            row["page"] = rebase_path("index.html", path.parent, out_dir)
            rows.append(row)
    environment = {key: _combined([r["environment"].get(key) for r in reports]) for key in first["environment"]}
    if "reference_cache" in environment:  # each from its report's folder: from the merged one's
        environment["reference_cache"] = _combined([rebase_path(r["environment"]["reference_cache"], p.parent, out_dir)
                                                    if isinstance(r["environment"].get("reference_cache"), str) else None
                                                    for p, r in zip(paths, reports)])  # fmt: skip
    data = {
        "atlas": _joined(rebase_path(r["atlas"], p.parent, out_dir) for p, r in zip(paths, reports)),
        "settings": first["settings"],
        "environment": environment,
        # The work the merged page stands for: the sum of the runs it is made of.
        "total_seconds": _total_seconds(paths, reports),
        "summary": None,  # below, where a hand-edited result that it cannot read is refused on one line
        "results": rows,
        "merged_from": [rebase_path(".", p.parent, out_dir) for p in paths],
    }
    try:
        data["summary"] = _summary(rows)
        files = _page_files(data, out_dir)
    except _MALFORMED as exc:
        # The fields the merge reads are checked above; this catches a hand edit deeper in a result
        # (a look's goal, a region's figures) that the page cannot print, still as one line.
        _refuse_malformed(data, paths, reports, out_dir, exc)
    refuse_another_report(out_dir, "validation")
    write_files_atomically(files, primary=out_dir / "report.json", whole=True)  # the Makefile's target
    return {"html": out_dir / "index.html", "json": out_dir / "report.json", "files": sorted(files), "data": data}


def write_validation(run, out_dir) -> dict:
    """Write ``index.html``, ``report.json``, the images and the plot, all-or-nothing.

    Returns ``{"html", "json", "files", "data"}``: the written paths and the report dict.
    """
    out_dir = Path(out_dir)
    files = build_report(run, out_dir)
    refuse_another_report(out_dir, "validation")
    write_files_atomically(files, primary=out_dir / "report.json", whole=True)  # the Makefile's target
    data = json.loads(files[out_dir / "report.json"])
    return {"html": out_dir / "index.html", "json": out_dir / "report.json", "files": sorted(files), "data": data}
