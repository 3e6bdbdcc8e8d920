"""``atlasgen report`` through click: an atlas without its manifest, and validation figures of another bake."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.cli.main import app
from atlasgen.io.atlas import read_atlas
from atlasgen.materials.material import read_materials
from atlasgen.validate.identity import atlas_identity

GLOSS = 'type = "separable"\nsource = "ggx"\nalpha = 0.3\nterms = 2\n'


def _atlas(tmp_path, write_material, **materials):
    for name, text in materials.items():
        write_material(name, text)
    atlas = tmp_path / "X.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), atlas)
    return atlas


@pytest.mark.slow
def test_report_separable_refuses_an_atlas_without_its_manifest(tmp_path, write_material):
    """Without X.json it exited 0 with "not in atlas" in the table (only report.json's atlas.missing said why), while
    an empty X.json was refused: both are exit 3 now, one line naming the atlas, and nothing is written."""
    atlas = _atlas(tmp_path, write_material, gloss=GLOSS)
    out = tmp_path / "sep"
    args = ["report", "separable", "-m", str(tmp_path / "materials"), "--atlas", str(atlas), "-o", str(out), "--repeats", "1"]
    runner = CliRunner()
    atlas.with_suffix(".json").unlink()
    result = runner.invoke(app, args)
    assert result.exit_code == 3, result.output
    assert result.output == (f"atlasgen: error: {atlas.as_posix()}: no manifest beside the atlas (expected "
                             f"{atlas.with_suffix('.json').as_posix()}); re-run atlasgen bake -o {atlas.as_posix()}\n")  # fmt: skip
    assert not out.exists()
    atlas.with_suffix(".json").write_text("")  # as an empty manifest already was
    result = runner.invoke(app, args)
    assert result.exit_code == 3 and result.output.count("\n") == 1 and result.output.startswith("atlasgen: error: ")
    assert not out.exists()


@pytest.mark.slow
def test_report_library_warns_of_validation_figures_measured_on_another_bake(tmp_path, write_material):
    clay = 'type = "lambert"\ncolour = [0.7, 0.4, 0.2]\n'
    atlas = _atlas(tmp_path, write_material, clay=clay)
    read = read_atlas(atlas)
    folder = tmp_path / "validation"
    folder.mkdir()
    row = {"material": "clay", "scene": "front", "references": {"model": {"psnr_db": 61.25, "flip": 0.004}},
           "atlas_identity": atlas_identity(read, read.material("clay"))}  # fmt: skip
    (folder / "report.json").write_text(json.dumps({"results": [row]}))
    args = ["report", "library", "--atlas", str(atlas), "--validation", str(folder), "--no-physical", "-q"]
    runner = CliRunner()
    current = runner.invoke(app, [*args, "-o", str(tmp_path / "r1")])
    assert current.exit_code == 0 and current.output == ""
    assert "<td>61.2</td>" in (tmp_path / "r1" / "index.html").read_text()

    _atlas(tmp_path, write_material, clay=clay.replace("0.7", "0.3"))
    stale = runner.invoke(app, [*args, "-o", str(tmp_path / "r2")])
    assert stale.exit_code == 0, stale.output
    assert stale.stdout == ""
    assert stale.stderr == (f"atlasgen: warning: {(folder / 'report.json').as_posix()}: the validation figures of 'clay' "
                            f"were measured on another bake of it than {atlas.with_suffix('.json').as_posix()}'s (its "
                            "material file has changed since: another content hash); not shown: re-run atlasgen validate\n")  # fmt: skip
    page = (tmp_path / "r2" / "index.html").read_text()
    assert "<td>61.2</td>" not in page and '<p class="stale"><b>stale</b>: not validated on this atlas' in page


@pytest.mark.slow
def test_report_library_names_with_v_the_figures_of_materials_the_atlas_lacks(tmp_path, write_material):
    """A report of a wider library (a scene atlas's page over the library's report) had the extra materials' figures
    dropped without a word even under -v; -v now names them, and the run stays quiet without it: a subset is no fault."""
    clay = 'type = "lambert"\ncolour = [0.7, 0.4, 0.2]\n'
    atlas = _atlas(tmp_path, write_material, clay=clay)
    read = read_atlas(atlas)
    folder = tmp_path / "validation"
    folder.mkdir()
    rows = [{"material": name, "scene": scene, "references": {"model": {"psnr_db": 61.25, "flip": 0.004}},
             "atlas_identity": atlas_identity(read, read.material("clay"))}
            for name, scene in (("clay", "front"), ("snow", "front"), ("ink", "front"), ("snow", "back"))]  # fmt: skip
    (folder / "report.json").write_text(json.dumps({"results": rows}))
    args = ["report", "library", "--atlas", str(atlas), "--validation", str(folder), "--no-physical"]
    runner = CliRunner()
    for flag in ("-q", None):
        plain = runner.invoke(app, [*args, "-o", str(tmp_path / "r"), *([flag] if flag else [])])
        assert plain.exit_code == 0 and plain.stderr == "", plain.output
    verbose = runner.invoke(app, [*args, "-o", str(tmp_path / "r"), "-v"])
    assert verbose.exit_code == 0, verbose.output
    assert verbose.stderr.splitlines()[-1] == (f"  {(folder / 'report.json').as_posix()}: left out the figures of 2 materials "
                                               f"{atlas.with_suffix('.json').as_posix()} does not hold: snow, ink")  # fmt: skip
    assert "<td>61.2</td>" in (tmp_path / "r" / "index.html").read_text()


@pytest.mark.parametrize(
    ("option", "report", "writer"),
    [("--validation", "report.json", "atlasgen validate"), ("--separable", "index.html", "atlasgen report separable")],
)
def test_report_library_refuses_a_named_report_folder_without_its_report(tmp_path, option, report, writer):
    """A mistyped --validation wrote a page with no validation figures and exit 0; named, a folder must hold its
    report (left at its default, build/validation is used when present, as make report's first run needs)."""
    typo = tmp_path / "validaton"
    res = CliRunner().invoke(app, ["report", "library", "--atlas", str(tmp_path / "X.dds"), option, str(typo),
                                   "-o", str(tmp_path / "report"), "--no-physical"])  # fmt: skip
    assert res.exit_code == 3, res.output
    assert res.stderr == (f"atlasgen: error: {typo.as_posix()}: no {report} in the {option} folder; expected a folder "
                          f"{writer} wrote, or no {option}\n")  # fmt: skip
    assert not (tmp_path / "report").exists()


def test_report_library_into_a_folder_of_another_command_s_set_is_refused_before_any_work(tmp_path, write_material):
    """A hostile sweep: an atlas baked as ix/index.dds, then `report library -o ix` (its page ix/index.html: the same
    set, .index.atlasgen) removed the atlas and every file beside it, exit 0."""
    write_material("clay", 'type = "lambert"\n')
    atlas = tmp_path / "ix" / "index.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), atlas)
    before = sorted(p.name for p in atlas.parent.iterdir())
    res = CliRunner().invoke(app, ["report", "library", "--atlas", str(atlas), "-o", str(atlas.parent), "--no-physical"])
    assert res.exit_code == 4 and res.stderr == (
        f"atlasgen: error: {atlas.as_posix()}: written by `atlasgen bake -o index.dds/.ktx2` into the output set "
        "(.index.atlasgen) this command replaces whole; expected a folder of its own for each command's outputs; nothing "
        "was replaced\n"), res.output  # fmt: skip
    assert sorted(p.name for p in atlas.parent.iterdir()) == before and atlas.is_file()


@pytest.mark.parametrize("report", [None, "[]"])
def test_report_library_refuses_a_separable_folder_that_holds_no_separable_report(tmp_path, report):
    """Hostile sweeps: another library page (an index.html, no report.json) given as --separable was linked from the
    page as the separable factorisation report, exit 0; so was a folder whose report.json studies nothing."""
    other = tmp_path / "rep"
    other.mkdir()
    (other / "index.html").write_text("<html>a library page</html>")
    if report is not None:
        (other / "report.json").write_text(report)
    res = CliRunner().invoke(app, ["report", "library", "--atlas", str(tmp_path / "X.dds"), "--separable", str(other),
                                   "-o", str(tmp_path / "report"), "--no-physical"])  # fmt: skip
    assert res.exit_code == 3 and res.stderr == (
        f"atlasgen: error: {(other / 'report.json').as_posix()}: the --separable folder holds no separable report; "
        "expected a folder atlasgen report separable wrote, or no --separable\n"), res.output  # fmt: skip
    assert not (tmp_path / "report").exists()


def test_report_separable_refuses_a_material_file_lying_in_its_folder(tmp_path):
    """A hostile sweep: a separable material copied as s2/index.md and studied into -o s2 was replaced by the report's
    Markdown summary, exit 0."""
    folder = tmp_path / "s2"
    folder.mkdir()
    material = folder / "index.md"
    material.write_text(GLOSS)
    res = CliRunner().invoke(app, ["report", "separable", "-m", str(material), "--repeats", "1", "-o", str(folder)])
    assert res.exit_code == 4 and res.stderr == (
        f"atlasgen: error: {material.as_posix()}: the material file of 'index' lies in the report folder (-o), "
        f"{folder.as_posix()}, whose files the report replaces; expected the inputs outside it\n"), res.output  # fmt: skip
    assert material.read_text() == GLOSS and sorted(p.name for p in folder.iterdir()) == ["index.md"]
