"""The typed manifest: round trips to the same bytes, the shipped JSON Schemas, and every refusal.

The schemas are checked with ``jsonschema``, an implementation that shares no code with
atlasgen's own reader, so the two must agree on what a valid manifest is.
"""

from __future__ import annotations

import copy
import gzip
import json
import re
from importlib.resources import files
from pathlib import Path

import jsonschema
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from atlasgen.cli.main import app
from atlasgen.contract import FORMAT_VERSION
from atlasgen.errors import InputError, ManifestError
from atlasgen.io.manifest import (
    BrdfError,
    Dimensions,
    ErrorSummary,
    Fit,
    LutRepresentation,
    Manifest,
    MaterialEntry,
    SeparableFactors,
    VolumeBleed,
    format_manifest,
    parse_manifest,
    read_manifest,
    read_slots,
    write_manifest,
)  # fmt: skip

GOLDEN = Path(__file__).resolve().parents[1] / "resources" / "golden"
VARIANTS = ("array-srgb", "volume-linear")


def _schema(name: str):
    schema = json.loads((files("atlasgen") / "schemas" / f"{name}.schema.json").read_text(encoding="utf-8"))
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def _golden(variant: str) -> dict:
    return json.loads((GOLDEN / f"{variant}.json").read_text(encoding="utf-8"))


def _lut_entry(name="clay", first=0, **kw) -> MaterialEntry:
    return MaterialEntry(name=name, id=first, constant=f"MATERIAL_{name.upper()}", first_slice=first, type="lambert",
                         source=f"materials/{name}.toml", params={"colour": [0.5, 0.5, 0.5]}, **kw)  # fmt: skip


def _manifest(*entries, **kw) -> Manifest:
    return Manifest(dimensions=Dimensions(width=64, height=32, layers=256, mip_count=7), encoding="srgb", dxgi_format=29,
                    materials=list(entries), **kw)  # fmt: skip


# ---- round trips ----------------------------------------------------------------------------------


@pytest.mark.parametrize("variant", VARIANTS)
def test_the_golden_manifests_are_reproduced_byte_for_byte(variant):
    path = GOLDEN / f"{variant}.json"
    assert format_manifest(read_manifest(path)) == path.read_text(encoding="utf-8")


@pytest.mark.parametrize("variant", VARIANTS)
def test_read_of_write_is_the_same_manifest(variant, tmp_path):
    manifest = read_manifest(GOLDEN / f"{variant}.json")
    assert read_manifest(write_manifest(manifest, tmp_path / "atlas.json")) == manifest
    assert Manifest.from_json(manifest.to_json()) == manifest


def test_the_golden_manifests_parse_into_the_typed_parts():
    manifest = read_manifest(GOLDEN / "array-srgb.json")
    gold = manifest.entry_named("separable-gold")
    assert gold.factors.parametrization == "half_diff" and gold.factors.target == "f_proxy"
    assert len(gold.factors.factor_scale) == gold.slice_count == gold.factors.terms == 4
    assert gold.factors.errors_8bit.relative_rms == gold.representation.estimated_error_8bit
    assert gold.factors.errors.float_error.relative_rms > 0 and gold.factors.errors.pairs > 0
    leaf = manifest.entry_named("leaf")
    assert leaf.factors is None and leaf.representation is None and leaf.extra == {}
    assert read_manifest(GOLDEN / "volume-linear.json").volume_bleed[0].level == 1


def test_helpers_find_entries_by_name_and_slice():
    manifest = _manifest(_lut_entry("a", 0), _lut_entry("b", 3, slice_count=2))
    assert manifest.entry_named("b").first_slice == 3 and manifest.entry_named("c") is None
    assert [manifest.by_slice(i) and manifest.by_slice(i).name for i in range(6)] == ["a", None, None, "b", "b", None]
    assert manifest.slices_used == 3 and manifest.names == ["a", "b"]
    assert manifest.entry_named("b").scale == [[1.0, 1.0], [1.0, 1.0]]


def test_the_typed_part_is_chosen_by_the_keys_present_not_the_type_name():
    golden = _golden("array-srgb")
    separable = next(e for e in golden["materials"] if "factor_scale" in e)
    renamed = {**separable, "type": "hologram"}
    assert MaterialEntry.from_json(renamed).factors == MaterialEntry.from_json(separable).factors
    plain = {k: v for k, v in separable.items() if k not in SeparableFactors.keys() and k != "representation"}
    assert MaterialEntry.from_json(plain).factors is None


def test_unknown_entry_keys_are_kept_in_order_and_written_back():
    data = _lut_entry().to_json()
    data["sheen"] = {"amount": 0.5}
    data["zz"] = [1, 2]
    entry = MaterialEntry.from_json(data)
    assert entry.extra == {"sheen": {"amount": 0.5}, "zz": [1, 2]}
    assert list(entry.to_json()) == list(data)


def test_model_fields_merge_in_place_and_become_typed():
    base = _lut_entry()
    representation = {"kind": "lut", "supersampling": 4, "error_budget": 0.01, "reconstruction_error": 0.004,
                      "meets_budget": True, "candidates": [{"supersampling": 1, "error": 0.02}]}  # fmt: skip
    merged = base.with_fields({"representation": representation, "quantization_error": {"max": 0.5, "rms": 0.25}})
    assert merged.representation == LutRepresentation(**representation)
    assert merged.quantization_error == ErrorSummary(max=0.5, rms=0.25)
    keys = list(merged.to_json())
    assert keys.index("quantization_error") == keys.index("clamped_fraction") + 1 and keys[-1] == "representation"


def test_a_fit_description_becomes_typed_and_round_trips_in_order():
    fit = {"from": "physical", "reference": "roughplastic", "gloss": 0.45, "azimuths": 128, "relative_rms": 0.02}
    merged = _lut_entry().with_fields({"fit": fit})
    assert merged.fit == Fit(source="physical", gloss=0.45, details=fit) and merged.extra == {}
    assert merged.to_json()["fit"] == fit and list(merged.to_json()["fit"]) == list(fit)
    written = _manifest(merged, atlas_sha256="0" * 64).to_json()
    assert list(_schema("manifest").iter_errors(written)) == []
    written["materials"][0]["fit"]["gloss"] = 2.0
    assert list(_schema("manifest").iter_errors(written)) != []


_numbers = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False) | st.integers(-1000, 1000)


@st.composite
def _manifests(draw):
    entries, first = [], 0
    for i in range(draw(st.integers(0, 4))):
        n = draw(st.integers(1, 3))
        factors = None
        if draw(st.booleans()):
            table = st.lists(st.lists(st.lists(_numbers, min_size=3, max_size=3), min_size=2, max_size=2), min_size=n, max_size=n)
            factors = SeparableFactors(
                parametrization=draw(st.sampled_from(["half_diff", "in_out"])),
                target=draw(st.sampled_from(["f_cos", "f_proxy"])),
                terms=draw(st.none() | st.just(n)),
                factor_scale=draw(table), factor_bias=draw(table),
                max_error=draw(st.none() | st.floats(0.001, 1.0)),
                errors_8bit=draw(st.none() | st.builds(BrdfError, relative_rms=_numbers, log_error=_numbers)),
            )  # fmt: skip
        pair = st.lists(_numbers, min_size=2, max_size=2)
        scale_pair = st.lists(st.floats(min_value=1e-30, max_value=1e6) | st.integers(1, 1000), min_size=2, max_size=2)
        entries.append(MaterialEntry(
            name=f"m{i}", id=first, constant=f"MATERIAL_M{i}", first_slice=first, slice_count=n,
            type=draw(st.sampled_from(["lambert", "separable", "toon"])), description=draw(st.text(max_size=8)),
            scale=draw(st.lists(scale_pair, min_size=n, max_size=n)), bias=draw(st.lists(pair, min_size=n, max_size=n)),
            flags=draw(st.dictionaries(st.sampled_from(["outline", "nearest"]), st.booleans())),
            clamped_fraction=draw(st.floats(0.0, 1.0)), factors=factors,
            quantization_error=ErrorSummary(max=draw(st.floats(0, 10)), rms=draw(st.floats(0, 10))),
        ))  # fmt: skip
        first += n + draw(st.integers(0, 2))
    bleed = draw(
        st.none()
        | st.lists(st.builds(VolumeBleed, level=st.integers(1, 8), max=st.floats(0, 2), rms=st.floats(0, 2)), max_size=3)
    )
    return _manifest(*entries, volume_bleed=bleed, atlas_sha256=draw(st.text("0123456789abcdef", min_size=64, max_size=64)))


@settings(max_examples=60, deadline=None)
@given(_manifests())
@pytest.mark.slow
def test_any_manifest_round_trips_through_its_text(manifest):
    text = format_manifest(manifest)
    back = parse_manifest(text)
    assert back == manifest
    assert format_manifest(back) == text
    assert list(_schema("manifest").iter_errors(json.loads(text))) == []


# ---- schemas -------------------------------------------------------------------------------------


@pytest.mark.parametrize("variant", VARIANTS)
def test_golden_manifests_validate_against_the_schema(variant):
    assert list(_schema("manifest").iter_errors(_golden(variant))) == []


@pytest.mark.slow
def test_a_budgeted_lut_manifest_validates_against_the_schema(tmp_path, write_material):
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_materials

    write_material("a", 'type = "lambert"\nerror_budget = 0.02\n')
    manifest = bake_atlas(read_materials([tmp_path / "materials"])).manifest
    assert isinstance(manifest.materials[0].representation, LutRepresentation)
    manifest.atlas_sha256 = "0" * 64  # the hash of the texture, filled in as the pair is written
    assert list(_schema("manifest").iter_errors(json.loads(format_manifest(manifest)))) == []


@pytest.mark.parametrize("lut", [False, True], ids=["by cost", "representation lut"])
def test_an_auto_record_is_read_and_validates_against_the_schema(tmp_path, lut):
    """Both records the separable model writes: a choice by run-time cost (the cost table's device and unit, each
    candidate's cost) and a representation = "lut" bake's one candidate, with no cost."""
    auto = copy.deepcopy(AUTO)
    if lut:
        del auto["cost_device"], auto["cost_unit"]
        auto["candidates"] = [{k: v for k, v in auto["candidates"][0].items() if k != "cost"}]
        auto["chosen"] = "lut"
    data = _with(_auto(lambda a: (a.clear(), a.update(auto))))
    path = tmp_path / "atlas.json"
    path.write_text(json.dumps(data))
    assert read_manifest(path).materials[5].representation.auto == auto
    assert list(_schema("manifest").iter_errors(data)) == []


@pytest.mark.parametrize("variant", VARIANTS)
def test_info_json_of_the_golden_atlases_validates_against_its_schema(variant, tmp_path):
    dds = tmp_path / f"{variant}.dds"
    dds.write_bytes(gzip.decompress((GOLDEN / f"{variant}.dds.gz").read_bytes()))
    runner = CliRunner()
    without = runner.invoke(app, ["info", str(dds), "--format", "json"])
    (tmp_path / f"{variant}.json").write_bytes((GOLDEN / f"{variant}.json").read_bytes())
    res = runner.invoke(app, ["info", str(dds), "--format", "json"])
    assert without.exit_code == 0 and res.exit_code == 0, (without.output, res.output)
    validator = _schema("info")
    assert list(validator.iter_errors(json.loads(without.output))) == []
    data = json.loads(res.output)
    assert list(validator.iter_errors(data)) == []
    assert [m["name"] for m in data["manifest"]["materials"]] == [m["name"] for m in _golden(variant)["materials"]]


def test_the_schemas_are_package_data():
    import fnmatch
    import tomllib

    config = tomllib.loads((Path(__file__).resolve().parents[2] / "pyproject.toml").read_text(encoding="utf-8"))
    patterns = config["tool"]["setuptools"]["package-data"]["atlasgen"]
    for name in ("info.schema.json", "manifest.schema.json"):
        assert any(fnmatch.fnmatch(f"schemas/{name}", pattern) for pattern in patterns), name
    assert sorted(p.name for p in (files("atlasgen") / "schemas").iterdir() if p.name.endswith(".json")) == [
        "info.schema.json",
        "manifest.schema.json",
    ]


# ---- refusals ------------------------------------------------------------------------------------


def _refusal(tmp_path, content, name="atlas.json") -> str:
    path = tmp_path / "build" / name
    path.parent.mkdir(exist_ok=True)
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content if isinstance(content, str) else json.dumps(content))
    with pytest.raises(ManifestError) as info:
        read_manifest(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(path.as_posix() + ": "), message
    return message


def _with(change) -> dict:
    data = copy.deepcopy(_golden("array-srgb"))
    change(data)
    return data


def _set(path, value):
    def change(data):
        target = data
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value

    return change


#: A whole ``representation = "auto"`` record, on the golden's separable entry: the cases below damage one part.
AUTO = {"error_budget": 0.04, "cost_device": "llvmpipe", "cost_unit": "ns per pixel per light", "chosen": "separable:2",
        "candidates": [{"representation": "lut", "cost": 11.2, "error": 0.2, "meets_budget": False},
                       {"representation": "separable:2", "cost": 21.9, "error": 0.02, "error_se": 0.001,
                        "meets_budget": True}]}  # fmt: skip


def _auto(change=None):
    def edit(data):
        auto = copy.deepcopy(AUTO)
        if change is not None:
            change(auto)
        data["materials"][5]["representation"]["auto"] = auto

    return edit


REFUSED = {
    "a list": ([], None, "expected an atlas manifest (a JSON object), got an empty list"),
    "empty object": ({}, "format_version", f"missing; expected format version {FORMAT_VERSION}"),
    "materials not a list": ({"format_version": FORMAT_VERSION, "materials": 5}, "dimensions", "missing"),
    "newer version": (
        _with(_set(["format_version"], FORMAT_VERSION + 1)),
        "format_version",
        "the file is newer than this atlasgen",
    ),
    "older version": (
        _with(_set(["format_version"], FORMAT_VERSION - 1)),
        "format_version",
        f"expected format version {FORMAT_VERSION} (the file is from an older atlasgen: re-bake the atlas "
        f"with this one), got {FORMAT_VERSION - 1}",
    ),
    "version 0": (
        _with(_set(["format_version"], 0)),
        "format_version",
        f"expected format version {FORMAT_VERSION} (an integer), got 0",
    ),
    "version string": (_with(_set(["format_version"], "1")), "format_version", 'got "1"'),
    "unknown top-level": (_with(_set(["extras"], 1)), "extras", "unknown field"),
    "materials a number": (_with(_set(["materials"], 5)), "materials", "expected a list of material objects, got 5"),
    "entry not an object": (_with(_set(["materials", 2], "leaf")), "materials[2]", "expected a JSON object"),
    "negative slice": (
        _with(_set(["materials", 3, "first_slice"], -1)),
        "materials[3].first_slice",
        "expected an integer >= 0, got -1",
    ),
    "id not first slice": (
        _with(_set(["materials", 3, "id"], 9)),
        "materials[3].id",
        "expected the entry's first_slice (3), got 9",
    ),
    "missing name": (_with(lambda d: d["materials"][1].pop("name")), "materials[1].name", "missing; expected a material name"),
    "bad scale": (_with(_set(["materials", 0, "scale"], [[1.0]])), "materials[0].scale[0]", "[rgb, alpha] pair"),
    "flag not bool": (
        _with(_set(["materials", 0, "flags"], {"outline": 1})),
        "materials[0].flags.outline",
        "expected true or false, got 1",
    ),
    "factor table": (
        _with(_set(["materials", 5, "factor_bias"], [[0, 0]] * 4)),
        "materials[5].factor_bias[0]",
        "[[r, g, b], [r, g, b]]",
    ),
    "factors without scale": (_with(lambda d: d["materials"][5].pop("factor_scale")), "materials[5].factor_scale", "missing"),
    "bad representation": (
        _with(_set(["materials", 5, "representation"], {"kind": "x"})),
        "materials[5].representation",
        "expected a LUT",
    ),
    "fit gloss": (
        _with(_set(["materials", 0, "fit"], {"from": "physical", "gloss": 1.5})),
        "materials[0].fit.gloss",
        "expected a number in [0, 1], got 1.5",
    ),
    "fit source": (
        _with(_set(["materials", 0, "fit"], {"from": "closed-form", "gloss": 0.5})),
        "materials[0].fit.from",
        "one of 'physical', 'bsdf', 'auto'",
    ),
    "transmission not an object": (_with(_set(["materials", 5, "transmission"], 3)), "materials[5].transmission", "an object"),
    "transmission slice": (
        _with(_set(["materials", 5, "transmission"], {"slice": 1})),
        "materials[5].transmission.slice",
        "expected 3 (the entry's last slice, after its terms), got 1",
    ),
    "encoding": (_with(_set(["encoding"], "hdr")), "encoding", "one of 'srgb', 'linear'"),
    # It said "expected 0 (the entry's last slice, after its terms), got 0".
    "transmission of a one-slice entry": (
        _with(
            lambda d: d["materials"][5].update(
                slice_count=1, transmission={"slice": 0}, factor_scale=[], factor_bias=[], scale=[[1.0, 1.0]], bias=[[0.0, 0.0]]
            )
        ),
        "materials[5].transmission",
        "expected an entry of at least 2 slices (a term and this one), got slice_count 1",
    ),
    "scale beyond float32": (
        _with(_set(["materials", 0, "scale"], [[1e39, 1.0]])),
        "materials[0].scale[0]",
        "an [rgb, alpha] pair of numbers above 0 that float32 holds, got [1e+39, 1.0]",
    ),
    "zero scale": (
        _with(_set(["materials", 0, "scale"], [[0.0, 1.0]])),
        "materials[0].scale[0]",
        "an [rgb, alpha] pair of numbers above 0 that float32 holds, got [0.0, 1.0]",
    ),
    "negative scale": (
        _with(_set(["materials", 0, "scale"], [[1.0, -0.5]])),
        "materials[0].scale[0]",
        "an [rgb, alpha] pair of numbers above 0 that float32 holds, got [1.0, -0.5]",
    ),
    "constant not an identifier": (
        _with(_set(["materials", 0, "constant"], "X; } fn evil() {")),
        "materials[0].constant",
        "expected a shader identifier",
    ),
    # Python's JSON reader takes these; neither is a figure the bake writes or a reader can use.
    "not a finite figure": (
        json.dumps(_with(_set(["materials", 0, "quantization_error", "max"], float("inf")))),
        "materials[0].quantization_error.max",
        "expected a finite number >= 0, got inf",
    ),
    "an integer just beyond a double": (
        json.dumps(_golden("array-srgb")).replace('"scale": [[', f'"scale": [[{2**1024 - 1}, ', 1),
        None,
        "malformed JSON (an integer of 309 digits, beyond any number a double holds)",
    ),
    "an integer beyond a double": (
        json.dumps(_golden("array-srgb")).replace('"scale": [[', '"scale": [[1' + "0" * 400 + ", ", 1),
        None,
        "malformed JSON (an integer of 401 digits, beyond any number a double holds)",
    ),
    "a lone surrogate": (
        json.dumps(_with(_set(["materials", 0, "type"], "lam" + chr(0xD800) + "bert"))),  # written as "lam\ud800bert"
        None,
        "holds a lone UTF-16 surrogate, which is no text",
    ),
    "dxgi mismatch": (_with(_set(["dxgi_format"], 28)), "dxgi_format", "29 (the DXGI format of srgb encoding), got 28"),
    # The includes declare each constant in three languages beside their own functions: a keyword, an include
    # function's name or another material's constant failed the renderer's shader compile (exit 1).
    "constant not the name's": (
        _with(_set(["materials", 1, "constant"], "atlas_sample")),
        "materials[1].constant",
        "(MATERIAL_ and the name in capitals, other characters as '_'), got 'atlas_sample'",
    ),
    "two names, one constant": (
        _with(lambda d: [d["materials"][i].update(name=n, constant="MATERIAL_X_Y") for i, n in ((0, "x-y"), (1, "x_y"))]),
        "materials[1].constant",
        "expected a constant of its own, got 'MATERIAL_X_Y', also 'x-y''s",
    ),
    # An engine that loops over 'terms' factor pairs read one slice of the next material.
    "terms not the term slices": (
        _with(_set(["materials", 5, "terms"], 5)),
        "materials[5].terms",
        "expected 4, the entry's term slices (slice_count), got 5",
    ),
    "terms counting the transmission slice": (
        _with(
            lambda d: d["materials"][5].update(
                transmission={"slice": 3},
                terms=4,
                factor_scale=d["materials"][5]["factor_scale"][:3],
                factor_bias=d["materials"][5]["factor_bias"][:3],
            )
        ),
        "materials[5].terms",
        "expected 3, the entry's term slices (slice_count less the transmission slice), got 4",
    ),
    # The library report charts these: "x" or null in one was an internal error there.
    "a candidate's error that is text": (
        _with(_set(["materials", 5, "representation", "candidates", 0, "relative_rms_by_terms", 2], "x")),
        "materials[5].representation.candidates[0].relative_rms_by_terms",
        "expected a list of finite numbers of at least 0, one per K, got [",
    ),
    "a candidate's negative standard error": (
        _with(_set(["materials", 5, "representation", "candidates", 0, "relative_rms_se_by_terms", 0], -0.5)),
        "materials[5].representation.candidates[0].relative_rms_se_by_terms",
        "expected a list of finite numbers of at least 0",
    ),
    # Named by the flag itself: the whole object was "expected an object of true/false flags, got an object".
    "a flag that is text": (
        _with(_set(["materials", 0, "flags"], {"outline": "yes"})),
        "materials[0].flags.outline",
        'expected true or false, got "yes"',
    ),
    # The library report read these (a KeyError, a TypeError, a log axis of NaN: internal errors).
    "auto without candidates": (
        _with(_auto(lambda a: a.pop("candidates"))),
        "materials[5].representation.auto.candidates",
        "missing; expected a list of objects",
    ),
    "auto candidates as text": (
        _with(_auto(lambda a: a.update(candidates="xyz"))),
        "materials[5].representation.auto.candidates",
        'expected a list of objects, got "xyz"',
    ),
    "auto candidate without a representation": (
        _with(_auto(lambda a: a["candidates"][0].pop("representation"))),
        "materials[5].representation.auto.candidates[0].representation",
        "missing; expected a non-empty string",
    ),
    "auto candidate's negative cost": (
        _with(_auto(lambda a: a["candidates"][1].update(cost=-1))),
        "materials[5].representation.auto.candidates[1].cost",
        "expected a finite number >= 0, got -1",
    ),
    "auto chosen no candidate": (
        _with(_auto(lambda a: a.update(chosen="separable:9"))),
        "materials[5].representation.auto.chosen",
        'expected one of its candidates\' representations, got "separable:9"',
    ),
    # Validation's look goal (a ValueError or TypeError there).
    "look goal as text": (
        _with(_set(["materials", 0, "validate"], "abc")),
        "materials[0].validate",
        'expected an object, got "abc"',
    ),
    "look goal psnr as text": (
        _with(_set(["materials", 0, "validate"], {"psnr_db": "x"})),
        "materials[0].validate.psnr_db",
        'expected a finite number > 0 (dB), got "x"',
    ),
    "look goal's unknown key": (
        _with(_set(["materials", 0, "validate"], {"gain": 2})),
        "materials[0].validate.gain",
        "unknown key; expected a look goal's psnr_db and/or flip",
    ),
    # info -v's realpath of a 1.6 MB path took minutes.
    "a source beyond PATH_MAX": (
        _with(_set(["materials", 0, "source"], "a/" * 2100 + "x.toml")),
        "materials[0].source",
        "expected a material file's path (no NUL character) of at most 4096 bytes",
    ),
    "factor beyond float32": (
        _with(_set(["materials", 5, "factor_scale", 0, 1, 2], 1e300)),
        "materials[5].factor_scale[0]",
        "per-channel values, each a float32, got [[",
    ),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_each_refusal_is_one_line_naming_the_file_and_the_field(case, tmp_path):
    content, field, expected = REFUSED[case]
    message = _refusal(tmp_path, content)
    if field is not None:
        assert f": field '{field}': " in message, message
    assert expected in message, message


#: What the schema cannot say: id = first_slice, the DXGI/encoding pairing and the transmission slice's place,
#: and what JSON itself cannot hold (Python's reader takes Infinity, a 400-digit integer and a lone surrogate).
_BEYOND_THE_SCHEMA = {"id not first slice", "auto chosen no candidate", "dxgi mismatch", "transmission slice", "transmission of a one-slice entry",
                      "constant not the name's", "two names, one constant",
                      "terms not the term slices", "terms counting the transmission slice",
                      "not a finite figure",
                      "an integer beyond a double", "an integer just beyond a double", "a lone surrogate"}  # fmt: skip


@pytest.mark.parametrize("case", sorted(set(REFUSED) - _BEYOND_THE_SCHEMA))
def test_the_schema_refuses_what_the_reader_refuses(case):
    content = REFUSED[case][0]
    assert list(_schema("manifest").iter_errors(content)) != []


def test_the_schema_names_the_parametrizations_and_targets_the_rebuild_knows():
    """The schema is hand-written; the separable model refuses a name its rebuild lacks (parametrization, target)."""
    from atlasgen.separable.parametrization import PARAMETRIZATIONS
    from atlasgen.shaders.separable import TARGETS

    entry = _schema("manifest").schema["$defs"]["material"]["properties"]
    assert (entry["parametrization"]["enum"], entry["target"]["enum"]) == (list(PARAMETRIZATIONS), list(TARGETS))


def test_a_transmission_slice_is_the_last_slice_and_the_terms_are_the_rest():
    """With ``transmission``, factor_scale and factor_bias hold one entry per term: all slices but the last."""

    def add(data):
        entry = data["materials"][5]
        entry["factor_scale"], entry["factor_bias"] = entry["factor_scale"][:-1], entry["factor_bias"][:-1]
        entry["terms"] = entry["slice_count"] - 1  # as the bake writes it: K terms, then the transmission slice
        entry["transmission"] = {
            "slice": entry["slice_count"] - 1,
            "pairs": 10,
            "seed": 1,
            "estimator": "x",
            "errors_8bit_sphere": {"relative_rms": 0.1, "relative_rms_se": 0.01, "log_error": 0.2},
        }

    data = _with(add)
    entry = MaterialEntry.from_json(data["materials"][5])
    assert entry.factors.term_slices == entry.slice_count - 1 == entry.factors.transmission.slice
    assert entry.factors.transmission.errors_8bit_sphere.relative_rms == 0.1
    assert entry.to_json() == data["materials"][5]
    assert list(_schema("manifest").iter_errors(data)) == []
    # Without the record the same scales are one short of the slices.
    with pytest.raises(ManifestError, match=r"factor_scale.*a list of 4"):
        MaterialEntry.from_json({k: v for k, v in data["materials"][5].items() if k != "transmission"})


def test_slices_must_lie_in_the_atlas_and_not_overlap(tmp_path):
    def move(i, first):
        def change(data):
            data["materials"][i]["first_slice"] = data["materials"][i]["id"] = first

        return _with(change)

    # A first slice outside the atlas is named as such (it named slice_count, even at 2^64).
    for first in (256, 2**64):
        assert f"field 'materials[11].first_slice': expected a slice of the atlas's 256 layers (0..255), got {first}" in (
            _refusal(tmp_path, move(11, first)))  # fmt: skip
    message = _refusal(tmp_path, move(4, 5))
    assert "field 'materials[5].first_slice'" in message and "and 'red-plastic' holds slice 5" in message
    assert "expected each material once" in _refusal(tmp_path, _with(_set(["materials", 1, "name"], "beetle-shell")))
    # A name is the material's shader identifier too: a tampered one is refused, shown escaped on the one line.
    message = _refusal(tmp_path, _with(_set(["materials", 1, "name"], "a\n\u0000b")))
    assert "field 'materials[1].name': expected a material name (a letter, then letters" in message


@pytest.mark.parametrize(("materials", "field", "expected"), [
    ([{"name": "a", "first_slice": 300}], "materials[0].first_slice", "expected a slice of the atlas's 256 layers (0..255), got 300"),
    ([{"name": "a", "first_slice": 1}, {"name": "a", "first_slice": 2}], "materials[1].name",
     "expected each material once, got 'a' twice"),
    ([{"name": "a", "first_slice": 1}, {"name": "b", "first_slice": 1}], "materials[1].first_slice",
     "expected slices of its own, got 1 (slice_count 1), and 'a' holds slice 1"),
    # A run's slices, not its first alone: a 4-slice material at 254 was moved to 1..4 without a word, and one run
    # reaching into the next moved that one.
    ([{"name": "a", "first_slice": 254, "slice_count": 4}], "materials[0].slice_count",
     "expected an integer from 1 to 2 (the slices from 254 to the atlas's last), got 4"),
    ([{"name": "a", "first_slice": 0, "slice_count": -5}], "materials[0].slice_count", "got -5"),
    ([{"name": "a", "first_slice": 0, "slice_count": "x"}], "materials[0].slice_count", 'got "x"'),
    ([{"name": "a", "first_slice": 0, "slice_count": 4}, {"name": "b", "first_slice": 2}], "materials[1].first_slice",
     "expected slices of its own, got 2 (slice_count 1), and 'a' holds slice 2"),
    # An edited id was kept silently, the material placed by its first_slice (the full reader refuses it).
    ([{"name": "a", "id": 3, "first_slice": 7}], "materials[0].id", "expected the entry's first_slice (7), got 3"),
], ids=["slice beyond the atlas", "a name twice", "a slice twice", "a run beyond the atlas", "a negative count",
        "a count no number", "runs overlapping", "an id not its first slice"])  # fmt: skip
def test_ids_to_keep_are_ids_an_atlas_can_hold(tmp_path, materials, field, expected):
    """``--ids-from`` (and the atlas's own manifest) read names and slices only, of any format version;
    a slice 300 was silently dropped (the material renumbered) and a name given twice kept its last slice."""
    path = tmp_path / "atlas.json"
    path.write_text(json.dumps({"format_version": 1, "materials": materials}))
    with pytest.raises(ManifestError, match=re.escape(f"field '{field}': ") + ".*" + re.escape(expected)):
        read_slots(path)
    path.write_text(
        json.dumps({"format_version": 1, "materials": [{"name": "a", "first_slice": 255}, {"name": "b", "first_slice": 0}]})
    )
    assert read_slots(path) == {"a": 255, "b": 0}


@pytest.mark.parametrize("data", [[1, 2], "str", 3, None])
def test_ids_to_keep_come_from_a_json_object(tmp_path, data):
    """A list or a string said "field 'materials': expected a list of materials, got null"."""
    path = tmp_path / "atlas.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ManifestError, match=re.escape("atlas.json: expected an atlas manifest (a JSON object), got ")):
        read_slots(path)


def test_a_file_that_is_not_json_or_not_a_file(tmp_path):
    assert "got malformed JSON (Expecting value" in _refusal(tmp_path, "not json")
    # Nested past Python's recursion limit: a malformed file too, not a RecursionError (exit 1, "a bug").
    deep = "[" * 100000 + "]" * 100000
    assert "got malformed JSON (arrays or objects nested too deeply to read)" in _refusal(tmp_path, deep)
    (tmp_path / "build" / "atlas.json").write_text(deep)
    with pytest.raises(ManifestError, match="nested too deeply"):
        read_slots(tmp_path / "build" / "atlas.json")
    assert "UTF-8" in _refusal(tmp_path, b"\xff\xfe{}")
    # A key twice: Python's decoder kept the last, so a hand-edited encoding was read as the other one without a word.
    twice = '{"format_version": 1, "encoding": "linear", "encoding": "srgb", "materials": []}'
    assert "got malformed JSON (the key 'encoding' appears twice in one object; expected each key once)" in _refusal(
        tmp_path, twice
    )
    with pytest.raises(ManifestError, match=r"build: expected an atlas manifest \(a UTF-8 JSON file\), got a directory"):
        read_manifest(tmp_path / "build")
    with pytest.raises(InputError, match="nope.json: no such manifest"):
        read_manifest(tmp_path / "nope.json")


def test_info_refuses_a_corrupt_manifest_beside_the_atlas_in_one_line(tmp_path):
    dds = tmp_path / "atlas.dds"
    dds.write_bytes(gzip.decompress((GOLDEN / "array-srgb.dds.gz").read_bytes()))
    (tmp_path / "atlas.json").write_text(json.dumps(_with(_set(["format_version"], FORMAT_VERSION + 1))))
    res = CliRunner().invoke(app, ["info", str(dds)])
    assert res.exit_code == InputError.exit_code
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and "atlas.json: field 'format_version'" in lines[0], res.output


def test_the_schema_s_name_pattern_is_the_contract_s():
    from atlasgen.contract import NAME_PATTERN

    assert _schema("manifest").schema["$defs"]["material"]["properties"]["name"]["pattern"] == NAME_PATTERN.pattern


def test_a_manifest_over_the_size_limit_is_refused_before_it_is_read(tmp_path, monkeypatch):
    """A 100 MB manifest took 10 s and 0.66 GB to read; one over MAX_MANIFEST_BYTES is refused on one line by every
    reader of manifests (read_manifest, read_slots, read_atlas), the size taken before the text is read."""
    from atlasgen.io import manifest as manifest_module
    from atlasgen.io.manifest import read_slots

    monkeypatch.setattr(manifest_module, "MAX_MANIFEST_BYTES", 100)
    path = tmp_path / "x.json"
    path.write_text("{" + " " * 100 + "}")
    expected = f"{path.as_posix()}: expected an atlas manifest (a UTF-8 JSON file), at most 100 bytes, got 102 bytes"
    for read in (manifest_module.read_manifest, read_slots):
        with pytest.raises(ManifestError) as info:
            read(path)
        assert str(info.value) == expected
