"""The library page shows validation figures only as those of the material they were measured on."""

from __future__ import annotations

import doctest
import json

import pytest

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.io.atlas import read_atlas
from atlasgen.materials.material import read_materials
from atlasgen.reports.library import write_library_report
from atlasgen.validate import identity
from atlasgen.validate.identity import atlas_identity, material_sha256

CLAY = 'type = "lambert"\ncolour = [0.7, 0.4, 0.2]\n'
SNOW = 'type = "lambert"\ncolour = [0.9, 0.9, 0.95]\n'


def _bake(tmp_path, write_material, **materials):
    for path in (tmp_path / "materials").glob("*.toml"):
        path.unlink()
    for name, text in materials.items():
        write_material(name, text)
    atlas = tmp_path / "atlas.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), atlas)
    return atlas


def _validation(tmp_path, atlas, psnr=None, with_identity=True):
    """A validation folder whose report.json holds a front/model result per material of ``atlas``, as validate writes
    it (its identity recorded, unless ``with_identity`` is false: a report of an older atlasgen)."""
    read = read_atlas(atlas)
    folder = tmp_path / "validation"
    folder.mkdir(exist_ok=True)
    rows = []
    for k, entry in enumerate(read.manifest.materials):
        row = {"material": entry.name, "scene": "front",
               "references": {"model": {"psnr_db": (psnr or {}).get(entry.name, 50.0 + k), "flip": 0.004,
                                        "speed_ratio": 2.0}}}  # fmt: skip
        if with_identity:
            row["atlas_identity"] = atlas_identity(read, entry)
        rows.append(row)
    (folder / "report.json").write_text(json.dumps({"results": rows}))
    return folder


def _cell(name, psnr):
    return f'<td class="l nowrap">front/model</td><td>{psnr:.1f}</td>'


def _page(tmp_path, atlas, folder):
    warnings = []
    index = write_library_report(atlas, tmp_path / "report", validation_dir=folder, physical=False, warn=warnings.append)
    return index.read_text(), warnings


@pytest.mark.slow
def test_figures_of_a_material_changed_since_are_not_shown_as_its_own(tmp_path, write_material):
    """The finding: report library printed figures measured on an older atlas (a material whose colour changed
    since) as current. They are dropped now, the material's row says "stale: not validated on this atlas" and
    why, one warning line names it; another material, unchanged, keeps its figures, as both do when only their
    slots move."""
    atlas = _bake(tmp_path, write_material, clay=CLAY, snow=SNOW)
    before = read_atlas(atlas)
    folder = _validation(tmp_path, atlas, {"clay": 61.25, "snow": 57.5})
    text, warnings = _page(tmp_path, atlas, folder)
    assert _cell("clay", 61.25) in text and _cell("snow", 57.5) in text and warnings == []
    assert 'class="stale"' not in text and 'class="unverified"' not in text

    # make validate validates each material once and re-assembles the atlas around it: a material added before
    # them moves their slices (id, first_slice), not what they are, so their figures stay current.
    atlas = _bake(tmp_path, write_material, aaa='type = "lambert"\ncolour = [0.1, 0.1, 0.1]\n', clay=CLAY, snow=SNOW)
    after = read_atlas(atlas)
    assert after.manifest_sha256 != before.manifest_sha256
    assert after.material("clay").first_slice != before.material("clay").first_slice
    assert material_sha256(after, after.material("clay")) == material_sha256(before, before.material("clay"))
    text, warnings = _page(tmp_path, atlas, folder)
    assert _cell("clay", 61.25) in text and _cell("snow", 57.5) in text and warnings == []

    atlas = _bake(tmp_path, write_material, clay=CLAY.replace("0.7, 0.4, 0.2", "0.2, 0.5, 0.3"), snow=SNOW)
    text, warnings = _page(tmp_path, atlas, folder)
    assert _cell("clay", 61.25) not in text and _cell("snow", 57.5) in text
    shown = (folder / "report.json").as_posix()
    assert ('<p class="stale"><b>stale</b>: not validated on this atlas: ' + shown + " measured another bake of it, "
            "and its material file has changed since: another content hash; re-run atlasgen validate</p>") in text  # fmt: skip
    assert warnings == [f"{shown}: the validation figures of 'clay' were measured on another bake of it than "
                        f"{atlas.with_suffix('.json').as_posix()}'s (its material file has changed since: another "
                        "content hash); not shown: re-run atlasgen validate"]  # fmt: skip


@pytest.mark.slow
def test_figures_of_a_material_baked_differently_from_the_same_file_are_stale(tmp_path, write_material):
    """Same material file, other texels (here an atlas baked linear instead of sRGB): the content hash alone would call
    the figures current."""
    atlas = _bake(tmp_path, write_material, clay=CLAY)
    folder = _validation(tmp_path, atlas, {"clay": 61.25})
    write_bake(bake_atlas(read_materials([tmp_path / "materials"]), linear=True), atlas)
    text, warnings = _page(tmp_path, atlas, folder)
    assert _cell("clay", 61.25) not in text
    assert len(warnings) == 1 and "it was baked differently since: its manifest entry or texels differ" in warnings[0]
    assert doctest.testmod(identity).failed == 0  # identity_problem's reasons, one per case


@pytest.mark.slow
def test_a_report_that_records_no_identity_is_marked_unverified(tmp_path, write_material):
    """A report.json of an older atlasgen cannot say what it measured: its figures are marked unverified, with one
    warning for the report naming its materials."""
    atlas = _bake(tmp_path, write_material, clay=CLAY, snow=SNOW)
    folder = _validation(tmp_path, atlas, {"clay": 61.25, "snow": 57.5}, with_identity=False)
    text, warnings = _page(tmp_path, atlas, folder)
    shown = (folder / "report.json").as_posix()
    assert text.count('<p class="unverified"><b>unverified</b>: ' + shown + " records no identity of the atlas it "
                      "validated (written by an older atlasgen), so these figures may be of another bake of it; re-run "
                      "atlasgen validate</p>") == 2  # fmt: skip
    assert warnings == [f"{shown}: records no identity of the atlas it validated (written by an older atlasgen), so the "
                        f"figures of clay, snow cannot be checked against {atlas.with_suffix('.json').as_posix()}; shown "
                        "as unverified: re-run atlasgen validate"]  # fmt: skip
