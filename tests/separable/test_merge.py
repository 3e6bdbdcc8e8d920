"""Per-material separable reports, written all-or-nothing, merge into the report one run writes."""

from __future__ import annotations

import json
import os
import re
import shutil
from pathlib import Path

import pytest

from atlasgen.errors import InputError, OutputError
from atlasgen.materials.material import read_material
from atlasgen.reports.separable import write_separable_report
from atlasgen.reports.separable_merge import PLOT_KINDS, merge_separable_reports
from tests.html_links import PageLinks

#: Small studies: two grids, one repeat, one parametrization (seconds, not tens of seconds).
CHEAP = {"resolutions": (8, 16), "repeats": 1, "parametrizations": ("half_diff",)}


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    """Two materials, each studied into its own folder, as ``make report``'s jobs do."""
    root = tmp_path_factory.mktemp("separable")
    sources = {
        "lobe": 'type = "separable"\nsource = "blinn_phong"\nexponent = 40.0\nterms = 2\n',
        "sheen": 'type = "separable"\nsource = "ggx"\nalpha = 0.4\nterms = 1\n',
    }
    folders = {}
    for name, text in sources.items():
        (root / f"{name}.toml").write_text(text)
        folders[name] = root / "out" / "materials" / name
        written = write_separable_report([read_material(root / f"{name}.toml")], folders[name], **CHEAP)
        assert written["markdown"] == folders[name] / "index.md" and written["markdown"].is_file()
    return root / "out", folders


@pytest.mark.slow
def test_merging_one_report_reproduces_it_byte_for_byte(reports, tmp_path):
    # The studies survive the JSON round trip: the study's own writer, fed from JSON,
    # writes the same Markdown the measuring run wrote.
    # Merged beside the report: the material file's path, given from the report's folder, is the same from there.
    _, folders = reports
    again = folders["lobe"].parent / "again"
    merge_separable_reports([folders["lobe"]], again)
    for name in ("index.md", "index.html", "report.json", *(f"lobe-{kind}.png" for kind in PLOT_KINDS)):
        assert (again / name).read_bytes() == (folders["lobe"] / name).read_bytes(), name


@pytest.mark.slow
def test_a_merge_over_a_single_report_is_the_same_output_set(reports, tmp_path):
    """One folder, one set: a merge written where a single run's report was keeps its store and lock, so the two
    commands never write the same paths under two locks, and no stale generation is left behind."""
    import shutil

    from atlasgen.io.atomic import STORE_SUFFIX

    _, folders = reports
    folder = tmp_path / "report"
    shutil.copytree(folders["lobe"], folder, symlinks=True)
    merge_separable_reports([folders["lobe"], folders["sheen"]], folder)
    stores = sorted(p.name for p in folder.iterdir() if p.name.endswith(STORE_SUFFIX))
    assert stores == [p.name for p in folders["lobe"].iterdir() if p.name.endswith(STORE_SUFFIX)], stores
    assert len(json.loads((folder / "report.json").read_text())) == 2


@pytest.mark.slow
def test_merged_report_holds_every_study_and_links_only_files_beside_it(reports):
    out, folders = reports
    written = merge_separable_reports([folders["lobe"], folders["sheen"]], out)
    merged = json.loads(written["json"].read_text())
    studies = [json.loads((folders[n] / "report.json").read_text())[0] for n in ("lobe", "sheen")]
    for study in studies:  # each material file given from the merged report's folder (out), not its own
        study["source"] = f"../{study['name']}.toml"
    assert merged == studies
    text = written["markdown"].read_text()
    links = re.findall(r"\]\(([^)]+)\)", text)
    assert len(links) == 2 * len(PLOT_KINDS)
    for link in links:
        assert "/" not in link and (out / link).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # The HTML page shows every plot beside it, and links only files beside it or its own sections.
    page = written["html"].read_text()
    parser = PageLinks(page)
    assert sorted(parser.images) == sorted(links)
    for link in parser.links:
        assert (f'id="{link[1:]}"' in page) if link.startswith("#") else (out / link).is_file(), link
    assert {"#material-lobe", "#material-sheen", "index.md"} <= set(parser.links)
    # One summary row per material, with its measured error.
    for study in merged:
        assert f"| {study['name']} | " in text
        assert f"{100 * study['chosen']['float']['relative_rms']:.2f}%" in text


def _edited_report(reports, tmp_path, keys, value) -> Path:
    """A folder holding the lobe study's report.json with the field at ``keys`` set to ``value``."""
    _, folders = reports
    data = json.loads((folders["lobe"] / "report.json").read_text())
    target = data[0]
    for key in keys[:-1]:
        target = target[key]
    target[keys[-1]] = value
    edited = tmp_path / "edited"
    edited.mkdir()
    (edited / "report.json").write_text(json.dumps(data))
    return edited


@pytest.mark.parametrize(("keys", "value", "expected"), [
    (("chosen", "8bit_srgb", "relative_rms"), -0.5, "field '[0].chosen.8bit_srgb.relative_rms': expected a number >= 0, got -0.5"),
    (("chosen", "terms"), "three", "field '[0].chosen.terms': expected a whole number >= 1, got 'three'"),
    (("chosen", "grid"), 0, "field '[0].chosen.grid': expected a whole number >= 1, got 0"),
    (("timings", "svd_s"), -1, "field '[0].timings.svd_s': expected a number >= 0, got -1"),
])  # fmt: skip
@pytest.mark.slow
def test_a_figure_no_study_measures_is_refused_naming_it(reports, tmp_path, keys, value, expected):
    """The merged table printed a relative RMS of -0.5 as "-50.00%" and terms = "three" as written, exit 0."""
    edited = _edited_report(reports, tmp_path, keys, value)
    with pytest.raises(InputError) as info:
        merge_separable_reports([edited], tmp_path / "merged")
    assert str(info.value) == f"{(edited / 'report.json').as_posix()}: {expected}"
    assert not (tmp_path / "merged").exists()


@pytest.mark.parametrize(("keys", "value", "field"), [
    (("chosen", "terms"), 7, "[0].chosen.float.relative_rms"),
    (("chosen", "8bit_srgb", "relative_rms"), 0.9, "[0].chosen.8bit_srgb.relative_rms"),
])  # fmt: skip
@pytest.mark.slow
def test_chosen_figures_that_are_not_the_study_s_own_at_its_k_are_refused(reports, tmp_path, keys, value, field):
    """A hostile sweep's: terms = 7 printed K = 3's figures as K = 7's, and an 8-bit error of 0.9 merged beside a
    table that gives 0.006 at the chosen K. The SVD terms are prefixes of one factorization, so the chosen row is
    the table's at K."""
    edited = _edited_report(reports, tmp_path, keys, value)
    with pytest.raises(InputError) as info:
        merge_separable_reports([edited], tmp_path / "merged")
    message = str(info.value)
    assert message.startswith(f"{(edited / 'report.json').as_posix()}: field '{field}': expected ") and \
        ", the study's by_terms.f_cos." in message and "at the chosen K = " in message, message  # fmt: skip
    assert not (tmp_path / "merged").exists()


@pytest.mark.slow
def test_a_merge_into_one_of_its_sources_is_refused_and_changes_nothing(reports, tmp_path):
    """``report separable --merge A B -o B`` replaced B's own report.json with the merge (exit 0)."""
    import shutil

    _, folders = reports
    target = tmp_path / "sheen"
    shutil.copytree(folders["sheen"], target, symlinks=True)
    before = {p: p.read_bytes() for p in target.rglob("*") if p.is_file()}
    with pytest.raises(OutputError, match=r"sheen/report.json: the merged report would overwrite a --merge source"):
        merge_separable_reports([folders["lobe"], target], target)
    assert {p: p.read_bytes() for p in target.rglob("*") if p.is_file()} == before


@pytest.mark.slow
def test_bad_sources_are_refused_and_nothing_is_written(reports, tmp_path):
    _, folders = reports
    out = tmp_path / "merged"
    with pytest.raises(InputError, match="'lobe' is also in"):
        merge_separable_reports([folders["lobe"], folders["lobe"] / "report.json"], out)
    with pytest.raises(InputError, match=r"none/report.json: no such separable report"):
        merge_separable_reports([tmp_path / "none"], out)
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "report.json").write_text(json.dumps([{"name": "x"}]))
    with pytest.raises(InputError, match="entry 0 is not a material study"):
        merge_separable_reports([broken], out)
    data = json.loads((folders["lobe"] / "report.json").read_text())
    (broken / "report.json").write_text(json.dumps(data))
    with pytest.raises(InputError, match=r"lobe-terms.png: no such file \(the terms plot of 'lobe'\)"):
        merge_separable_reports([broken], out)
    for kind in PLOT_KINDS:  # the other three, good
        shutil.copy(folders["lobe"] / f"lobe-{kind}.png", broken)
    plot = broken / "lobe-pareto.png"
    # A hostile sweep's: a named pipe hung the merge, /dev/zero filled the memory, an empty file was merged as a plot.
    plot.unlink()
    os.mkfifo(plot)
    with pytest.raises(InputError, match=r"lobe-pareto.png: expected a regular file, got a named pipe"):
        merge_separable_reports([broken], out)
    plot.unlink()
    plot.symlink_to("/dev/zero")
    with pytest.raises(InputError, match=r"lobe-pareto.png: expected a regular file, got a character device"):
        merge_separable_reports([broken], out)
    plot.unlink()
    plot.write_bytes(b"")
    with pytest.raises(InputError, match=r"expected the pareto plot of 'lobe', a PNG image, got 0 bytes of something"):
        merge_separable_reports([broken], out)
    assert not out.exists()


def test_an_interrupted_report_leaves_the_folder_as_it_was(tmp_path, write_material):
    out = tmp_path / "report"
    out.mkdir()
    (out / "index.md").write_text("the previous report")
    lut = read_material(write_material("clay", 'type = "lambert"\n'))
    with pytest.raises(InputError, match="clay.toml: field 'type': material 'clay' is 'lambert', not separable; expected type"):
        write_separable_report([lut], out, **CHEAP)
    assert (out / "index.md").read_text() == "the previous report"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["materials", "report"]  # no staging folder left


def test_staged_folder_replaces_files_only_on_success(tmp_path):
    from atlasgen.io.atomic import staged_folder

    out = tmp_path / "out"
    with staged_folder(out) as staging:
        (staging / "sub").mkdir()
        (staging / "sub" / "a.txt").write_text("a")
    assert (out / "sub" / "a.txt").read_text() == "a"
    with pytest.raises(RuntimeError), staged_folder(out) as staging:
        (staging / "sub").mkdir()
        (staging / "sub" / "a.txt").write_text("half")
        raise RuntimeError("interrupted")
    assert (out / "sub" / "a.txt").read_text() == "a"
    (tmp_path / "file").write_text("not a folder")
    with pytest.raises(OutputError), staged_folder(tmp_path / "file" / "out") as staging:
        pass
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "out"]


@pytest.mark.slow
def test_cli_merge_prints_the_merged_markdown_and_names_a_bad_source(reports, tmp_path):
    from click.testing import CliRunner

    from atlasgen.cli.main import app

    _, folders = reports
    runner = CliRunner()
    res = runner.invoke(
        app, ["report", "separable", "--merge", str(folders["lobe"]), str(folders["sheen"]), "-o", str(tmp_path / "m")]
    )
    assert res.exit_code == 0, res.output
    assert res.output.strip() == (tmp_path / "m" / "index.html").as_posix()
    res = runner.invoke(app, ["report", "separable", "--merge", str(tmp_path / "none"), "-o", str(tmp_path / "n")])
    assert res.exit_code == 3
    assert (
        res.output.startswith(f"atlasgen: error: {(tmp_path / 'none' / 'report.json').as_posix()}: ")
        and res.output.count("\n") == 1
    )
