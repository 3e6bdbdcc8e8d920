"""The validation report's environment section: its rows from report.json, and the table they make."""

from __future__ import annotations

import re

from atlasgen.reports.environment import ENVIRONMENT_COLUMNS, environment_rows
from atlasgen.reports.html import render_page


def _psnr(x):
    return {"psnr_db": x, "linear_relative_rms": 0.01}


def _result(material, type_, scene, breakdown=None, psnr=40.5, floor=52.25):
    ref = {"psnr_db": psnr, "noise_floor_db": floor, "spp": 256}
    row = {"material": material, "type": type_, "scene": scene, "references": {"model": ref}}
    if breakdown is not None:
        row["environment_breakdown"] = breakdown
    return row


BREAKDOWN = {"total": _psnr(38.125), "sh_band_limit": _psnr(51.5), "split_sum": _psnr(38.75),
             "exact_vs_reference": _psnr(47.0), "gpu_vs_cpu": _psnr(None), "pixels": 1234}  # fmt: skip
DATA = {"results": [
    _result("clay", "lambert", "front"),  # not an environment scene: no row
    _result("clay", "lambert", "env-sky", BREAKDOWN),
    _result("gold", "separable", "env-sky", psnr=33.0, floor=None),
]}  # fmt: skip


def test_rows_hold_each_part_in_the_columns_order():
    clay, gold = environment_rows(DATA)
    assert (clay["material"], clay["scene"]) == ("clay", "env-sky")
    assert clay["figures"] == ["38.12", "51.50", "38.75", "47.00", "identical"]
    assert [key for _, key in ENVIRONMENT_COLUMNS] == ["total", "sh_band_limit", "split_sum", "exact_vs_reference", "gpu_vs_cpu"]
    assert clay["reference"] == "40.50 (noise floor 52.25 at 256 spp)" and clay["pixels"] == "1234" and not clay["note"]
    # A separable material: the reference comparison only, and why.
    assert gold["figures"] == [""] * len(ENVIRONMENT_COLUMNS) and gold["reference"] == "33.00"
    assert "not split by part" in gold["note"]


def test_the_section_shows_every_row_and_is_absent_without_environment_scenes():
    columns = [heading for heading, _ in ENVIRONMENT_COLUMNS]
    html = render_page("environment_breakdown.html.j2", environment_rows=environment_rows(DATA),
                       environment_columns=columns).decode()  # fmt: skip
    assert 'id="environment-breakdown"' in html
    cells = [re.sub(r"<[^>]+>", "", c) for c in re.findall(r"<td[^>]*>(.*?)</td>", html)]
    assert cells[: 4 + len(columns)] == ["clay", "lambert", "env-sky", "40.50 (noise floor 52.25 at 256 spp)",
                                          "38.12", "51.50", "38.75", "47.00", "identical"]  # fmt: skip
    assert all(f"<th>{c}</th>" in html for c in columns)
    empty = render_page("environment_breakdown.html.j2", environment_rows=environment_rows({"results": DATA["results"][:1]}),
                        environment_columns=columns).decode()  # fmt: skip
    assert "<table" not in empty
