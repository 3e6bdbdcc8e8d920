"""The validation report's environment-lighting section: each material's error under an environment, by part.

Per material and environment scene (``atlasgen validate --environment``) the row gives what was measured
(:func:`atlasgen.validate.environment.break_down_environment` and :func:`atlasgen.validate.run`'s
reference): the GPU atlas image against the Mitsuba reference; on the CPU, the renderer's two
approximations against the exact integral of the same decoded slice under the same environment image,
whole (``total``) and each alone: the SH band limit (l <= 4) of the diffuse term and the split sum
(Karis 2013) of the specular one; the exact integral against the reference (what neither approximation
explains: the reference's noise, the image's resolution); and the GPU against the CPU's approximation
(the renderer's own precision). PSNR in dB on the material's pixels, as every figure of the report.
A separable material is shaded by the split sum with its own directional albedo, and its error is not
split by part: its row has the reference comparison alone.
"""

from __future__ import annotations

import math

from atlasgen.validate.run import ENVIRONMENT_SCENES

__all__ = ["ENVIRONMENT_COLUMNS", "environment_rows"]

#: (heading, key in the breakdown) of the CPU figures, in the table's order.
ENVIRONMENT_COLUMNS = (
    ("CPU approximation vs exact integral", "total"),
    ("SH band limit alone", "sh_band_limit"),
    ("split sum alone", "split_sum"),
    ("exact integral vs reference", "exact_vs_reference"),
    ("GPU vs CPU approximation", "gpu_vs_cpu"),
)


def _db(x) -> str:
    """A PSNR as the table shows it: 2 decimals, "identical" for the infinite PSNR of equal images.

    >>> _db(41.237), _db(None), _db(float("inf"))
    ('41.24', 'identical', 'identical')
    """
    return "identical" if x is None or (isinstance(x, float) and math.isinf(x)) else f"{x:.2f}"


def environment_rows(data: dict) -> list[dict]:
    """The section's rows from a validation report's JSON dict (``report.json``), in the report's order.

    Each: ``material``, ``scene``, ``reference`` (the GPU atlas against the model reference: PSNR, and
    its noise floor and spp), ``figures`` (one text per :data:`ENVIRONMENT_COLUMNS`, empty where not
    measured), ``pixels`` (the material's pixels) and ``note``. Rows come from the environment scenes
    (:data:`atlasgen.validate.run.ENVIRONMENT_SCENES`) and from any result that has a breakdown.
    """
    rows = []
    for row in data.get("results", []):
        b = row.get("environment_breakdown")
        if b is None and row["scene"] not in ENVIRONMENT_SCENES:
            continue
        ref = row["references"].get("model", {})
        floor = ref.get("noise_floor_db")
        reference = _db(ref.get("psnr_db")) if ref else "n/a"
        if floor is not None:
            reference += f" (noise floor {_db(floor)} at {ref.get('spp')} spp)"
        figures = ["" if b is None or key not in b else _db(b[key]["psnr_db"]) for _, key in ENVIRONMENT_COLUMNS]
        rows.append({
            "material": row["material"], "type": row["type"], "scene": row["scene"], "reference": reference,
            "figures": figures, "pixels": "" if b is None else str(b["pixels"]),
            "note": "" if b is not None else "not split by part: the split sum with its own directional albedo",
        })  # fmt: skip
    return rows
