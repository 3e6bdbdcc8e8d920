"""The bake pipeline: closed-form slices, scales, clamping, stable IDs and determinism."""

import json

import numpy as np
import pytest

from atlasgen.bake.pipeline import bake_atlas, read_previous_slots, sibling_paths, write_bake
from atlasgen.contract import texel_grid
from atlasgen.errors import InputError, MaterialError
from atlasgen.io.manifest import format_manifest
from atlasgen.materials.material import read_materials
from atlasgen.models.base import SliceSet
from atlasgen.optics.quantize import unorm_scale
from tests.dds_reader import parse, srgb_to_linear


def bake_folder(folder, **options):
    return bake_atlas(read_materials([folder]), **options)


@pytest.mark.parametrize("linear", [False, True])
def test_lambert_slice_matches_closed_form_within_half_lsb(tmp_path, write_material, linear):
    colour = (0.8, 0.5, 0.25)
    write_material("clay", f'type = "lambert"\ncolour = {list(colour)}\n')
    out = tmp_path / "a.dds"
    result = bake_folder(tmp_path / "materials", linear=linear)
    write_bake(result, out)
    texels = parse(out.read_bytes())["levels"][0][0].astype(np.float64) / 255
    nl, _ = texel_grid()
    # Stored over the slice's RGB peak, 0.8 (its scale): every code of the slice's range is used.
    scale = result.manifest.materials[0].scale[0][0]
    assert scale == unorm_scale(0.8) and abs(scale - 0.8) < 1e-7
    expected = np.maximum(nl, 0)[..., None] * np.array(colour) / scale
    if linear:
        assert np.abs(texels[..., :3] - expected).max() <= 0.5 / 255 + 1e-12
    else:
        # Half an LSB in the stored (sRGB) code, which is what 8 bits can promise.
        code = np.where(expected <= 0.0031308, 12.92 * expected, 1.055 * expected ** (1 / 2.4) - 0.055)
        assert np.abs(texels[..., :3] - code).max() <= 0.5 / 255 + 1e-12
        assert np.abs(srgb_to_linear(texels[..., :3]) - expected).max() < 0.0075 / scale
    assert np.all(texels[..., 3] == 0)


class Bright:
    """A stand-in model whose alpha reaches 25 (F/F0 at grazing for F0 = 0.04)."""

    def bake_values(self):
        nl, nv = texel_grid()
        rgba = np.zeros(nl.shape + (4,))
        rgba[..., :3] = 0.5
        rgba[..., 3] = 1 + 24 * (1 - nv) ** 5
        return rgba


def test_values_above_one_get_a_slice_scale_and_nothing_clamps(tmp_path, write_material, monkeypatch):
    write_material("bright", 'type = "lambert"\n')
    from atlasgen.models.lambert import Lambert

    values = Bright().bake_values()
    monkeypatch.setattr(Lambert, "bake", lambda self, v: SliceSet(values[None].copy()))
    result = bake_folder(tmp_path / "materials", linear=True)
    entry = result.manifest.materials[0]
    assert entry.scale[0] == [0.5, 25.0]  # each at its peak: RGB 0.5 spends every code too
    assert entry.clamped_fraction == 0.0
    decoded = result.levels[0][0, ..., 3] / 255 * 25.0
    assert np.abs(decoded - values[..., 3]).max() <= 0.5 / 255 * 25 + 1e-9
    assert entry.quantization_error.max <= 0.5 / 255 * 25 + 1e-9
    assert not result.warnings


def test_the_quantization_error_is_the_max_and_rms_of_a_known_error_pattern(tmp_path, write_material, monkeypatch):
    """Every texel holds an 8-bit code plus a known offset (0.3 of a code on a quarter of them, 0
    elsewhere; the peak, 1, sets the scale to 1), stored linearly: the manifest's
    quantization_error is then max = 0.3 / 255 and rms = sqrt(mean(offset^2)) / 255, not the mean."""
    write_material("pattern", 'type = "lambert"\n')
    from atlasgen.models.lambert import Lambert

    nl, _ = texel_grid()
    rows, columns = np.indices(nl.shape)
    codes = (rows * 64 + columns) * 7 % 255
    offset = np.where((rows + columns) % 4 == 0, 0.3, 0.0)
    offset[0, 0], codes[0, 0] = 0.0, 255
    values = np.repeat(((codes + offset) / 255)[..., None], 4, axis=-1)
    monkeypatch.setattr(Lambert, "bake", lambda self, v: SliceSet(values[None].copy()))
    result = bake_folder(tmp_path / "materials", linear=True)
    entry = result.manifest.materials[0]
    assert entry.scale[0] == [1.0, 1.0]
    np.testing.assert_array_equal(result.levels[0][0], np.repeat(codes[..., None], 4, axis=-1))
    assert entry.quantization_error.max == pytest.approx(0.3 / 255, rel=1e-6)
    assert entry.quantization_error.rms == pytest.approx(np.sqrt(np.mean(offset**2)) / 255, rel=1e-6)
    assert entry.quantization_error.rms != pytest.approx(np.mean(offset) / 255, rel=0.1)


def test_fixed_scale_clamps_and_reports_the_fraction(tmp_path, write_material, monkeypatch):
    write_material("bright", 'type = "lambert"\nalpha_scale = 2.0\n')
    from atlasgen.models.lambert import Lambert

    values = Bright().bake_values()
    monkeypatch.setattr(Lambert, "bake", lambda self, v: SliceSet(values[None].copy()))
    result = bake_folder(tmp_path / "materials")
    entry = result.manifest.materials[0]
    expected = float((values[..., 3] > 2.0).sum()) / values.size
    assert entry.clamped_fraction == pytest.approx(expected)
    # A material warning (bake --strict refuses it), not one of the bake's general ones.
    (warning,) = result.material_warnings
    assert result.warnings == [] and warning.cause == "clamped to the scale" and warning.figure == entry.clamped_fraction
    assert "'bright'" in str(warning) and "clamped" in str(warning)


def test_manifest_records_contract_and_materials(tmp_path, write_material):
    path = write_material("clay", 'type = "lambert"\ncolour = "#808080"\n')
    result = bake_folder(tmp_path / "materials")
    m = result.manifest
    assert m.dimensions.to_json() == {"width": 64, "height": 32, "layers": 256, "mip_count": 7}
    assert m.encoding == "srgb" and m.layout == "array" and "u" in m.mapping
    e = m.materials[0]
    import hashlib

    assert e.content_hash == hashlib.sha256(path.read_bytes()).hexdigest()
    assert e.params["colour"] == pytest.approx([float(srgb_to_linear(128 / 255))] * 3)
    assert e.first_slice == 0 and e.slice_count == 1 and e.type == "lambert"
    assert "bake_s" in result.timings["materials"]["clay"]
    assert "timings" not in format_manifest(m)


def test_same_inputs_give_byte_identical_outputs(tmp_path, write_material):
    write_material("a", 'type = "lambert"\ncolour = [0.3, 0.6, 0.9]\n')
    write_material("b", 'type = "lambert"\nid = 200\n')
    outputs = []
    for run in range(2):
        out = tmp_path / f"run{run}" / "atlas.dds"
        paths = write_bake(bake_folder(tmp_path / "materials"), out)
        outputs.append({k: paths[k].read_bytes() for k in ("dds", "manifest", "include")})
    assert outputs[0] == outputs[1]


def test_ids_stay_stable_when_materials_are_added_and_removed(tmp_path, write_material):
    folder = tmp_path / "materials"
    for name in ("b", "d"):
        write_material(name, 'type = "lambert"\n')
    out = tmp_path / "atlas.dds"
    write_bake(bake_folder(folder), out)
    before = read_previous_slots(sibling_paths(out)["manifest"])
    assert before == {"b": 0, "d": 1}
    (folder / "b.toml").unlink()
    write_material("a", 'type = "lambert"\n')  # sorts first; must not take d's slice
    write_material("c", 'type = "lambert"\n')
    previous = read_previous_slots(sibling_paths(out)["manifest"])
    write_bake(bake_folder(folder, previous_slots=previous), out)
    after = read_previous_slots(sibling_paths(out)["manifest"])
    assert after["d"] == 1 and {after["a"], after["c"]} == {0, 2}


def test_explicit_id_over_a_previous_slot_is_a_conflict(tmp_path, write_material):
    write_material("old", 'type = "lambert"\n')
    previous = {"old": 3}
    write_material("new", 'type = "lambert"\nid = 3\n')
    with pytest.raises(MaterialError, match=r"new\.toml: field 'id'.*previous manifest"):
        bake_folder(tmp_path / "materials", previous_slots=previous)


def test_corrupt_previous_manifest_is_an_input_error(tmp_path):
    bad = tmp_path / "atlas.json"
    bad.write_text("{not json")
    with pytest.raises(InputError, match="atlas.json"):
        read_previous_slots(bad)


def test_a_manifest_from_an_older_atlasgen_keeps_its_ids_and_does_not_stop_the_bake(tmp_path, write_material):
    # A version-1 manifest (atlasgen 0.1.0) beside the output: read_manifest refuses it, but
    # the bake that replaces it takes its names and slices, and writes the current format.
    write_material("clay", 'type = "lambert"\n')
    write_material("moss", 'type = "lambert"\n')
    out = tmp_path / "build" / "atlas.dds"
    out.parent.mkdir()
    old = {"format_version": 1, "materials": [{"name": "moss", "first_slice": 7}, {"name": "clay", "first_slice": 3}]}
    out.with_suffix(".json").write_text(json.dumps(old))
    assert read_previous_slots(out.with_suffix(".json")) == {"moss": 7, "clay": 3}
    write_bake(
        bake_atlas(read_materials([tmp_path / "materials"]), previous_slots=read_previous_slots(out.with_suffix(".json"))), out
    )
    written = json.loads(out.with_suffix(".json").read_text())
    assert written["format_version"] > 1
    assert {m["name"]: m["first_slice"] for m in written["materials"]} == {"moss": 7, "clay": 3}


@pytest.mark.parametrize("text", ["[]", '{"materials": 5}', '{"materials": [{"name": "a"}]}', "not json"])
def test_unreadable_previous_slots_are_one_line_naming_the_file(tmp_path, text):
    from atlasgen.errors import ManifestError

    path = tmp_path / "atlas.json"
    path.write_text(text)
    with pytest.raises(ManifestError) as info:
        read_previous_slots(path)
    assert str(info.value).startswith(path.as_posix() + ": ") and "\n" not in str(info.value)
    # The atlas's own manifest, damaged, stopped every later bake of it with a line that gave no way out; a named
    # --ids-from (missing_ok=False) is the user's own file, and its line stays the reader's.
    assert str(info.value).endswith("bake reads it to keep the atlas's material IDs: mend it, or delete it to bake "
                                    "afresh with every ID assigned anew")  # fmt: skip
    with pytest.raises(ManifestError) as named:
        read_previous_slots(path, missing_ok=False)
    assert "bake reads it" not in str(named.value)
