"""Merging per-material validation reports: the same entries as one run, images in the per-material folders."""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import replace
from pathlib import Path

import pytest

from atlasgen.errors import InputError, OutputError
from tests.html_links import PageLinks


def _split(run):
    """One ValidationRun per material, as ``make validate``'s per-material jobs produce."""
    materials = list(dict.fromkeys(r.material for r in run.runs))
    return {m: replace(run, runs=[r for r in run.runs if r.material == m], seconds=run.seconds / len(materials))
            for m in materials}  # fmt: skip


@pytest.fixture(scope="module")
def merged(validation_run, tmp_path_factory):
    from atlasgen.reports.validation import merge_validation_reports, write_validation

    out = tmp_path_factory.mktemp("merge") / "validation"
    parts = _split(validation_run)
    for material, part in parts.items():
        write_validation(part, out / "materials" / material)
    return out, parts, merge_validation_reports([out / "materials" / m for m in parts], out)


def test_merged_entries_equal_a_single_runs(merged, validation_run):
    from atlasgen.reports.validation import report_dict

    out, parts, written = merged
    single = json.loads(json.dumps(report_dict(validation_run)))  # as report.json holds it
    data = json.loads((out / "report.json").read_text())
    assert data == written["data"]
    assert len(data["results"]) == len(single["results"])
    by_key = {(r["material"], r["scene"]): r for r in data["results"]}
    for expected in single["results"]:
        got = dict(by_key[(expected["material"], expected["scene"])])
        folder = f"materials/{expected['material']}"
        assert got.pop("page") == f"{folder}/index.html"
        # Only the image paths differ: they point into the material's own folder.
        assert got.pop("atlas_image") == f"{folder}/{expected.pop('atlas_image')}"
        for kind, ref in expected["references"].items():
            images = got["references"][kind].pop("images")
            assert images == {k: f"{folder}/{v}" for k, v in ref.pop("images").items()}
        assert got == expected
    assert data["summary"] == single["summary"]
    assert data["settings"] == single["settings"]
    assert data["total_seconds"] == pytest.approx(sum(p.seconds for p in parts.values()))
    assert data["merged_from"] == [f"materials/{m}" for m in parts]
    # Each report names the atlas from its own folder; the merged one from its own, as its links are.
    assert data["atlas"] == Path(os.path.relpath(validation_run.atlas, out)).as_posix()


def test_every_image_and_page_the_merged_html_links_exists(merged):
    out, parts, _ = merged
    text = (out / "index.html").read_text(encoding="utf-8")
    parser = PageLinks(text)
    assert "speed_error.png" in parser.images
    assert (out / "speed_error.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for src in parser.images:
        assert not Path(src).is_absolute() and ".." not in Path(src).parts
        assert (out / src).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", src
    # Every result's images live in its material's folder, and its own page is linked.
    assert {p for p in parser.images if p != "speed_error.png"} <= {
        p for m in parts for p in (str(q.relative_to(out)) for q in (out / "materials" / m / "images").iterdir())
    }
    pages = {link for link in parser.links if link.endswith(".html")}
    assert sorted(pages) == sorted(f"materials/{m}/index.html" for m in parts)
    # The other links: a zoomable image's own file, or a section of the page (the contents).
    for link in set(parser.links) - pages:
        if link.startswith("#"):
            assert f'id="{link[1:]}"' in text, link
        else:
            assert link in parser.images, link
    assert {f"#material-{m}" for m in parts} <= set(parser.links)
    assert f"{len(parts)} per-material runs" in text


def test_the_plot_is_made_from_report_dicts(validation_run):
    from atlasgen.reports.validation import plot_speed_error, report_dict

    data = report_dict(validation_run)
    assert plot_speed_error(data)[:8] == b"\x89PNG\r\n\x1a\n"
    # A ratio the run could not measure (None in the JSON) is left out, not plotted as 0.
    for row in data["results"]:
        for ref in row["references"].values():
            ref["speed_ratio"] = None
    assert plot_speed_error(data)[:8] == b"\x89PNG\r\n\x1a\n"


def test_summary_line_reads_the_merged_goals(merged):
    from atlasgen.reports.validation import summary_line

    out, _, written = merged
    s = written["data"]["summary"]
    line = summary_line(written["data"], written["html"])
    assert line.startswith(f"{(out / 'index.html').as_posix()} ({len(written['data']['results'])} material/scene results, ")
    assert f"{s['lut_meeting_goals']}/{s['lut_results']} LUT results meet the storage goals" in line


def test_reports_with_other_settings_or_the_same_material_twice_are_refused(merged, tmp_path):
    from atlasgen.reports.validation import merge_validation_reports

    out, parts, _ = merged
    first, second = (out / "materials" / m for m in list(parts)[:2])
    other = tmp_path / "other"
    other.mkdir()
    data = json.loads((second / "report.json").read_text())
    data["settings"]["spp"] += 3
    (other / "report.json").write_text(json.dumps(data))
    with pytest.raises(InputError, match=r"other/report.json: validated with other settings .*\(spp differ\)"):
        merge_validation_reports([first, other], tmp_path / "merged")
    with pytest.raises(InputError, match="is also in"):
        merge_validation_reports([first, first / "report.json"], tmp_path / "merged")
    with pytest.raises(InputError, match="nowhere/report.json: no such validation report"):
        merge_validation_reports([first, tmp_path / "nowhere"], tmp_path / "merged")
    (other / "report.json").write_text("[1, 2]")
    with pytest.raises(InputError, match="not a validation report"):
        merge_validation_reports([other], tmp_path / "merged")
    with pytest.raises(InputError, match="no validation reports to merge"):
        merge_validation_reports([], tmp_path / "merged")
    assert not (tmp_path / "merged").exists()


@pytest.mark.parametrize("named", ["folder", "report.json"])
def test_a_merge_into_one_of_its_sources_is_refused_and_changes_nothing(merged, tmp_path, named):
    """``validate --merge A B -o B`` replaced B's own report with the merge, so a later merge of B counted
    A's materials twice: the merged report may not replace a source's (exit 4, before anything is written)."""
    from atlasgen.reports.validation import merge_validation_reports

    out, parts, _ = merged
    first, second = (tmp_path / m for m in list(parts)[:2])
    for folder in (first, second):
        shutil.copytree(out / "materials" / folder.name, folder)
    before = {p: p.read_bytes() for p in second.rglob("*") if p.is_file()}
    source = second if named == "folder" else second / "report.json"
    with pytest.raises(OutputError, match=r"report.json: the merged report would overwrite a --merge source"):
        merge_validation_reports([first, source], second / "." if named == "folder" else second)
    assert {p: p.read_bytes() for p in second.rglob("*") if p.is_file()} == before


def _edited(merged, tmp_path, change, material=None) -> Path:
    """A copy of one material's report.json (the first's, or ``material``'s) with ``change`` applied to its parsed JSON."""
    out, parts, _ = merged
    source = out / "materials" / (material or next(iter(parts)))
    data = json.loads((source / "report.json").read_text())
    change(data)
    folder = tmp_path / "edited"
    shutil.copytree(source, folder, symlinks=False)  # its images too: a merge links only images that are there
    (folder / "report.json").unlink()
    (folder / "report.json").write_text(json.dumps(data))
    return folder


def _pop(*keys):
    def change(data):
        target = data
        for key in keys[:-1]:
            target = target[key] if not isinstance(target, dict) or key in target else next(iter(target.values()))
        target.pop(keys[-1])

    return change


def _put(value, *keys):
    def change(data):
        target = data
        for key in keys[:-1]:
            target = target[key] if key != "*" else next(iter(target.values()))
        target[keys[-1]] = value

    return change


@pytest.mark.parametrize(("change", "field", "expected"), [
    (_put(True, "results", 0, "look", "not_judged"), "results[0].look.not_judged",
     "expected a reason as atlasgen validate writes it, got True"),
    (_put(3, "results", 0, "look", "reference"), "results[0].look.reference", "expected a reference name"),
    (_pop("results", 0, "material"), "results[0].material", "expected a material name as atlasgen validate writes it, missing"),
    (_put([1], "results", 0, "material"), "results[0].material", "got [1]"),
    (_pop("results", 0, "atlas_image"), "results[0].atlas_image", "missing"),
    (_put(5, "results", 0, "atlas_image"), "results[0].atlas_image", "expected an image path"),
    (_put("x", "results", 0, "look"), "results[0].look", "expected an object"),
    (_put(5, "results", 0, "notes"), "results[0].notes", "expected a list of notes"),
    (_put("x", "results", 0, "error_breakdown"), "results[0].error_breakdown", "expected an object"),
    (_put(5, "results", 0, "page"), "results[0].page", "expected a page path"),
    (_put([1], "results", 0, "references", "*", "images"), ".images", "expected an object of image paths"),
    (_put({"a": 1}, "results", 0, "references", "*", "images"), ".images", "expected image paths"),
    (_put("x", "settings", "scenes"), "settings.scenes", "expected a list of scenes"),
    (_put("many", "settings", "spp"), "settings.spp", "expected a finite number"),
    (_put(3, "atlas"), "atlas", "expected the atlas's path as atlasgen validate writes it, got 3"),
    (_put("", "atlas"), "atlas", "got ''"),
    # Linked from the merged page as they were: outside the source folder, or no image of it.
    (_put("/etc/passwd", "results", 0, "atlas_image"), "results[0].atlas_image",
     "expected the path of a PNG image beside the report, got '/etc/passwd'"),
    (_put("../../../../../../etc/passwd", "results", 0, "atlas_image"), "results[0].atlas_image",
     "expected the path of a PNG image beside the report"),
    (_put({"reference": "images/none.png"}, "results", 0, "references", "*", "images"), ".images.reference",
     "expected the path of a PNG image beside the report, got 'images/none.png'"),
    # The library page read these as figures: an internal error (ValueError) each.
    (_put([1, 2], "results", 0, "claimed_errors"), "results[0].claimed_errors", "expected an object of figures, got list"),
    (_put({"relative_rms_8bit": "abc"}, "results", 0, "claimed_errors"), "results[0].claimed_errors.relative_rms_8bit",
     "expected a finite number or null, got 'abc'"),
    (_put({"relative_rms_8bit": -0.5}, "results", 0, "claimed_errors"), "results[0].claimed_errors.relative_rms_8bit",
     "expected a number >= 0, got -0.5"),
    (_put({"terms": 2.5}, "results", 0, "claimed_errors"), "results[0].claimed_errors.terms",
     "expected a whole number of terms, got 2.5"),
    # Merged as they were, and "yes" counted as met: a verdict is true, false or null, a look goal numbers.
    (_put("yes", "results", 0, "references", "*", "meets_goal"), ".meets_goal",
     "expected true, false or null as atlasgen validate writes it, got 'yes'"),
    (_put({"meets_goal": 1}, "results", 0, "look"), "results[0].look.meets_goal",
     "expected true, false or null as atlasgen validate writes it, got 1"),
    (_put({"meets_goal": None, "goal": {"psnr_db": 30.0, "flip": "0.05"}}, "results", 0, "look"),
     "results[0].look.goal.flip", "expected a finite number or null, got '0.05'"),
    (_put({"meets_goal": None, "goal": [30]}, "results", 0, "look"), "results[0].look.goal",
     "expected an object of goals, got [30]"),
    # A hostile sweep's, merged with exit 0 and printed: a region's FLIP of -1 and coverage of 500%, a breakdown's
    # FLIP of 5 and PSNR of true ("1.00"), a whole frame's PSNR of true.
    (_put({"grazing": {"coverage": 0.1, "pixels": 3, "psnr_db": 40.0, "flip": -1.0}}, "results", 0, "references", "*",
          "regions"), ".regions.grazing.flip", "expected a number in [0, 1], got -1.0"),
    (_put({"rest": {"coverage": 5.0, "pixels": 3, "psnr_db": 40.0, "flip": 0.1}}, "results", 0, "references", "*",
          "regions"), ".regions.rest.coverage", "expected a number in [0, 1], got 5.0"),
    (_put({"table_8bit": {"psnr_db": 40.0, "flip": 5.0}}, "results", 0, "error_breakdown"),
     "results[0].error_breakdown.table_8bit.flip", "expected a number in [0, 1], got 5.0"),
    (_put({"table_float": {"psnr_db": True}}, "results", 0, "error_breakdown"),
     "results[0].error_breakdown.table_float.psnr_db", "expected a finite number or null, got True"),
    (_put(True, "results", 0, "references", "*", "whole_frame_psnr_db"), ".whole_frame_psnr_db",
     "expected a finite number or null, got True"),
])  # fmt: skip
def test_a_hand_edited_report_is_refused_naming_the_field(merged, tmp_path, change, field, expected):
    """Each of these was an internal error (KeyError, TypeError, AttributeError) or merged silently."""
    from atlasgen.reports.validation import merge_validation_reports

    folder = _edited(merged, tmp_path, change)
    with pytest.raises(InputError) as info:
        merge_validation_reports([folder], tmp_path / "merged")
    message = str(info.value)
    assert message.startswith(f"{(folder / 'report.json').as_posix()}: field '") and field in message and \
        expected in message and "\n" not in message, message  # fmt: skip
    assert not (tmp_path / "merged").exists()


@pytest.mark.parametrize(("key", "value", "expected"), [
    ("flip", -1.0, "expected a number in [0, 1], got -1.0"),
    ("coverage", 5.0, "expected a number in [0, 1], got 5.0"),
    ("clipped_pixels", -3, "expected a number >= 0, got -3"),
    ("spp", 0, "expected a number >= 1, got 0"),
])  # fmt: skip
def test_a_figure_beyond_what_it_can_be_is_refused(merged, tmp_path, key, value, expected):
    """A hostile sweep's: a FLIP of -1 became the summary's worst, and a coverage of 5 merged."""
    from atlasgen.reports.validation import merge_validation_reports

    folder = _edited(merged, tmp_path, lambda data: data["results"][0]["references"]["model"].update({key: value}))
    with pytest.raises(InputError) as info:
        merge_validation_reports([folder], tmp_path / "merged")
    assert str(info.value).endswith(f"field 'results[0].references.model.{key}': {expected}"), str(info.value)


def test_a_verdict_its_figures_do_not_give_is_refused(merged, tmp_path):
    """An edited meets_goal (true beside 20 dB and FLIP 0.5) merged as "all goals met"; a negative time printed."""
    from atlasgen.reports.validation import merge_validation_reports

    def forged(data):
        ref = next(r for r in data["results"] if r["references"].get("model", {}).get("meets_goal") is True)["references"]
        ref["model"].update(psnr_db=20.0, flip=0.5)

    folder = _edited(merged, tmp_path / "verdict", forged)
    with pytest.raises(InputError) as info:
        merge_validation_reports([folder], tmp_path / "merged")
    assert ".references.model.meets_goal': expected false from its figures (PSNR 20.0 dB, FLIP 0.5000) and the goals " \
        "(PSNR >= " in str(info.value) and str(info.value).endswith("got true; re-run atlasgen validate"), str(info.value)  # fmt: skip
    folder = _edited(merged, tmp_path / "seconds", _put(-5, "total_seconds"))
    with pytest.raises(InputError, match=r"field 'total_seconds': expected a number >= 0, got -5$"):
        merge_validation_reports([folder], tmp_path / "merged")
    assert not (tmp_path / "merged").exists()


def test_a_verdict_beside_no_figures_is_refused(merged, tmp_path):
    """A hostile sweep's: figures all null beside meets_goal true merged as "storage 2/2 met" (a null PSNR is an
    infinite one, but a null FLIP is none at all), and "not measured" beside true passed into the merged page."""
    from atlasgen.reports.validation import merge_validation_reports

    def met(**figures):
        def change(data):
            row = next(r for r in data["results"] if r["references"].get("model", {}).get("meets_goal") is True)
            row["references"]["model"].update(figures)

        return change

    folder = _edited(merged, tmp_path / "null", met(psnr_db=None, flip=None, rmse=None))
    with pytest.raises(InputError) as info:
        merge_validation_reports([folder], tmp_path / "merged")
    assert str(info.value).endswith(".references.model.flip': expected a number beside the verdict it gives (meets_goal "
                                    "true), got None; re-run atlasgen validate"), str(info.value)  # fmt: skip
    folder = _edited(merged, tmp_path / "black", met(psnr_db=None, flip=None, not_measured="black"))
    with pytest.raises(InputError, match=r"\.references\.model\.meets_goal': expected null from its figures \(PSNR inf "):
        merge_validation_reports([folder], tmp_path / "merged")
    merge_validation_reports([_edited(merged, tmp_path / "inf", met(psnr_db=None))], tmp_path / "merged")  # identical
    assert json.loads((tmp_path / "merged" / "report.json").read_text())["summary"]


def test_a_verdict_nulled_or_given_where_the_goals_do_not_judge_is_refused(merged, tmp_path):
    """A hostile sweep's: a model verdict nulled by hand dropped the result from the summary's count (LUT 3/3 for
    4/4), and a verdict on a material that claims its own error was counted; a type of 5 and a result on a scene
    the report never rendered merged."""
    from atlasgen.reports.validation import merge_validation_reports

    def model_of(material):
        def change(data):
            row = next(r for r in data["results"] if r["material"] == material)
            row["references"]["model"]["meets_goal"] = None if material == "matte" else True

        return change

    folder = _edited(merged, tmp_path / "nulled", model_of("matte"), material="matte")
    with pytest.raises(InputError) as info:
        merge_validation_reports([folder], tmp_path / "merged")
    assert ".references.model.meets_goal': expected true from its figures (PSNR " in str(info.value) and \
        str(info.value).endswith("got null; re-run atlasgen validate"), str(info.value)  # fmt: skip
    folder = _edited(merged, tmp_path / "claimed", model_of("gloss"), material="gloss")
    with pytest.raises(InputError, match=r"\.references\.model\.meets_goal': expected null \(a separable material claims "
                                         r"its own error, which the goals do not judge\), got true$"):  # fmt: skip
        merge_validation_reports([folder], tmp_path / "merged")
    folder = _edited(merged, tmp_path / "scene", _put("side", "results", 0, "scene"))
    with pytest.raises(InputError, match=r"field 'results\[0\]\.scene': expected a scene of settings\.scenes \('front', "
                                         r"'back'\), got 'side'$"):  # fmt: skip
        merge_validation_reports([folder], tmp_path / "merged")
    folder = _edited(merged, tmp_path / "type", _put(5, "results", 0, "type"))
    with pytest.raises(InputError, match=r"field 'results\[0\]\.type': expected a material type as atlasgen validate "
                                         r"writes it, got 5$"):  # fmt: skip
        merge_validation_reports([folder], tmp_path / "merged")
    # A type this atlasgen has no model for (a plug-in's) keeps its recorded verdict, null included.
    merge_validation_reports([_edited(merged, tmp_path / "plugin", lambda data: [
        r.update(type="plugin-model") or r["references"]["model"].update(meets_goal=None) for r in data["results"]],
        material="matte")], tmp_path / "merged")  # fmt: skip
    merged_rows = json.loads((tmp_path / "merged" / "report.json").read_text())["results"]
    assert [r["references"]["model"]["meets_goal"] for r in merged_rows] == [None] * len(merged_rows)


def _met_look(data, forge) -> None:
    """A row's look made met, its reference's figures far beyond its goal and its floor, then ``forge`` applied."""
    row = next(r for r in data["results"] if (r.get("look") or {}).get("reference") in r["references"])
    ref = row["references"][row["look"]["reference"]]
    for key in ("parts", "not_measured", "coverage"):
        ref.pop(key, None)
    ref.update(psnr_db=60.0, flip=0.001, clipped_pixels=0, noise_floor_db=90.0, noise_floor_ok=True, look_goal=True)
    row["look"].update(goal={"psnr_db": 30.0, "flip": 0.05}, meets_goal=True, not_judged=None)
    row["look"].pop("parts", None)
    if forge is not None:
        forge(row)


@pytest.mark.parametrize(("forge", "expected"), [
    (None, None),  # as atlasgen validate would write it: merged
    # The reference's figures or the goal edited: "met" beside a physical PSNR of 10 dB passed --strict.
    (lambda row: row["references"][row["look"]["reference"]].update(psnr_db=10.0), "expected false from the "),
    (lambda row: row["references"][row["look"]["reference"]].update(flip=0.9), "expected false from the "),
    (lambda row: row["look"]["goal"].update(psnr_db=99.0), "expected false from the "),
    # The verdict edited: the page printed a miss beside figures that meet the goal.
    (lambda row: row["look"].update(meets_goal=False), "expected true from the "),
    # No figures at all, "met": the page printed "inf / inf dB ... met".
    (lambda row: row["references"][row["look"]["reference"]].update(psnr_db=None, flip=None), "flip"),
    # Nothing rendered, kept as "met" in the merged report.json.
    (lambda row: row["look"].update(reference=None, skipped=True, why_none="not rendered (--no-physical)"), "null"),
])  # fmt: skip
def test_a_look_verdict_its_figures_do_not_give_is_refused(merged, tmp_path, forge, expected):
    from atlasgen.reports.validation import merge_validation_reports

    folder = _edited(merged, tmp_path, lambda data: _met_look(data, forge), material="film")  # judged on its look
    if expected is None:
        merge_validation_reports([folder], tmp_path / "merged")
        return
    with pytest.raises(InputError) as info:
        merge_validation_reports([folder], tmp_path / "merged")
    message = str(info.value)
    assert message.endswith("; re-run atlasgen validate") and "\n" not in message, message
    if expected == "flip":
        assert ".flip': expected a number beside the verdict it gives (meets_goal true), got None" in message, message
    elif expected == "null":
        assert ".look.meets_goal': expected null for a look compared with nothing (not rendered (--no-physical)), " \
            "got true" in message, message  # fmt: skip
    else:
        assert ".look.meets_goal': " + expected in message and "reference's figures (PSNR " in message, message
    assert not (tmp_path / "merged").exists()


def test_a_field_the_page_cannot_print_is_one_line_naming_the_file(merged, tmp_path):
    """Deeper than the checked fields (the settings' goals): the page's own failure, one line."""
    from atlasgen.reports.validation import merge_validation_reports

    for i, (change, got) in enumerate([(_put("x", "settings", "goals"), "'x'"), (_put([1], "settings", "goals"), "[1]")]):
        folder = _edited(merged, tmp_path / str(i), change)
        with pytest.raises(InputError) as info:
            merge_validation_reports([folder], tmp_path / "merged")
        # Named by the field the page stopped on (it named no field).
        assert str(info.value).startswith(f"{(folder / 'report.json').as_posix()}: field 'settings.goals': expected the "
                                          f"value atlasgen validate writes there, got {got} (")  # fmt: skip
        assert "\n" not in str(info.value)
    assert not (tmp_path / "merged").exists()


def test_a_result_the_page_cannot_print_is_named_by_file_and_entry(merged, tmp_path):
    """Two reports, the second's first result edited below the checked fields: the refusal names that
    report and that result, not every merged file; nothing is written."""
    from atlasgen.reports.validation import merge_validation_reports

    out, parts, _ = merged
    first, second = (out / "materials" / m for m in list(parts)[:2])
    data = json.loads((second / "report.json").read_text())
    row = data["results"][0]
    row["error_breakdown"] = {**row["error_breakdown"], "table_float": "x"}  # an object of figures, made a string
    edited = tmp_path / "edited"
    shutil.copytree(second, edited)
    (edited / "report.json").write_text(json.dumps(data))
    with pytest.raises(InputError) as info:
        merge_validation_reports([first, edited], tmp_path / "merged")
    message = str(info.value)
    # Named by the field (it named the result only), now checked before the page is formatted.
    assert message == (f"{(edited / 'report.json').as_posix()}: field 'results[0].error_breakdown.table_float': expected "
                       "an object of figures, got 'x'"), message  # fmt: skip
    assert first.as_posix() not in message and "\n" not in message
    assert not (tmp_path / "merged").exists()


def test_the_summary_s_sentences_are_spaced(merged):
    """The template's trim_blocks ate the newline between sentences that follow an ``{% if %}``: the page read
    "worst mean FLIP 0.0122.21 of 26 judged looks" and "skin/back.No physical reference"."""
    import re

    out, _, written = merged
    text = (out / "index.html").read_text(encoding="utf-8")
    summary = re.sub(r"<[^>]+>", "", text.split('<h2 id="summary">', 1)[1].split("</p>", 1)[0])
    data = written["data"]["summary"]
    assert data["look_results"] and data["no_physical_reference"], "the run must hold both sentences"
    assert not re.search(r"\d\.\d+\.\d|[a-z)]\.[A-Z]", summary), summary


def test_a_merge_into_a_separable_report_s_folder_is_refused_and_changes_nothing(merged, tmp_path):
    """Both commands name their set by report.json, so they share a store: `validate --merge ... -o S` replaced the
    separable report S whole (exit 0), and what read S as one then failed. Refused, exit 4, nothing replaced."""
    import json

    from atlasgen.io.atomic import write_files_atomically
    from atlasgen.reports.validation import merge_validation_reports

    out, parts, _ = merged
    separable = tmp_path / "separable"
    study = (json.dumps([{"name": "gold", "source": "gold.toml"}]) + "\n").encode()
    write_files_atomically({separable / "index.md": b"# gold\n", separable / "report.json": study},
                           primary=separable / "report.json", whole=True)  # fmt: skip
    before = {p: p.read_bytes() for p in separable.rglob("*") if p.is_file()}
    with pytest.raises(OutputError, match=r"report.json: already written by another command's outputs \(a separable "
                                          r"report\); expected a folder of its own"):  # fmt: skip
        merge_validation_reports([out / "materials" / m for m in parts], separable)
    assert {p: p.read_bytes() for p in separable.rglob("*") if p.is_file()} == before
    # Its own kind it replaces, as every merge does.
    merge_validation_reports([out / "materials" / m for m in parts], tmp_path / "again")
    merge_validation_reports([out / "materials" / m for m in parts], tmp_path / "again")


def test_the_merged_environment_keeps_each_field_s_type(merged):
    """The merge wrote every environment field as text: 6 renders stored across three runs as "2", and a list as
    its Python repr. Counts are added up, lists joined, text kept, so the merged report has a run's schema."""
    out, parts, _ = merged
    sources = [json.loads((out / "materials" / m / "report.json").read_text())["environment"] for m in parts]
    environment = json.loads((out / "report.json").read_text())["environment"]
    assert set(environment) == set(sources[0])
    for key, value in environment.items():
        given = [s[key] for s in sources if s.get(key) is not None]
        if given and all(isinstance(v, int) and not isinstance(v, bool) for v in given):
            assert value == sum(given), key
        elif given and all(isinstance(v, list) for v in given):
            assert value == list(dict.fromkeys(x for v in given for x in v)), key
        else:
            assert isinstance(value, str | type(None)), key
    import doctest

    from atlasgen.reports import validation

    assert doctest.testmod(validation).failed == 0  # _combined's examples


def test_a_verdict_on_another_reference_than_the_model_is_refused(merged, tmp_path):
    """The storage goals judge the model reference alone: an edited "missed" on the physical comparison was printed
    in the metrics table beside "all goals met" for the same material."""
    from atlasgen.reports.validation import merge_validation_reports

    other = "physical"

    def judge_physics(data):
        references = data["results"][0]["references"]
        references[other] = {**references.get(other, references["model"]), "meets_goal": False}

    folder = _edited(merged, tmp_path, judge_physics)
    with pytest.raises(
        InputError,
        match=rf"field 'results\[0\].references.{other}.meets_goal': expected null \(the "
        r"goals judge the model reference alone\), got false",
    ):
        merge_validation_reports([folder], tmp_path / "merged")


def test_an_image_that_is_no_png_and_run_times_past_a_double_are_refused(merged, tmp_path):
    """A .png link to /etc/passwd was linked from the merged page as an image; two runs of 1e308 s summed to inf,
    whose writing failed with a line that blamed another field."""
    from atlasgen.reports.validation import merge_validation_reports

    folder = _edited(merged, tmp_path, _put("images/pw.png", "results", 0, "atlas_image"))
    (folder / "images" / "pw.png").symlink_to("/etc/passwd")
    with pytest.raises(
        InputError,
        match=r"field 'results\[0\].atlas_image': expected the path of a PNG image beside "
        r"the report, got 'images/pw.png'",
    ):
        merge_validation_reports([folder], tmp_path / "merged")
    out, parts, _ = merged
    sources = []
    for name in list(parts)[:2]:
        sources.append(tmp_path / name)
        shutil.copytree(out / "materials" / name, sources[-1], symlinks=False)
        data = json.loads((sources[-1] / "report.json").read_text())
        data["total_seconds"] = 1e308
        (sources[-1] / "report.json").unlink()
        (sources[-1] / "report.json").write_text(json.dumps(data))
    with pytest.raises(
        InputError,
        match=r"field 'total_seconds': expected run times whose sum a double holds, got "
        r"1e\+308 \+ 1e\+308",
    ):
        merge_validation_reports(sources, tmp_path / "merged")
    assert not (tmp_path / "merged").exists()
