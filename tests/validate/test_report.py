"""The report: every image the HTML references exists, and the JSON holds the measured figures."""

from __future__ import annotations

import json
from html.parser import HTMLParser
from pathlib import Path

import hypothesis
import pytest
from hypothesis import strategies as st
from markupsafe import escape

from atlasgen.errors import OutputError


class _Sources(HTMLParser):
    def __init__(self):
        super().__init__()
        self.sources = []

    def handle_starttag(self, tag, attrs):
        if tag == "img":
            self.sources.append(dict(attrs).get("src"))


@pytest.fixture(scope="module")
def written(validation_run, tmp_path_factory):
    from atlasgen.reports.validation import write_validation

    out = tmp_path_factory.mktemp("report") / "validation"
    return out, write_validation(validation_run, out)


def test_every_image_the_html_references_exists_and_is_a_png(written):
    out, paths = written
    parser = _Sources()
    parser.feed((out / "index.html").read_text(encoding="utf-8"))
    assert len(parser.sources) > 10
    for src in parser.sources:
        assert src and not Path(src).is_absolute() and ".." not in Path(src).parts
        data = (out / src).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n", src
    assert "speed_error.png" in parser.sources


def test_json_holds_the_measured_metrics_of_every_result(written, validation_run):
    out, _ = written
    data = json.loads((out / "report.json").read_text())
    assert len(data["results"]) == len(validation_run.runs)
    for row, run in zip(data["results"], validation_run.runs):
        assert (row["material"], row["scene"]) == (run.material, run.scene)
        assert row["atlas_seconds"] == run.atlas_seconds
        for kind, ref in run.references.items():
            got = row["references"][kind]
            assert got["psnr_db"] == pytest.approx(ref.metrics.psnr)
            assert got["flip"] == pytest.approx(ref.metrics.flip)
            assert got["speed_ratio"] == pytest.approx(ref.seconds / run.atlas_seconds)
            assert (out / got["images"]["reference"]).is_file() and (out / got["images"]["flip"]).is_file()
            if kind == "model" and run.type != "separable":
                assert got["meets_goal"] == (ref.metrics.psnr >= 45.0 and ref.metrics.flip <= 0.01)
    summary = data["summary"]
    assert summary["lut_results"] == sum(1 for r in validation_run.runs if r.type != "separable")


def test_report_files_are_written_all_or_nothing(validation_run, tmp_path):
    from atlasgen.reports.validation import write_validation

    blocker = tmp_path / "validation"
    blocker.write_text("a file where the output folder should be")
    with pytest.raises(OutputError):
        write_validation(validation_run, blocker / "sub")
    assert blocker.read_text() == "a file where the output folder should be"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["validation"]


def test_json_and_html_carry_noise_floors_and_masks_and_strict_flags_a_noisy_floor(written, validation_run):
    from atlasgen.reports.validation import missed_goals, noise_floor_failures

    out, _ = written
    data = json.loads((out / "report.json").read_text())
    for row, run in zip(data["results"], validation_run.runs):
        for kind, ref in run.references.items():
            got = row["references"][kind]
            if getattr(ref, "noise_floor_db", None) is None:
                assert "noise_floor_db" not in got
            else:
                assert got["noise_floor_db"] == pytest.approx(ref.noise_floor_db)
                assert got["noise_floor_ok"] == ref.noise_floor_ok
            if getattr(ref, "mask", None) is not None:
                assert got["masked_fraction"] == pytest.approx(ref.masked_fraction) and got["masked"]
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "noise floor dB" in html and "by object: PSNR / FLIP (coverage), noise floor" in html
    # Each floor is labelled with the samples it was measured at.
    for row in data["results"]:
        ref = row["references"].get("physical", {})
        if "noise_floor_db" in ref:
            assert f"{ref['noise_floor_db']:.1f} at {ref['spp']} spp" in html
    # Flag one comparison as too noisy: it is listed, and --strict counts it as missed.
    row = next(r for r in data["results"] if "noise_floor_db" in r["references"].get("physical", {}))
    row["references"]["physical"].update(noise_floor_db=20.0, psnr_db=15.0, noise_floor_ok=False)
    (failure,) = [f for f in noise_floor_failures(data) if f.startswith(f"{row['material']} on {row['scene']}:")]
    assert "20.0 dB is not 10 dB above the PSNR it measures (15.0 dB)" in failure
    assert failure in missed_goals(data)
    row["references"]["physical"]["noise_floor_ok"] = True
    assert failure not in noise_floor_failures(data)


def test_json_and_html_carry_coverage_clipping_grazing_and_the_look_verdict(written, validation_run):
    from atlasgen.reports.validation import look_verdict

    out, result = written
    data = json.loads((out / "report.json").read_text())
    for row, run in zip(data["results"], validation_run.runs):
        for kind, ref in row["references"].items():
            m = run.references[kind].metrics
            assert ref["coverage"] == pytest.approx(m.coverage) and ref["clipped_pixels"] == m.clipped_pixels
            if kind in ("model", "physical"):
                assert set(ref["regions"]) == {"grazing", "rest"} and "whole_frame_psnr_db" in ref
        look = row["look"]
        assert look["goal"] == {
            "psnr_db": data["settings"]["goals"]["look_psnr_db"],
            "flip": data["settings"]["goals"]["look_flip"],
        }
        if look["reference"] is not None:
            judged = look_verdict(look, row["references"][look["reference"]])
            assert (look["meets_goal"], look["not_judged"]) == (judged["meets_goal"], judged["not_judged"])
    s = data["summary"]
    assert s["look_results"] == sum(1 for row in data["results"] if row["look"]["reference"] is not None)
    assert s["no_physical_reference"] == ["cel"]
    html = (out / "index.html").read_text()
    assert "N.V &lt; 0.2: PSNR / FLIP" in html and "whole-frame PSNR dB" in html and "coverage" in html


def test_a_comparison_split_by_object_reports_and_judges_each_part(written, validation_run):
    """Skin's sphere and flat part: each in report.json with its figures and noise floor, on the page, and
    judged apart: a flat part under the look goal makes the look miss on that scene, named with its figure,
    and a part short of its floor is named as such."""
    from atlasgen.reports.validation import describe_materials, look_verdict, missed_goals, noise_floor_failures

    out, _ = written
    data = json.loads((out / "report.json").read_text())
    rows = [row for row in data["results"] if row["material"] == "skin"]
    assert {row["scene"] for row in rows} == {"front", "back"}
    for row, run in (
        (row, next(r for r in validation_run.runs if (r.material, r.scene) == ("skin", row["scene"]))) for row in rows
    ):
        ref, own = row["references"]["physical"], run.references["physical"]
        assert set(ref["parts"]) == {"sphere", "flat part"}
        for name, part in ref["parts"].items():
            assert part["pixels"] == own.metrics.parts[name]["pixels"] > 0
            assert part["noise_floor_db"] == pytest.approx(own.part_floors[name])
            assert set(part) >= {"coverage", "psnr_db", "flip", "clipped_pixels", "unclipped_psnr_db", "noise_floor_ok"}
        assert any(note.startswith("the physical reference renders each object alone") for note in row["notes"])
    html = (out / "index.html").read_text(encoding="utf-8")
    assert "flat part: " in html and "sphere: " in html
    # The reference image's caption says how converged it is: its spp and floor, and each part's.
    for row in rows:
        ref = row["references"]["physical"]
        caption = (f"{ref['spp']} spp, noise floor {ref['noise_floor_db']:.1f} dB; "
                   + ", ".join(f"{n} {p['spp']} spp, {p['noise_floor_db']:.1f} dB" for n, p in ref["parts"].items()))  # fmt: skip
        assert f"{escape(ref['description'])} ({caption})</figcaption>" in html
        assert f"{escape(row['references']['model']['description'])}</figcaption>" in html  # exact: no spp
    # Make the front's reference converged, its whole comparison and sphere over the goal, its flat part under it.
    row = next(r for r in rows if r["scene"] == "front")
    ref = row["references"]["physical"]
    ref.update(psnr_db=33.0, flip=0.04, clipped_pixels=0, noise_floor_db=60.0, noise_floor_ok=True)
    ref["parts"]["sphere"].update(psnr_db=41.5, flip=0.03, clipped_pixels=0, noise_floor_db=60.0, noise_floor_ok=True)
    ref["parts"]["flat part"].update(psnr_db=27.3, flip=0.07, clipped_pixels=0, noise_floor_db=60.0, noise_floor_ok=True)
    verdict = look_verdict(row["look"], ref)
    assert verdict["meets_goal"] is False and verdict["parts"] == {
        "sphere": {"meets_goal": True, "not_judged": None},
        "flat part": {"meets_goal": False, "not_judged": None},
    }
    row["look"].update(verdict)
    (line,) = [x for x in describe_materials(data) if x.startswith("skin:")]
    assert line.startswith("skin: goals missed: look") and "missed on front (flat part)" in line
    assert "sphere: 41.5 / " in line and "flat part: 27.3 / " in line
    (miss,) = [m for m in missed_goals(data) if m.startswith("skin on front: look")]
    assert "sphere: PSNR 41.5 dB" in miss and "flat part: PSNR 27.3 dB, FLIP 0.0700 (missed)" in miss
    # The sphere short of its floor: the flat part's miss, against its own clear floor, still stands.
    ref["parts"]["sphere"].update(noise_floor_db=45.0, noise_floor_ok=False, spp=16)
    ref["noise_floor_ok"] = False
    assert look_verdict(row["look"], ref)["meets_goal"] is False
    # Both parts short of their floors: the look is not judged, and each part is named.
    ref["parts"]["flat part"].update(noise_floor_db=30.0, noise_floor_ok=False, spp=64)
    assert look_verdict(row["look"], ref)["not_judged"].endswith(
        "floor 60.0 dB (sphere: floor 45.0 dB at 16 spp, flat part: floor 30.0 dB at 64 spp)"
    )
    failures = [f for f in noise_floor_failures(data) if f.startswith("skin on front:")]
    assert len(failures) == 2 and any("flat part" in f for f in failures)
    failure = next(f for f in failures if "sphere" in f)
    assert "noise floor on the sphere 45.0 dB is not 10 dB above the PSNR it measures there (41.5 dB) at 16 spp" in failure


def test_the_report_is_the_same_bytes_from_whatever_folder_it_is_written(validation_run, tmp_path, monkeypatch):
    """report.json and the page gave the atlas path as typed: run from the atlas's folder ("atlas.dds") or from
    one below it ("../atlas.dds"), the same inputs wrote two reports. It is now given from the report's folder,
    as its images are."""
    from dataclasses import replace

    from atlasgen.reports.validation import write_validation

    (tmp_path / "sub").mkdir()
    written = []
    # The reference cache too (a hostile sweep): it was recorded as typed, a path from the working folder.
    for cwd, given, cache in ((tmp_path, "atlas.dds", "refcache"), (tmp_path / "sub", "../atlas.dds", "../refcache")):
        monkeypatch.chdir(cwd)
        out = tmp_path / f"report-{len(written)}"
        environment = {**validation_run.environment, "reference_cache": cache}
        write_validation(replace(validation_run, atlas=given, environment=environment), out)
        written.append({name: (out / name).read_bytes() for name in ("report.json", "index.html")})
    assert written[0] == written[1]
    assert json.loads(written[0]["report.json"])["atlas"] == "../atlas.dds"
    assert json.loads(written[0]["report.json"])["environment"]["reference_cache"] == "../refcache"
    assert b"Atlas <code>../atlas.dds</code>" in written[0]["index.html"]


def test_scenes_are_recorded_by_their_bytes_not_their_path(validation_run):
    """A scene's path as typed gave other bytes from another folder (a built-in scene's, from another clone), and a
    merge compared scenes by that path: one file spelt two ways was refused, and two contents at one path merged."""
    import hashlib

    import atlasgen

    (scene,) = [s for s in validation_run.settings["scenes"] if s["name"] == "front"]
    front = Path(atlasgen.__file__).parent / "data" / "validation" / "front.toml"
    assert set(scene) == {"name", "sha256", "width", "height"}
    assert scene["sha256"] == hashlib.sha256(front.read_bytes()).hexdigest()


# Material names as NAME_PATTERN has them (a letter, then letters, digits, _ and -) and scene names, both from
# small alphabets, so that runs of _ and . come up often.
_NAMES = st.builds(str.__add__, st.sampled_from("xyA"), st.text(alphabet="xy_-1", max_size=6))
_SCENES = st.text(alphabet="yz_.-", min_size=1, max_size=6)


@hypothesis.settings(max_examples=100, deadline=None)
@hypothesis.given(
    a=st.tuples(_NAMES, _SCENES), b=st.tuples(_NAMES, _SCENES), what=st.sampled_from(["atlas", "model", "flip-model"])
)
@hypothesis.example(a=("x", "y__z"), b=("x__y", "z"), what="atlas")
def test_two_results_never_share_an_image(a, b, what):
    """Material x on scene y__z and material x__y on scene z both wrote images/x__y__z__atlas.png: one row of the
    report showed the other material's render."""
    from atlasgen.reports.validation import image_name

    hypothesis.assume(a != b)
    assert image_name(*a, what) != image_name(*b, what)
