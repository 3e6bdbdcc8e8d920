"""``representation = "auto"``: the cheapest representation, in run-time cost, that meets an error budget.

Cost is the lighting pass's time per pixel per light, from a table measured by ``make bench``
(``bench/cost.py``) and shipped as ``atlasgen/data/lighting_cost.json`` with the device named:
a bake reads the table, never a clock, so the same inputs give the same manifest.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import lru_cache

from atlasgen.errors import AtlasgenError
from atlasgen.io.package_data import package_data_path

__all__ = ["LightingCost", "read_lighting_cost", "choose_representation", "cost_key", "COST_FILE"]

#: The shipped cost table, under ``atlasgen/data``.
COST_FILE = "lighting_cost.json"


def cost_key(kind: str, detail=None) -> str:
    """The cost table's key of a representation: ``lut``, ``analytic:ggx``, ``separable:4``."""
    return kind if detail is None else f"{kind}:{detail}"


@dataclass(frozen=True)
class LightingCost:
    """A cost table: ``costs[key]`` in ``unit`` (ns per pixel per light) on ``device``."""

    device: str
    unit: str
    costs: dict

    def cost(self, key: str) -> float:
        try:
            return float(self.costs[key])
        except KeyError:
            raise AtlasgenError(f"atlasgen/data/{COST_FILE}: no cost for {key!r}; rerun `make bench`") from None


@lru_cache(maxsize=1)
def read_lighting_cost() -> LightingCost:
    """The shipped cost table (``atlasgen/data/lighting_cost.json``)."""
    path = package_data_path(COST_FILE)
    data = json.loads(path.read_text(encoding="utf-8"))
    return LightingCost(str(data["device"]), str(data["unit"]), dict(data["costs"]))


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)


def choose_representation(candidates: list[dict], budget: float) -> tuple[int, list[dict]]:
    """Index of the cheapest candidate whose error meets ``budget``, and the candidates annotated.

    ``candidates`` are ``{"representation", "cost", "error", ...}``. Among those with
    ``error <= budget`` the lowest cost wins (ties: lower error, then list order); when
    none meets it the lowest error wins (ties: lower cost). So a tighter budget never
    yields a larger error: the choice at budget b1 < b2 either meets b2 too, and then
    the b2 choice is at least as cheap and errs at most b2 but the b1 choice errs at most b1 <
    anything outside b1; or it is the overall least error.
    """
    if not candidates:
        raise ValueError("no candidate representations")
    annotated = [{**c, "meets_budget": bool(_finite(c["error"]) and c["error"] <= budget)} for c in candidates]
    meeting = [i for i, c in enumerate(annotated) if c["meets_budget"]]
    if meeting:
        best = min(meeting, key=lambda i: (annotated[i]["cost"], annotated[i]["error"], i))
    else:
        best = min(range(len(annotated)), key=lambda i: (annotated[i]["error"] if _finite(annotated[i]["error"]) else math.inf,
                                                         annotated[i]["cost"], i))  # fmt: skip
    return best, annotated
