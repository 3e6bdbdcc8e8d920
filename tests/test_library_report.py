"""The whole-library HTML report opens with no broken image."""

import json

import pytest

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.errors import InputError
from atlasgen.materials.material import read_materials
from atlasgen.reports.library import write_library_report
from tests.html_links import PageLinks


def read_json(path):
    return json.loads(path.read_text())


def _clay_atlas(tmp_path, write_material):
    """tmp_path/atlas.dds of one lambert material, 'clay' (its timings file beside it)."""
    write_material("clay", 'type = "lambert"\n')
    atlas = tmp_path / "atlas.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), atlas)
    return atlas


@pytest.mark.slow
def test_every_referenced_image_exists(tmp_path, write_material):
    write_material("clay", 'type = "lambert"\ncolour = [0.7, 0.4, 0.2]\n')
    write_material("snow", 'type = "lambert"\nerror_budget = 0.01\n')
    write_material("gloss", 'type = "separable"\nsource = "ggx"\nalpha = 0.3\nerror_budget = 0.05\n')
    atlas = tmp_path / "build" / "atlas.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), atlas)
    index = write_library_report(atlas, tmp_path / "build" / "report", physical=False)
    parser = PageLinks(index.read_text())
    # What was skipped is said, not left out: the page claims nothing it did not measure.
    assert "Not measured on this page: it was written with <code>--no-physical</code>" in index.read_text()
    terms = next(m for m in read_json(atlas.with_suffix(".json"))["materials"] if m["name"] == "gloss")["terms"]
    # The library's cost plot, one cost plot and one preview per slice of each material.
    assert len(parser.images) == 1 + 3 + 2 + terms
    assert "cost-vs-error.png" in parser.images and "cost/gloss.png" in parser.images
    for src in parser.images + parser.links:
        assert (index.parent / src).is_file(), src
    text = index.read_text()
    assert "supersampling 1x" in text and "clay" in text
    gloss = next(m for m in read_json(atlas.with_suffix(".json"))["materials"] if m["name"] == "gloss")
    grid = gloss["sampling_grid"]
    assert f"separable, {terms} term(s), half_diff, sampled on {grid}x{grid} (budget 0.05)" in text
    # Every K the separable material could have been baked with, its cost from the shipped table;
    # the chosen K in bold.
    from atlasgen.separable.auto import read_lighting_cost

    table = read_lighting_cost()
    assert table.device in text
    for k in range(1, 9):
        assert f"separable:{k}" in text
    assert f"<b>separable:{terms}</b></td><td>{table.cost(f'separable:{terms}'):.3g}</td>" in text
    assert f"<b>lut</b></td><td>{table.cost('lut'):.3g}</td>" in text


@pytest.mark.slow
def test_a_separable_material_baked_as_one_lut_slice_gets_its_cost_from_the_table(tmp_path, write_material):
    """representation = "lut" records its one candidate without a cost: the page took c["cost"] (a KeyError, exit
    1); the cost is the shipped table's for a LUT slice."""
    from atlasgen.separable.auto import read_lighting_cost

    write_material("gloss", 'type = "separable"\nsource = "ggx"\nalpha = 0.3\nrepresentation = "lut"\n')
    atlas = tmp_path / "atlas.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), atlas)
    (candidate,) = read_json(atlas.with_suffix(".json"))["materials"][0]["representation"]["auto"]["candidates"]
    assert "cost" not in candidate
    index = write_library_report(atlas, tmp_path / "report", physical=False)
    assert f"{read_lighting_cost().costs['lut']:.3g}" in index.read_text()


def test_validation_figures_are_read_from_report_json(tmp_path, write_material):
    import json

    atlas = _clay_atlas(tmp_path, write_material)
    vdir = tmp_path / "validation"
    vdir.mkdir()
    (vdir / "index.html").write_text("<html></html>")
    (vdir / "report.json").write_text(
        json.dumps(
            {
                "results": [
                    {
                        "material": "clay",
                        "scene": "front",
                        "references": {"model": {"psnr_db": 61.25, "flip": 0.00425, "speed_ratio": 3.5}},
                    },
                ]
            }
        )
    )
    index = write_library_report(atlas, tmp_path / "report", validation_dir=vdir, physical=False)
    text = index.read_text()
    # One row per reference: PSNR (dB), FLIP, and how many times faster the atlas frame is.
    assert '<td class="l nowrap">front/model</td><td>61.2</td><td>0.0043</td><td>3.5x</td>' in text
    parser = PageLinks(text)
    assert "../validation/index.html" in parser.links


@pytest.mark.slow
def test_a_merged_validation_report_links_each_materials_own_page(tmp_path, write_material):
    write_material("clay", 'type = "lambert"\n')
    write_material("snow", 'type = "lambert"\n')
    atlas = tmp_path / "atlas.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), atlas)
    vdir = tmp_path / "validation"
    (vdir / "materials" / "clay").mkdir(parents=True)
    for page in (vdir / "index.html", vdir / "materials" / "clay" / "index.html"):
        page.write_text("<html></html>")
    model = {"psnr_db": 50.0, "flip": 0.005, "speed_ratio": 2.0, "linear_rmse": 0.001}
    (vdir / "report.json").write_text(json.dumps({"results": [
        {"material": "clay", "scene": s, "references": {"model": model}, "page": "materials/clay/index.html"}
        for s in ("front", "back")]}))  # fmt: skip
    index = write_library_report(atlas, tmp_path / "report", validation_dir=vdir, physical=False)
    parser = PageLinks(index.read_text())
    # One link per material that has its own page (both scenes share it); snow has none.
    assert sorted(parser.links) == ["../validation/index.html", "../validation/materials/clay/index.html"]
    assert not list((tmp_path / "report").rglob(".*.tmp"))


@pytest.mark.slow
def test_the_cli_prints_the_page_and_with_v_which_reports_it_found(tmp_path, write_material, monkeypatch):
    from click.testing import CliRunner

    from atlasgen.cli.main import app

    write_material("clay", 'type = "lambert"\n')
    atlas = tmp_path / "build" / "atlas.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), atlas)
    (tmp_path / "v").mkdir()
    (tmp_path / "v" / "report.json").write_text(json.dumps({"results": []}))
    # --separable left at its default (build/report/separable, from the working folder), which is used when present.
    monkeypatch.chdir(tmp_path)
    args = ["report", "library", "--atlas", str(atlas), "--validation", str(tmp_path / "v"), "-o", str(tmp_path / "r")]
    runner = CliRunner()
    assert runner.invoke(app, [*args, "-q"]).output == ""
    res = runner.invoke(app, [*args, "-v"])
    assert res.exit_code == 0, res.output
    assert res.stdout == f"{(tmp_path / 'r' / 'index.html').as_posix()}\n"
    assert res.stderr.splitlines() == [
        f"  validation report: {(tmp_path / 'v' / 'report.json').as_posix()} (used)",
        "  separable report: build/report/separable/index.html (absent)",
    ]


@pytest.mark.slow
def test_the_page_links_the_separable_reports_html_page(tmp_path, write_material):
    atlas = _clay_atlas(tmp_path, write_material)
    sep = tmp_path / "separable"
    sep.mkdir()
    (sep / "index.md").write_text("# text summary")
    assert (
        "../separable/index.html"
        not in PageLinks(write_library_report(atlas, tmp_path / "r", separable_dir=sep, physical=False).read_text()).links
    )
    (sep / "index.html").write_text("<html></html>")
    links = PageLinks(write_library_report(atlas, tmp_path / "r", separable_dir=sep, physical=False).read_text()).links
    assert links == ["../separable/index.html"]
    # A validation report's folder given as --separable was linked as the separable report, without a word.
    (sep / "report.json").write_text('{"results": [], "settings": {}}')
    with pytest.raises(InputError) as info:
        write_library_report(atlas, tmp_path / "r", separable_dir=sep, physical=False)
    assert str(info.value) == (f"{(sep / 'report.json').as_posix()}: the separable report (--separable) holds a "
                               "validation report; expected the folder atlasgen report separable -o wrote")  # fmt: skip


@pytest.mark.slow
def test_pareto_charts_against_the_physical_reference(tmp_path, write_material, monkeypatch):
    """One chart per material with a projectable reference and one over the library, every candidate
    listed with its SE, one line for a material without such a reference; same inputs, same bytes."""
    from atlasgen.models import get_model
    from atlasgen.models.physical_error import physical_candidates
    from atlasgen.reports import pareto

    write_material("sheen", 'type = "separable"\nsource = "blinn_phong"\nexponent = 4.0\nspecular = [0.2, 0.2, 0.2]\n'
                            'diffuse = [0.5, 0.35, 0.25]\nterms = 2\n')  # fmt: skip
    write_material("metal", 'type = "separable"\nsource = "ggx"\nalpha = 0.5\nterms = 1\n')
    write_material("hero", 'type = "toon"\n')
    atlas = tmp_path / "atlas.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), atlas)
    index = write_library_report(atlas, tmp_path / "r", jobs=1)
    text = index.read_text()
    parser = PageLinks(text)
    assert "pareto.png" in parser.images and "pareto/sheen.png" in parser.images
    assert "pareto/hero.png" not in parser.images
    for src in parser.images + parser.links:
        assert (index.parent / src).is_file(), src
    entry = next(m for m in read_json(atlas.with_suffix(".json"))["materials"] if m["name"] == "sheen")
    expected = physical_candidates(get_model("separable"), entry["params"])
    assert len(expected["candidates"]) == 14  # six fitted LUTs, K = 1..8
    for c in expected["candidates"]:
        assert f"{c['representation']}" in text
        assert f"<td>{c['error']:.4g}</td><td>{c['error_se']:.2g}</td>" in text
    assert "<b>separable:2</b> (baked)" in text
    from atlasgen.separable.auto import read_lighting_cost

    assert read_lighting_cost().device in text
    assert "<li>hero: model &#39;toon&#39; has no physical reference</li>" in text
    names = ("pareto.png", "pareto/sheen.png", "pareto/sheen.json", "pareto/metal.png", "pareto/hero.json", "index.html")
    first = {name: (tmp_path / "r" / name).read_bytes() for name in names}
    # Computed afresh elsewhere, in two processes: byte for byte the same.
    monkeypatch.setattr(pareto, "_MEMO", {})
    write_library_report(atlas, tmp_path / "r2", jobs=2)
    assert {name: (tmp_path / "r2" / name).read_bytes() for name in names} == first
    # Again in the same folder: from the cache (nothing recomputed), the same bytes.
    monkeypatch.setattr(pareto, "_MEMO", {})
    monkeypatch.setattr(pareto, "physical_candidates", lambda *a, **k: pytest.fail("recomputed a cached material"))
    write_library_report(atlas, tmp_path / "r", jobs=1)
    assert {name: (tmp_path / "r" / name).read_bytes() for name in names} == first


def _outputs(folder) -> dict:
    """``{path: bytes}`` of a report's files as a reader sees them, the set's store (a dot folder) left out."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in folder.rglob("*")
            if p.is_file() and not any(part.startswith(".") for part in p.relative_to(folder).parts)}  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("damage", ["a cost made null", "not JSON", "no key"])
def test_a_damaged_pareto_cache_entry_is_computed_again_and_said(tmp_path, write_material, monkeypatch, damage):
    """A cache file edited by hand kept its key: a cost made null ended in an internal error (exit 1), and a number
    changed was shown as measured."""
    from atlasgen.reports import pareto

    write_material("metal", 'type = "separable"\nsource = "ggx"\nalpha = 0.5\nterms = 1\n')
    atlas = tmp_path / "atlas.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), atlas)
    write_library_report(atlas, tmp_path / "r", jobs=1)
    cached = tmp_path / "r" / "pareto" / "metal.json"
    first = _outputs(tmp_path / "r")
    data = read_json(cached)
    if damage == "a cost made null":
        data["candidates"][1]["cost"] = None
        cached.write_text(json.dumps(data))
    elif damage == "not JSON":
        cached.write_text("{")
    else:
        del data["key"]
        cached.write_text(json.dumps(data))
    monkeypatch.setattr(pareto, "_MEMO", {})
    said = []
    write_library_report(atlas, tmp_path / "r", jobs=1, warn=said.append)
    reason = "not JSON" if damage == "not JSON" else "its content is not what it records"
    assert said == [f"{cached.as_posix()}: a damaged cache entry ({reason}); computed again"]
    assert _outputs(tmp_path / "r") == first


@pytest.mark.slow
def test_thin_sheet_and_thin_film_materials_get_pareto_charts(tmp_path, write_material):
    """leaf (thin sheet) and beetle-shell (spectral thin film) are measured against their models'
    NumPy references and charted; skin (a volume) is named, LUT only, with its reason."""
    from pathlib import Path

    from atlasgen.io.manifest import read_manifest
    from atlasgen.reports.pareto import library_candidates

    shipped = Path(__file__).resolve().parents[1] / "materials"
    for name in ("leaf", "beetle-shell"):
        write_material(name, (shipped / f"{name}.toml").read_text())
    write_material("skin", 'type = "sss"\n')
    atlas = tmp_path / "atlas.dds"
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), atlas)
    results = library_candidates(read_manifest(atlas.with_suffix(".json")).materials, jobs=1)
    assert results["leaf"]["sphere"] and not results["beetle-shell"]["sphere"]
    assert any(c["representation"] == "separable:8" for c in results["beetle-shell"]["candidates"])
    index = write_library_report(atlas, tmp_path / "r", jobs=1)
    parser = PageLinks(index.read_text())
    assert {"pareto.png", "pareto/leaf.png", "pareto/beetle-shell.png"} <= set(parser.images)
    assert "pareto/skin.png" not in parser.images
    text = index.read_text()
    assert "<li>skin: LUT only, no chart: the reference is light transport" in text
    assert "No separable candidate: no separable source holds a thin sheet" in text
    assert "the error covers l over the whole sphere" in text


@pytest.mark.slow
def test_odd_validation_and_timings_files_are_refused_on_one_line(tmp_path, write_material):
    """A folder where a file belongs was an internal error (IsADirectoryError), so was a page that is no path;
    a report that is a list and timings that are a string named the wrong type; a negative bake time showed."""
    from atlasgen.errors import FieldError, InputError

    atlas = _clay_atlas(tmp_path, write_material)
    timings = tmp_path / "atlas.timings.json"
    good_timings = timings.read_text()
    vdir = tmp_path / "validation"
    vdir.mkdir()

    def refusal(**kwargs) -> str:
        with pytest.raises(InputError) as info:
            write_library_report(atlas, tmp_path / "report", physical=False, **kwargs)
        assert "\n" not in str(info.value) and not (tmp_path / "report").exists()
        return str(info.value)

    (vdir / "report.json").mkdir()
    assert refusal(validation_dir=vdir) == f"{(vdir / 'report.json').as_posix()}: expected a regular file, got a folder"
    (vdir / "report.json").rmdir()
    (vdir / "report.json").write_text("[]")
    assert refusal(validation_dir=vdir).endswith("expected a validation report (a JSON object), got list")
    # null and {} were read as no validation at all, and a file given as the folder as a folder without one.
    (vdir / "report.json").write_text("null")
    assert refusal(validation_dir=vdir).endswith("expected a validation report (a JSON object), got null")
    (vdir / "report.json").write_text("{}")
    assert refusal(validation_dir=vdir).endswith(
        "field 'results': missing; expected the list of results atlasgen validate writes"
    )
    assert refusal(validation_dir=timings) == (f"{timings.as_posix()}: the validation report (--validation) is a file; "
                                               "expected the folder atlasgen validate -o wrote")  # fmt: skip
    # --separable's was linked from the page as the separable report's folder.
    assert refusal(separable_dir=timings) == (f"{timings.as_posix()}: the separable report (--separable) is a file; "
                                              "expected the folder atlasgen report separable -o wrote")  # fmt: skip
    row = {"material": "clay", "scene": "front", "references": {}, "page": 5}
    (vdir / "report.json").write_text(json.dumps({"results": [row]}))
    assert "field 'results[0].page': expected a page path as atlasgen validate writes it, got 5" in refusal(validation_dir=vdir)
    # A hostile sweep's: a second result of a material on a scene (shown as two rows, one edited), a page outside.
    (vdir / "report.json").write_text(json.dumps({"results": [{**row, "page": "materials/clay/index.html"}] * 2}))
    assert ("field 'results[1]': expected one result per material and scene, got a second of material 'clay' on scene "
            "'front' (results[0])") in refusal(validation_dir=vdir)  # fmt: skip
    (vdir / "report.json").write_text(json.dumps({"results": [{**row, "page": "/etc/passwd"}]}))
    assert "field 'results[0].page': expected a page inside the report's folder" in refusal(validation_dir=vdir)
    (vdir / "report.json").write_text(json.dumps({"results": [{**row, "page": "../../x.html"}]}))
    assert "field 'results[0].page': expected a page inside the report's folder" in refusal(validation_dir=vdir)
    (vdir / "report.json").unlink()
    # null, [] and a material's timings of 0 were read as none: every bake time '–', without a word.
    for text, expected in (("null", "expected a bake's timings (a JSON object), got null"),
                           ("[]", "expected a bake's timings (a JSON object), got list"),
                           ('{"materials": {"clay": 0}}', "field 'materials.clay': expected an object of timings, got 0")):  # fmt: skip
        timings.write_text(text)
        assert refusal().endswith(expected)
    timings.unlink()
    timings.mkdir()
    assert refusal() == f"{timings.as_posix()}: expected a regular file, got a folder"
    timings.rmdir()
    timings.write_text('"x"')
    assert refusal().endswith("expected a bake's timings (a JSON object), got str")
    data = json.loads(good_timings)
    data["materials"]["clay"]["bake_s"] = -5
    timings.write_text(json.dumps(data))
    with pytest.raises(FieldError, match=r"field 'materials.clay.bake_s': expected a number >= 0, got -5"):
        write_library_report(atlas, tmp_path / "report", physical=False)


@pytest.mark.slow
@pytest.mark.parametrize("which", ["validation_dir", "separable_dir"])
def test_the_page_may_not_be_written_into_a_report_it_reads(tmp_path, write_material, which):
    """-o R/sep --separable R/sep replaced the separable report's index.html with the library page: two sets mixed."""
    from atlasgen.errors import OutputError

    atlas = _clay_atlas(tmp_path, write_material)
    theirs = tmp_path / "theirs"
    theirs.mkdir()
    (theirs / "index.html").write_text("<html>theirs</html>")
    with pytest.raises(OutputError, match=r"theirs: the report folder \(-o\) is the .* report \(--.*\)'s folder"):
        write_library_report(atlas, tmp_path / "." / "theirs", physical=False, **{which: theirs})
    assert (theirs / "index.html").read_text() == "<html>theirs</html>"
    # A hostile sweep's: a material's page folder of theirs (copied as plain files, so no output set guarded it).
    page = theirs / "materials" / "clay" / "index.html"
    page.parent.mkdir(parents=True)
    page.write_text("<html>their page</html>")
    with pytest.raises(OutputError, match=r"clay: the report folder \(-o\) is inside the .* report \(--.*\)'s folder"):
        write_library_report(atlas, page.parent, physical=False, **{which: theirs})
    assert page.read_text() == "<html>their page</html>"


def test_an_auto_choice_s_candidates_are_told_apart_and_only_the_baked_one_is_chosen():
    """A first user read mx_car_paint's `separable:8` twice in its cost table (0.211 and 0.0903, the SVD and the
    NMF candidate), both bold as chosen, under a caption that called them the manifest's error (0.0282)."""
    from types import SimpleNamespace

    from atlasgen.reports.library import _runtime_candidates

    kind = "estimated relative log RMS of f cos, 8-bit, {}"
    auto = {"chosen": "separable:8", "error_measure": "relative_log_rms", "candidates": [
        {"representation": "lut", "cost": 11.2, "error": 0.17, "error_kind": "relative log RMS of f cos, one 8-bit slice"},
        {"representation": "separable:8", "cost": 67.1, "error": 0.211, "factorization": "svd", "error_kind": kind.format("SVD")},
        {"representation": "separable:8", "cost": 67.1, "error": 0.0903, "factorization": "nmf", "error_kind": kind.format("NMF")},
    ]}  # fmt: skip
    entry = SimpleNamespace(representation=SimpleNamespace(auto=auto), factors=SimpleNamespace(factorization="nmf", terms=8))
    rows = _runtime_candidates(entry, table=None)
    assert [r["representation"] for r in rows] == ["lut", "separable:8 (svd)", "separable:8 (nmf)"]
    assert [r["chosen"] for r in rows] == [False, False, True]
    assert rows[2]["measure"] == kind.format("NMF") and rows[2]["error"] == 0.0903


@pytest.mark.slow  # two pages with their plots: about 2 s of CPU, at the fast loop's budget
def test_the_page_is_the_same_bytes_from_whatever_folder_it_is_written(tmp_path, write_material, monkeypatch):
    """Its heading gave the atlas path as typed: run from build/ ("atlas.dds") or the root ("build/atlas.dds"),
    the same inputs wrote two pages. It is now given from the page, as its links are."""
    atlas = _clay_atlas(tmp_path, write_material)
    (tmp_path / "sub").mkdir()
    pages = []
    for cwd, given in ((tmp_path, "atlas.dds"), (tmp_path / "sub", "../atlas.dds")):
        monkeypatch.chdir(cwd)
        out = tmp_path / f"report-{len(pages)}"
        pages.append(write_library_report(given, out, physical=False).read_bytes())
    assert pages[0] == pages[1]
    assert b"<h1>Material library: ../atlas.dds</h1>" in pages[0]
    assert atlas.exists()
