"""The separable report: every promised plot and table, from measured data; the CLI's error paths."""

import json
import re
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from atlasgen.errors import InputError
from atlasgen.materials.material import read_material
from atlasgen.reports.separable import write_separable_report

SHOWCASE = Path(__file__).resolve().parents[2] / "materials" / "materialx-showcase.mtlx"


@pytest.mark.slow
def test_report_writes_markdown_json_and_the_plots(write_material, tmp_path, separable_atlas):
    atlas, _ = separable_atlas
    material = read_material(write_material("lobe", 'type = "separable"\nsource = "blinn_phong"\nexponent = 40.0\nterms = 2\n'))
    out = write_separable_report(
        [material],
        tmp_path / "report",
        atlas_path=atlas,
        resolutions=(8, 16),
        repeats=1,
        parametrizations=("half_diff", "in_out"),
    )
    plots = out["plots"]["lobe"]
    assert set(plots) == {"terms", "resolution", "pareto", "parametrization"}
    for png in plots.values():
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = out["markdown"].read_text()
    for png in plots.values():
        assert f"]({png.name})" in text
    data = json.loads(out["json"].read_text())[0]
    # The table shows the measured numbers: the chosen K's float error, as a percentage.
    assert f"{100 * data['chosen']['float']['relative_rms']:.2f}%" in text
    assert [r["resolution"] for r in data["by_resolution"]] == [8] * 4 + [16] * 4
    # The Pareto front only ever improves the error as time grows.
    errs = [p["relative_rms"] for p in data["pareto"]]
    assert errs == sorted(errs, reverse=True)
    assert set(data["by_parametrization"]) == {"half_diff", "in_out"}
    assert data["nonnegative"]["nd"]["terms"] == 1 and len(data["nonnegative"]["nmf"]) == 4
    # A material absent from the atlas is said to be absent, not measured.
    assert "missing" in data["atlas"]


def test_report_needs_a_separable_material(write_material, tmp_path):
    lut = read_material(write_material("clay", 'type = "lambert"\n'))
    with pytest.raises(InputError, match="clay.toml: field 'type': material 'clay' is 'lambert', not separable; expected"):
        write_separable_report([lut], tmp_path / "r")


def test_cli_maps_errors_to_messages(write_material, tmp_path):
    from atlasgen.cli.report_cmd import report

    write_material("clay", 'type = "lambert"\n')
    runner = CliRunner()
    res = runner.invoke(report, ["separable", "nope", "-m", str(tmp_path / "materials"), "-o", str(tmp_path / "r")])
    assert res.exit_code == 3 and "no material named nope" in res.output
    res = runner.invoke(report, ["separable", "-m", str(tmp_path / "materials"), "-o", str(tmp_path / "r")])
    assert res.exit_code == 3 and "no separable materials" in res.output


#: (material name, content hash) -> MaterialStudy: the three verbosities study the same files.
_STUDIES: dict = {}


@pytest.mark.parametrize("flag", [None, "-q", "-v"])
@pytest.mark.slow
@pytest.mark.xdist_group("separable-report-progress")  # one process, so the studies are shared
def test_cli_reports_progress_per_material(write_material, tmp_path, monkeypatch, flag):
    import functools

    import atlasgen.cli.report_cmd as command
    import atlasgen.reports.separable as module
    from atlasgen.cli.main import app

    # The study's sweeps, cut down to keep the test quick; the CLI passes everything else. What
    # is checked is the progress each verbosity prints, so each material is studied once. The
    # command holds its own reference to the function (from-import): patch that one.
    monkeypatch.setattr(command, "write_separable_report", functools.partial(
        module.write_separable_report, resolutions=(8,), parametrizations=("half_diff",)))  # fmt: skip
    study = module.study_material

    def study_once(material, *args, **kwargs):
        key = (material.name, material.content_hash)
        if key not in _STUDIES:
            _STUDIES[key] = study(material, *args, **kwargs)
        return _STUDIES[key]

    monkeypatch.setattr(module, "study_material", study_once)
    for name in ("lobe", "wide"):
        write_material(name, 'type = "separable"\nsource = "blinn_phong"\nexponent = 20.0\nterms = 1\n')
    out = tmp_path / "r"
    res = CliRunner().invoke(app, ["report", "separable", "-m", str(tmp_path / "materials"), "--repeats", "1",
                                   "-o", str(out), *([flag] if flag else [])])  # fmt: skip
    assert res.exit_code == 0, res.output
    if flag == "-q":
        assert res.output == ""
        return
    assert res.stdout == f"{(out / 'index.html').as_posix()}\n"
    lines = res.stderr.splitlines()
    assert lines[:2] == ["studied lobe (1/2)", "studied wide (2/2)"]
    if flag == "-v":
        assert [line.split(":")[0] for line in lines[2:]] == ["  lobe", "  wide"]
        assert (out / "lobe-terms.png").as_posix() in lines[2].split(": ", 1)[1].split(", ")
    else:
        assert lines[2:] == []


def test_cli_library_picks_from_the_installed_library(tmp_path):
    from atlasgen.cli.main import app
    from atlasgen.io.package_data import shipped_library

    res = CliRunner().invoke(app, ["report", "separable", "nope", "--library", "-o", str(tmp_path / "r")])
    assert res.exit_code == 3
    assert res.stderr.strip() == f"atlasgen: error: {shipped_library().as_posix()}: no material named nope"


def test_a_named_material_that_is_not_separable_is_named_with_its_type(write_material, tmp_path):
    """Issue 24: ``report separable terracotta`` said "no separable materials" without naming it."""
    from atlasgen.cli.report_cmd import report

    path = write_material("terracotta", 'type = "lambert"\n')
    res = CliRunner().invoke(report, ["separable", "terracotta", "-m", str(tmp_path / "materials"), "-o", str(tmp_path / "r")])
    assert res.exit_code == 3
    assert res.output.splitlines() == [f"atlasgen: error: {path.as_posix()}: field 'type': material 'terracotta' is "
                                       "'lambert', not separable; expected type = \"separable\""]  # fmt: skip


def test_a_name_and_a_file_of_the_same_material_name_are_refused(write_material, tmp_path):
    """Found by a hostile-input hunt: both were studied, into one set of plots under one name, exit 0."""
    from atlasgen.cli.report_cmd import report

    write_material("lobe", 'type = "separable"\nsource = "blinn_phong"\nexponent = 40.0\nterms = 2\n')
    other = tmp_path / "alt" / "lobe.toml"
    other.parent.mkdir()
    other.write_text('type = "separable"\nsource = "blinn_phong"\nexponent = 20.0\nterms = 2\n')
    res = CliRunner().invoke(report, ["separable", "lobe", str(other), "-m", str(tmp_path / "materials"),
                                      "-o", str(tmp_path / "r")])  # fmt: skip
    assert res.exit_code == 3 and not (tmp_path / "r").exists()
    assert res.output.splitlines() == [f"atlasgen: error: {other.as_posix()}: field 'name': duplicate material name "
                                       f"'lobe' (also in {(tmp_path / 'materials' / 'lobe.toml').as_posix()}); expected a name no "
                                       "other material has (the file's name field, or the file's own name where it "
                                       "has none)"]  # fmt: skip


def test_a_missing_atlas_is_refused_not_reported_as_not_in_atlas(write_material, tmp_path):
    from atlasgen.cli.report_cmd import report

    write_material("lobe", 'type = "separable"\nsource = "blinn_phong"\nexponent = 40.0\nterms = 2\n')
    missing = tmp_path / "nope.dds"
    res = CliRunner().invoke(report, ["separable", "lobe", "-m", str(tmp_path / "materials"), "--atlas", str(missing),
                                      "-o", str(tmp_path / "r")])  # fmt: skip
    assert res.exit_code == 3
    assert res.output.splitlines() == [
        f"atlasgen: error: {missing.as_posix()}: no such atlas; bake one first "
        f"(atlasgen bake MATERIAL_FILES_OR_FOLDERS -o {missing.as_posix()})"
    ]
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize(("key", "expected"), [
    ("parametrization", "expected one of half_diff, "),
    ("target", "expected one of f_cos, f_proxy, got 'bogus'"),
    ("type", "expected one of the models atlasgen knows ("),
])  # fmt: skip
def test_an_atlas_whose_manifest_entry_no_model_can_use_is_refused_before_the_study(
    write_material, tmp_path, separable_atlas, key, expected
):
    """A hostile sweep's: an entry edited to another parametrization failed deep in the study (an internal error),
    and one edited to another target or type was measured as it is not stored (exit 0), where info refuses them."""
    import shutil

    from atlasgen.cli.report_cmd import report

    atlas, _ = separable_atlas
    edited = tmp_path / "edited"
    edited.mkdir()
    for suffix in (".dds", ".json"):
        shutil.copy(Path(atlas).with_suffix(suffix), edited / f"atlas{suffix}")
    manifest = json.loads((edited / "atlas.json").read_text())
    index = next(i for i, m in enumerate(manifest["materials"]) if m["name"] == "phong")
    manifest["materials"][index][key] = "bogus"
    (edited / "atlas.json").write_text(json.dumps(manifest))
    write_material("phong", 'type = "separable"\nsource = "blinn_phong"\nexponent = 40.0\nterms = 2\n')
    res = CliRunner().invoke(report, ["separable", "phong", "-m", str(tmp_path / "materials"), "--atlas",
                                      str(edited / "atlas.dds"), "--repeats", "1", "-o", str(tmp_path / "r")])  # fmt: skip
    assert res.exit_code == 3, res.output
    lines = res.output.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"atlasgen: error: {(edited / 'atlas.json').as_posix()}: field "
                                                   f"'materials[{index}].{key}': {expected}"), lines  # fmt: skip
    assert not (tmp_path / "r").exists()


def test_an_empty_folder_given_as_a_material_file_is_named(tmp_path):
    """A hostile sweep's: `report separable dir.toml`, an empty folder, said "no separable materials" naming nothing."""
    from atlasgen.cli.report_cmd import report

    folder = tmp_path / "dir.toml"
    folder.mkdir()
    res = CliRunner().invoke(report, ["separable", str(folder), "-o", str(tmp_path / "r")])
    assert res.exit_code == 3, res.output
    assert res.output.splitlines() == [f"atlasgen: error: {folder.as_posix()}: no separable materials to report on; "
                                       'expected materials with type = "separable"']  # fmt: skip


def test_merging_an_empty_report_is_refused(tmp_path):
    from atlasgen.cli.report_cmd import report

    source = tmp_path / "empty"
    source.mkdir()
    (source / "report.json").write_text("[]\n")
    res = CliRunner().invoke(report, ["separable", "--merge", str(source), "-o", str(tmp_path / "out")])
    assert res.exit_code == 3
    assert res.output.splitlines() == [f"atlasgen: error: {(source / 'report.json').as_posix()}: an empty separable report "
                                       "(expected at least one material study)"]  # fmt: skip


@pytest.fixture(scope="module")
def lobe_study(tmp_path_factory):
    """One study of a Blinn-Phong lobe, as ``make report`` writes each material's, to edit by hand."""
    from atlasgen.cli.report_cmd import report

    root = tmp_path_factory.mktemp("study")
    (root / "lobe.toml").write_text('type = "separable"\nsource = "blinn_phong"\nexponent = 40.0\nterms = 2\n')
    res = CliRunner().invoke(report, ["separable", str(root / "lobe.toml"), "--repeats", "1", "-o", str(root / "lobe"), "-q"])
    assert res.exit_code == 0, res.output
    return root / "lobe"


def _set(data, keys, value):
    for key in keys[:-1]:
        data = data[key]
    data[keys[-1]] = value


@pytest.mark.slow
@pytest.mark.parametrize(("keys", "value", "expected"), [
    (["by_terms"], None, "field '[0].by_terms': expected an object, got None"),
    (["chosen", "float", "relative_rms_se"], "x", "field '[0].chosen.float.relative_rms_se': expected a finite number, "
                                                  "got 'x'"),
    (["by_resolution"], "x", "field '[0].by_resolution': expected a list, got 'x'"),
    (["by_resolution", 0, "cost"], "x", "field '[0].by_resolution[0].cost': expected a finite number, got 'x'"),
    (["by_resolution", 1, "terms"], "x", "field '[0].by_resolution[1].terms': expected a whole number >= 1, got 'x'"),
    (["pareto", 0, "seconds"], "x", "field '[0].pareto[0].seconds': expected a finite number, got 'x'"),
    (["charts"], {"terms": {"width": "a"}}, "field '[0].charts.terms.height': expected a value, got none (no such key)"),
    (["charts", "terms", "width"], "a", "field '[0].charts.terms.width': expected a whole number >= 1, got 'a'"),
    (["charts"], [1, 2], "field '[0].charts': expected an object, got [1, 2]"),
    (["by_terms", "f_cos", "float", 1], "small", "field '[0].by_terms.f_cos.float[1]': expected a finite number, "
                                                 "got 'small'"),
    (["chosen"], "x", "field '[0].chosen': expected an object, got 'x'"),
    (["chosen", "float", "relative_rms"], "big", "field '[0].chosen.float.relative_rms': expected a finite number, got 'big'"),
    (["name"], [1], "entry 0: expected a material name (a letter then letters, digits, '-' or '_', at most 63), got [1]"),
    # A name is the plots' file names: these read, and would write, files outside the study's folder.
    (["name"], "../lobe", "entry 0: expected a material name (a letter then letters, digits, '-' or '_', at most 63), "
                          "got '../lobe'"),
    (["name"], "sub/lobe", "entry 0: expected a material name"),
    # A hostile sweep's: an internal error (a list as a dict key; a template's missing attribute) ...
    (["chosen", "target"], ["x"], "field '[0].chosen.target': expected a string, got ['x']"),
    (["charts", "pareto", "labels"], "abc", "field '[0].charts.pareto.labels': expected a list, got 'abc'"),
    (["charts", "pareto", "labels"], [{"text": "a"}], "field '[0].charts.pareto.labels[0].left': expected a value, "
                                                      "got none (no such key)"),
    # ... the wrong field named (the last one read before the failure) ...
    (["by_resolution", 0, "terms"], None, "field '[0].by_resolution[0].terms': expected a whole number >= 1, got None"),
    (["timings"], [1], "field '[0].timings': expected an object, got [1]"),
    # ... and merged with exit 0, printed as measured: -100.00%, "± 100.00%", "K=one", "grid None".
    (["by_terms", "f_cos", "float", 0], True, "field '[0].by_terms.f_cos.float[0]': expected a finite number, got True"),
    (["nonnegative", "nmf", 0, "relative_rms"], -1, "field '[0].nonnegative.nmf[0].relative_rms': expected a number "
                                                    ">= 0, got -1"),
    (["chosen", "float", "relative_rms_se"], True, "field '[0].chosen.float.relative_rms_se': expected a finite number, "
                                                   "got True"),
    (["atlas"], {"path": "a.dds", "relative_rms": -0.4}, "field '[0].atlas.relative_rms': expected a number >= 0"),
    (["nonnegative", "nmf", 0, "terms"], "one", "field '[0].nonnegative.nmf[0].terms': expected a whole number >= 1"),
    (["pareto", 0, "resolution"], None, "field '[0].pareto[0].resolution': expected a whole number >= 1, got None"),
    (["chosen", "target"], "bogus", "field '[0].chosen.target': expected one of f_cos, f_proxy, got 'bogus'"),
    (["chosen", "factorization"], "bogus", "field '[0].chosen.factorization': expected one of svd, nmf, nd, got 'bogus'"),
    (["by_resolution", 1, "terms"], 1, "field '[0].by_resolution[1]': expected one row per (resolution, terms), "
                                            "not a second, got (8, 1)"),
])  # fmt: skip
def test_a_hand_edited_study_is_refused_on_one_line_not_an_internal_error(lobe_study, tmp_path, keys, value, expected):
    from atlasgen.cli.report_cmd import report

    data = json.loads((lobe_study / "report.json").read_text())
    _set(data[0], keys, value)
    edited = tmp_path / "edited"
    shutil.copytree(lobe_study, edited, symlinks=False)
    (edited / "report.json").unlink()
    (edited / "report.json").write_text(json.dumps(data))
    res = CliRunner().invoke(report, ["separable", "--merge", str(edited), "-o", str(tmp_path / "out")])
    assert res.exit_code == 3, res.output
    lines = res.output.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"atlasgen: error: {(edited / 'report.json').as_posix()}: ") and \
        expected in lines[0], lines  # fmt: skip
    # In words, not Python's: the failure was "(TypeError: ...)" or "(KeyError: 'rows')".
    assert not re.search(r"\b[A-Z][a-z]+Error\b", lines[0]), lines[0]
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_a_number_beyond_a_double_is_refused_not_merged_as_infinity(lobe_study, tmp_path):
    """1e999 is valid JSON that Python reads as inf: merged, it wrote "Infinity", which no reader takes back."""
    from atlasgen.cli.report_cmd import report

    text = (lobe_study / "report.json").read_text()
    figure = json.loads(text)[0]["chosen"]["float"]["relative_rms"]
    edited = tmp_path / "edited"
    shutil.copytree(lobe_study, edited, symlinks=False)
    (edited / "report.json").unlink()
    (edited / "report.json").write_text(text.replace(repr(figure), "1e999", 1))
    res = CliRunner().invoke(report, ["separable", "--merge", str(edited), "-o", str(tmp_path / "out")])
    assert res.exit_code == 3, res.output
    assert res.output.splitlines() == [f"atlasgen: error: {(edited / 'report.json').as_posix()}: field "
                                       "'[0].chosen.float.relative_rms': expected a finite number (beyond a double's "
                                       "range), got 1e999"]  # fmt: skip


@pytest.mark.slow
def test_the_report_s_chosen_figures_are_the_manifest_s_with_their_standard_errors(write_material, tmp_path):
    """A first user read separable-sharp's 8-bit error as 2.08% in this report and 2.58% ± 0.03% in the manifest,
    validation page and preview: the study measured on 10^5 uniform pairs, which miss a glossy lobe's peak, and
    showed no standard error. It now measures on the bake's own report sample."""
    from atlasgen.cli.main import app

    path = write_material("sharp", 'type = "separable"\nsource = "ggx"\nalpha = 0.05\nterms = 4\n')
    atlas = tmp_path / "atlas.dds"
    assert CliRunner().invoke(app, ["bake", str(path), "-o", str(atlas), "-q"]).exit_code == 0
    claimed = json.loads(atlas.with_suffix(".json").read_text())["materials"][0]["errors_8bit"]
    out = write_separable_report([read_material(path)], tmp_path / "report", atlas_path=atlas, resolutions=(8,),
                                 repeats=1, parametrizations=("half_diff",))  # fmt: skip
    data = json.loads(out["json"].read_text())[0]
    assert data["chosen"]["8bit_srgb"] == {k: claimed[k] for k in ("relative_rms", "relative_rms_se")}
    # The atlas read back is what was stored: the same figure again.
    assert (data["atlas"]["relative_rms"], data["atlas"]["relative_rms_se"]) == (
        claimed["relative_rms"],
        claimed["relative_rms_se"],
    )
    shown = f"{100 * claimed['relative_rms']:.2f}% ± {100 * claimed['relative_rms_se']:.2f}%"
    assert shown in out["markdown"].read_text()


@pytest.mark.slow
def test_a_materialx_study_reports_the_terms_its_bake_chose(tmp_path):
    """The study factored a MaterialX gold as K = 3 by SVD, in the relative RMS its budget is not in, where the bake
    stored K = 6 by NMF: the page's chosen row and the atlas column described two different bakes."""
    pytest.importorskip("MaterialX")
    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.materials.material import read_material_file

    # The shipped document's gold, baked alone.
    gold = [m for m in read_material_file(SHOWCASE) if m.name == "mx_gold"]
    atlas = tmp_path / "atlas.dds"
    write_bake(bake_atlas(gold), atlas)
    baked = json.loads(atlas.with_suffix(".json").read_text())["materials"][0]
    assert baked["representation"]["kind"] == "separable"
    out = write_separable_report(gold, tmp_path / "report", atlas_path=atlas, resolutions=(8,), repeats=1,
                                 parametrizations=("half_diff",))  # fmt: skip
    chosen = json.loads(out["json"].read_text())[0]["chosen"]
    assert (chosen["terms"], chosen["grid"], chosen["factorization"], chosen["target"]) == (
        baked["terms"], baked["sampling_grid"], baked["factorization"], baked["target"])  # fmt: skip
    assert chosen["8bit_srgb"]["relative_rms"] == baked["representation"]["estimated_error_8bit"]


def test_a_material_whose_bake_stores_no_terms_is_refused_not_studied_as_terms(write_material, tmp_path):
    """An analytic material's study reported the terms of a factorization the atlas does not hold."""
    path = write_material("closed", 'type = "separable"\nsource = "ggx"\nalpha = 0.3\nrepresentation = "analytic"\n')
    with pytest.raises(InputError) as info:
        write_separable_report([read_material(path)], tmp_path / "report")
    assert str(info.value) == (f"{path.as_posix()}: field 'representation': material 'closed' bakes as the closed form "
                               "(its representation), not separable terms: there are none to study; expected "
                               'representation = "separable", or "auto" where its budget chooses terms')  # fmt: skip
    assert not (tmp_path / "report").exists()


@pytest.mark.slow
@pytest.mark.mitsuba
def test_an_auto_budget_s_terms_are_studied_as_its_search_made_them(write_material, tmp_path, mitsuba_llvm):
    """A TOML budget's K-term NMF is the prefix of an 8-term one: studied as a K-term NMF factored anew, this auto
    roughconductor's chosen row read 2.27% beside the 4.45% its atlas and manifest hold."""
    from atlasgen.cli.main import app

    path = write_material("copper", 'type = "separable"\nsource = "mitsuba"\nrepresentation = "auto"\nfactorization = "nmf"\n'
                                    'bsdf = { type = "roughconductor", distribution = "ggx", alpha = 0.3, material = "Cu" }\n'
                                    "max_error = 0.05\n")  # fmt: skip
    atlas = tmp_path / "atlas.dds"
    assert CliRunner().invoke(app, ["bake", str(path), "-o", str(atlas), "-q"]).exit_code == 0
    baked = json.loads(atlas.with_suffix(".json").read_text())["materials"][0]
    assert baked["representation"]["kind"] == "separable" and baked["factorization"] == "nmf"
    out = write_separable_report([read_material(path)], tmp_path / "report", atlas_path=atlas, resolutions=(8,),
                                 repeats=1, parametrizations=("half_diff",))  # fmt: skip
    study = json.loads(out["json"].read_text())[0]
    # The same terms (the study's own 8-bit rounding of them agrees to its sixth digit), and the atlas read back.
    assert study["chosen"]["8bit_srgb"]["relative_rms"] == pytest.approx(baked["errors_8bit"]["relative_rms"], rel=1e-4)
    assert study["atlas"]["relative_rms"] == baked["errors_8bit"]["relative_rms"]


def test_a_named_material_that_is_not_separable_is_refused_beside_separable_ones(write_material, tmp_path):
    """Named beside a separable material, a lambert one was left out of the report without a word."""
    lam = write_material("lam", 'type = "separable"\nsource = "lambert"\ndiffuse = [0.5, 0.4, 0.3]\nterms = 1\n')
    clay = write_material("clay", 'type = "lambert"\n')
    with pytest.raises(InputError) as info:
        write_separable_report([read_material(lam), read_material(clay)], tmp_path / "report")
    assert str(info.value) == (f"{clay.as_posix()}: field 'type': material 'clay' is 'lambert', not separable; "
                               'expected type = "separable"')  # fmt: skip


@pytest.mark.slow
def test_a_folder_s_report_leaves_out_the_materials_that_store_no_terms(write_material, tmp_path):
    """Every separable material of a folder: one baked as the closed form failed the whole run, where a lambert
    material of the same folder is simply not asked for."""
    from atlasgen.cli.report_cmd import report

    write_material("closed", 'type = "separable"\nsource = "ggx"\nalpha = 0.3\nrepresentation = "analytic"\n')
    res = CliRunner().invoke(report, ["separable", "-m", str(tmp_path / "materials"), "-o", str(tmp_path / "r0")])
    assert res.exit_code == 3 and "no material stores separable terms to report on" in res.stderr, res.output
    write_material("lam", 'type = "separable"\nsource = "lambert"\ndiffuse = [0.5, 0.4, 0.3]\nterms = 1\n')
    res = CliRunner().invoke(report, ["separable", "-m", str(tmp_path / "materials"), "--repeats", "1", "-o",
                                      str(tmp_path / "r1"), "-q"])  # fmt: skip
    assert res.exit_code == 0, res.output
    assert [s["name"] for s in json.loads((tmp_path / "r1" / "report.json").read_text())] == ["lam"]
    # Named, it is refused on its line.
    res = CliRunner().invoke(report, ["separable", "closed", "-m", str(tmp_path / "materials"), "-o", str(tmp_path / "r2")])
    assert res.exit_code == 3 and "material 'closed' bakes as the closed form (its representation)" in res.stderr


#: A matte standard_surface (no specular lobe): its budget chooses one LUT slice.
MATTE = (
    '<?xml version="1.0"?>\n<materialx version="1.39">\n<standard_surface name="SR_matte" type="surfaceshader">'
    '<input name="base_color" type="color3" value="0.6, 0.5, 0.4" /><input name="specular" type="float" value="0" />'
    '</standard_surface>\n<surfacematerial name="matte" type="material"><input name="surfaceshader" '
    'type="surfaceshader" nodename="SR_matte" /></surfacematerial>\n</materialx>\n'
)


@pytest.mark.slow
def test_a_materialx_material_baked_as_a_lut_is_refused_naming_it_not_a_field_it_lacks(tmp_path):
    """A document has no representation field: the refusal named one, and told its author to set it."""
    pytest.importorskip("MaterialX")
    from atlasgen.materials.material import read_material_file

    path = tmp_path / "matte.mtlx"
    path.write_text(MATTE)
    with pytest.raises(InputError) as info:
        write_separable_report(read_material_file(path), tmp_path / "report")
    assert str(info.value) == (f"{path.as_posix()}: field 'matte': material 'matte' bakes as one LUT slice (its budget's "
                               "choice), not separable terms: there are none to study; expected the document's materials "
                               "that bake as terms, named (atlasgen report separable NAME -m DOC.mtlx)")  # fmt: skip


@pytest.mark.slow
def test_an_atlas_holding_another_bake_of_the_material_is_said_so_not_measured(tmp_path):
    """--atlas of a bake of another version of the material (roughness 0.1, not 0.3) measured one against the other:
    672.89% in the atlas column, without a word. The content hashes differ: the column says "another bake"."""
    from atlasgen.cli.main import app
    from atlasgen.reports.separable_merge import merge_separable_reports

    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    (tmp_path / "a" / "g.toml").write_text('type = "separable"\nsource = "ggx"\nalpha = 0.3\nterms = 2\n')
    (tmp_path / "b" / "g.toml").write_text('type = "separable"\nsource = "ggx"\nalpha = 0.1\nterms = 2\n')
    atlas = tmp_path / "b" / "a.dds"
    assert CliRunner().invoke(app, ["bake", str(tmp_path / "b" / "g.toml"), "-o", str(atlas), "-q"]).exit_code == 0
    out = write_separable_report([read_material(tmp_path / "a" / "g.toml")], tmp_path / "r", atlas_path=atlas,
                                 resolutions=(8,), repeats=1, parametrizations=("half_diff",))  # fmt: skip
    study = json.loads(out["json"].read_text())[0]
    assert study["atlas"]["other_bake"] is True and "relative_rms" not in study["atlas"]
    assert "another bake" in out["markdown"].read_text() and "another bake" in out["html"].read_text()
    # A merge of it keeps the words.
    merged = merge_separable_reports([tmp_path / "r"], tmp_path / "m")
    assert "another bake" in merged["html"].read_text()


def test_the_summary_row_names_the_factorization_its_figures_are_of():
    """mx_gold's row read K = 6 and an 8-bit figure found in no table of the page: they are its NMF's."""
    from atlasgen.reports.separable import MaterialStudy, _summary_cells, _timings_text

    figures = {"relative_rms": 0.029, "relative_rms_se": 0.001, "log_error": 0.01}
    study = MaterialStudy(name="gold", source="g.mtlx", chosen={"parametrization": "half_diff", "target": "f_cos",
                          "terms": 6, "grid": 32, "factorization": "nmf", "float": figures, "8bit_srgb": figures},
                          by_terms={}, by_resolution=[], by_parametrization={}, nonnegative={},
                          timings={"sample_s": 0.001, "svd_s": 0.002, "quantize_s": 0.003, "error_s": 0.004})  # fmt: skip
    assert _summary_cells(study)[3] == "6 (NMF)"
    assert "NMF 2.0 ms" in _timings_text(study) and "SVD" not in _timings_text(study)


@pytest.mark.slow
def test_the_material_and_atlas_are_given_from_the_report_s_folder(write_material, tmp_path, separable_atlas, monkeypatch):
    """Both were recorded as typed, paths from the working folder: the same inputs wrote other bytes from another
    folder (a hostile sweep). A merge gives them from its own folder, as validation's merge gives its atlas."""
    from atlasgen.reports.separable_merge import merge_separable_reports

    atlas, _ = separable_atlas
    shutil.copy(atlas, tmp_path / "atlas.dds")
    shutil.copy(atlas.with_suffix(".json"), tmp_path / "atlas.json")
    (tmp_path / "m").mkdir()
    (tmp_path / "sub").mkdir()
    source = write_material("lobe", 'type = "separable"\nsource = "blinn_phong"\nexponent = 40.0\nterms = 2\n')
    shutil.copy(source, tmp_path / "m" / "lobe.toml")
    recorded = []
    for cwd, prefix in ((tmp_path, ""), (tmp_path / "sub", "../")):
        monkeypatch.chdir(cwd)
        out = write_separable_report([read_material(f"{prefix}m/lobe.toml")], tmp_path / f"r{len(recorded)}",
                                     atlas_path=f"{prefix}atlas.dds", resolutions=(8,), repeats=1,
                                     parametrizations=("half_diff",))  # fmt: skip
        data = json.loads(out["json"].read_text())[0]
        recorded.append((data["source"], data["atlas"]["path"], data["atlas"]["missing"]))
    assert recorded[0] == recorded[1]
    assert recorded[0][:2] == ("../m/lobe.toml", "../atlas.dds") and recorded[0][2].startswith("../atlas.json: "), recorded[0]
    merged = merge_separable_reports([tmp_path / "r0"], tmp_path / "merged" / "all")
    data = json.loads(merged["json"].read_text())[0]
    assert (data["source"], data["atlas"]["path"]) == ("../../m/lobe.toml", "../../atlas.dds")
