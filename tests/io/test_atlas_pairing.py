"""One generation at a time: a bake's texture, manifest and includes are tied by hashes, and
every reader refuses files from different bakes (or a texture whose header is not what the
manifest claims) with one line naming both files and saying to re-run the bake."""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.errors import InputError
from atlasgen.io.atlas import RERUN, read_atlas
from atlasgen.io.dds import encode_dds, read_dds
from atlasgen.materials.material import read_materials
from atlasgen.render.atlas_texture import read_render_atlas
from tests import dds_reader, ktx2_reader

ROOT = Path(__file__).resolve().parents[2]


def _bake(tmp_path: Path, folder: str, colour: str = "[0.2, 0.3, 0.4]", linear: bool = False, suffix: str = ".dds") -> Path:
    """Bake two lambert materials from ``tmp_path/materials`` into ``tmp_path/folder/atlas<suffix>``."""
    materials = tmp_path / "materials"
    materials.mkdir(exist_ok=True)
    (materials / "clay.toml").write_text(f'type = "lambert"\ncolour = {colour}\n')
    (materials / "moss.toml").write_text('type = "lambert"\ncolour = [0.1, 0.5, 0.1]\n')
    out = tmp_path / folder / f"atlas{suffix}"
    write_bake(bake_atlas(read_materials([materials]), linear=linear), out)
    return out


def _refusal(path) -> str:
    with pytest.raises(InputError) as info:
        read_atlas(path)
    message = str(info.value)
    assert "\n" not in message and message.endswith(RERUN), message
    return message


@pytest.mark.parametrize("suffix", [".dds", ".ktx2"])
def test_a_bake_writes_a_pair_that_reads_back(tmp_path, suffix):
    out = _bake(tmp_path, "build", suffix=suffix)
    manifest = json.loads(out.with_suffix(".json").read_text())
    # The texels' hash, from the independent readers: every level's bytes, level 0 first.
    parse = ktx2_reader.parse if suffix == ".ktx2" else dds_reader.parse
    texels = hashlib.sha256(b"".join(np.ascontiguousarray(lv).tobytes() for lv in parse(out.read_bytes())["levels"]))
    assert manifest["atlas_sha256"] == texels.hexdigest()
    atlas = read_atlas(out)
    digest = hashlib.sha256(out.with_suffix(".json").read_bytes()).hexdigest()
    if suffix == ".ktx2":
        assert ktx2_reader.kvd_dict(ktx2_reader.parse(out.read_bytes()))["atlasgen.manifest_sha256"] == digest.encode()
    assert atlas.manifest_sha256 == digest
    for lang in ("wgsl", "glsl", "hlsl"):
        first = out.with_suffix(f".{lang}").read_text().split("\n", 1)[0]
        assert first == f"// atlasgen manifest sha256: {digest}", lang
    assert read_render_atlas(out).manifest == atlas.manifest


def test_a_texture_from_another_bake_is_refused_naming_both_files(tmp_path):
    out = _bake(tmp_path, "build")
    other = _bake(tmp_path, "other", colour="[0.7, 0.5, 0.3]")
    shutil.copy(other, out)  # a new texture beside an old manifest: the header agrees, the bytes do not
    message = _refusal(out)
    assert message.startswith(f"{out.with_suffix('.json').as_posix()}: field 'atlas_sha256': does not match {out.as_posix()}")
    assert "different bakes" in message


def test_a_linear_texture_with_an_srgb_manifest_is_refused(tmp_path):
    out = _bake(tmp_path, "build")
    shutil.copy(_bake(tmp_path, "linear", linear=True), out)
    message = _refusal(out)
    assert "field 'encoding': says srgb, but" in message and out.as_posix() in message and "has linear" in message


@pytest.mark.parametrize("what, levels, field", [
    ("one layer", lambda lv: [x[:1] for x in lv], "dimensions.layers"),
    ("fewer mips", lambda lv: lv[:3], "dimensions.mip_count"),
])  # fmt: skip
def test_a_texture_whose_header_is_not_what_the_manifest_claims_is_refused(tmp_path, what, levels, field):
    out = _bake(tmp_path, "build")
    image = read_dds(out)
    out.write_bytes(encode_dds(levels(image.levels), "array", image.dxgi_format))
    message = _refusal(out)
    assert f"field '{field}': says " in message and out.as_posix() in message, what


def test_a_volume_texture_with_an_array_manifest_is_refused(tmp_path):
    out = _bake(tmp_path, "build")
    materials = read_materials([tmp_path / "materials"])
    volume = tmp_path / "volume" / "atlas.dds"
    write_bake(bake_atlas(materials, layout="volume"), volume)
    shutil.copy(volume, out)
    assert "(the two are from different bakes)" in _refusal(out)


def test_a_slice_past_the_end_is_one_line(tmp_path):
    atlas = read_atlas(_bake(tmp_path, "build"))
    for index in (256, -1, 10**9):
        with pytest.raises(InputError, match=r"no slice .*; the atlas has slices 0\.\.255$"):
            atlas.decode_slice(index)
    with pytest.raises(InputError, match="no mip level 7"):
        atlas.decode_slice(0, level=7)


def test_the_renderer_refuses_an_include_from_another_bake(tmp_path):
    out = _bake(tmp_path, "build")
    other = _bake(tmp_path, "other", colour="[0.7, 0.5, 0.3]")
    shutil.copy(other.with_suffix(".wgsl"), out.with_suffix(".wgsl"))
    with pytest.raises(
        InputError, match=r"atlas\.wgsl: its manifest sha256 does not match .*atlas\.json .*re-run atlasgen bake$"
    ):
        read_render_atlas(out)
    text = other.with_suffix(".wgsl").read_text().split("\n", 1)[1]  # an include without its first line
    out.with_suffix(".wgsl").write_text(text)
    with pytest.raises(InputError, match="expected a first line '// atlasgen manifest sha256: ...'"):
        read_render_atlas(out)


def test_an_edited_manifest_no_longer_matches_its_include(tmp_path):
    out = _bake(tmp_path, "build")
    manifest = out.with_suffix(".json")
    manifest.write_text(manifest.read_text().replace('"generator": "atlasgen', '"generator": "edited atlasgen'))
    read_atlas(out)  # the texture still matches the manifest
    with pytest.raises(InputError, match="does not match"):
        read_render_atlas(out)


@pytest.mark.parametrize("command", [
    ["info", "{atlas}"],
    ["render", str(ROOT / "scenes" / "demo.toml"), "--atlas", "{atlas}", "-o", "{tmp}/out.exr"],
    ["validate", "--atlas", "{atlas}", "-o", "{tmp}/validation"],
])  # fmt: skip
@pytest.mark.slow
def test_every_command_refuses_a_mismatched_pair_with_one_line(tmp_path, command):
    out = _bake(tmp_path, "build")
    shutil.copy(_bake(tmp_path, "other", colour="[0.7, 0.5, 0.3]"), out)
    args = [a.format(atlas=out, tmp=tmp_path) for a in command]
    res = subprocess.run([sys.executable, "-m", "atlasgen", *args], capture_output=True, text=True, timeout=120)
    assert res.returncode == 3, (res.returncode, res.stderr)
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "atlas_sha256" in lines[0] and lines[0].endswith(RERUN), res.stderr
    assert not (tmp_path / "out.exr").exists() and not (tmp_path / "validation").exists()


def test_decoded_slices_of_a_matching_pair_are_the_bake(tmp_path):
    out = _bake(tmp_path, "build")
    atlas = read_atlas(out)
    clay = atlas.material("clay")
    rgba = atlas.decode_slice(clay.first_slice)
    np.testing.assert_allclose(rgba[..., :3].max(axis=(0, 1)), [0.2, 0.3, 0.4], atol=0.01)


def test_the_separable_rebuild_reads_through_the_pair_check(tmp_path):
    from atlasgen.separable.rebuild import read_separable_factors

    out = _bake(tmp_path, "build")
    with pytest.raises(InputError, match="'clay' is 'lambert', not 'separable'"):
        read_separable_factors(out, "clay")
    shutil.copy(_bake(tmp_path, "other", colour="[0.7, 0.5, 0.3]"), out)
    with pytest.raises(InputError, match=r"field 'atlas_sha256': does not match .*re-run atlasgen bake$"):
        read_separable_factors(out, "clay")


def test_a_ktx2_refuses_a_manifest_other_than_the_one_it_records(tmp_path):
    # Same texels, another manifest (its description edited): the texels still hash to
    # atlas_sha256, but the KTX2's recorded manifest hash names the manifest it was written with.
    out = _bake(tmp_path, "build", suffix=".ktx2")
    manifest = out.with_suffix(".json")
    manifest.write_text(manifest.read_text().replace('"description": ""', '"description": "edited"', 1))
    message = _refusal(out)
    assert message.startswith(f"{out.as_posix()}: KTX2 key 'atlasgen.manifest_sha256': does not match {manifest.as_posix()}")
    assert message.endswith(RERUN) and "\n" not in message


def test_a_ktx2_without_its_recorded_manifest_hash_is_refused(tmp_path):
    """Found by a hostile-input hunt: with the key/value data emptied (kvdByteLength 0), the check above was
    skipped, and an edited manifest passed as the atlas's."""
    import struct

    out = _bake(tmp_path, "build", suffix=".ktx2")
    data = bytearray(out.read_bytes())
    struct.pack_into("<II", data, 56, 0, 0)  # kvdByteOffset, kvdByteLength: no key/value data at all
    out.unlink()
    out.write_bytes(bytes(data))
    message = _refusal(out)
    assert message.startswith(f"{out.as_posix()}: KTX2 key 'atlasgen.manifest_sha256': missing; expected the SHA-256 of "
                              f"{out.with_suffix('.json').as_posix()}")  # fmt: skip


def test_info_says_which_files_beside_the_atlas_are_of_its_bake(tmp_path):
    """An include copied from another bake, or edited by hand, was loaded by an engine without a word: ``info``
    read the texture and the manifest only."""
    from click.testing import CliRunner

    from atlasgen.cli.main import app

    a = _bake(tmp_path, "a")
    b = _bake(tmp_path, "b", colour="[0.9, 0.1, 0.1]")
    runner = CliRunner()
    fresh = json.loads(runner.invoke(app, ["info", str(a), "--format", "json"]).output)["companions"]
    assert fresh == {"wgsl": "this bake", "glsl": "this bake", "hlsl": "this bake", "separable.bin": "none"}
    shutil.copyfile(b.with_suffix(".glsl"), a.with_suffix(".glsl"))
    a.with_suffix(".hlsl").unlink()
    text = a.with_suffix(".wgsl").read_text()
    a.with_suffix(".wgsl").write_text(text.split("\n", 1)[1])  # its first line, the manifest's hash, removed
    res = runner.invoke(app, ["info", str(a), "--format", "json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["companions"] == {"wgsl": "not atlasgen's", "glsl": "another bake", "hlsl": "none",
                                                    "separable.bin": "none"}  # fmt: skip
    lines = runner.invoke(app, ["info", str(a)]).output.splitlines()
    assert "  beside it: atlas.wgsl (not atlasgen's), atlas.glsl (another bake); absent: atlas.hlsl, atlas.separable.bin" \
        in lines, lines  # fmt: skip


def test_info_tells_a_file_edited_since_its_bake_from_one_of_this_bake(tmp_path):
    """A hostile sweep's findings: an include whose material constant was edited (or cut in half) keeps its first line,
    the manifest's hash, and info called it "this bake"; a side-car with an edited table likewise. Each is now compared
    with what a bake of the manifest writes. And info now checks the manifest's entries as render does: a type it does
    not know passed info and was refused by render."""
    import struct

    from click.testing import CliRunner

    from atlasgen.cli.main import app

    folder = tmp_path / "materials"
    folder.mkdir()
    (folder / "clay.toml").write_text('type = "lambert"\ncolour = [0.5, 0.4, 0.3]\n')
    (folder / "sep.toml").write_text('type = "separable"\nsource = "ggx"\nalpha = 0.3\nterms = 2\n')
    atlas = tmp_path / "out" / "atlas.dds"
    write_bake(bake_atlas(read_materials([folder])), atlas)
    runner = CliRunner()

    def companions():
        res = runner.invoke(app, ["info", str(atlas), "--format", "json"])
        assert res.exit_code == 0, res.output
        return json.loads(res.output)["companions"]

    assert companions() == {"wgsl": "this bake", "glsl": "this bake", "hlsl": "this bake", "separable.bin": "this bake"}
    wgsl, sidecar = atlas.with_suffix(".wgsl"), atlas.with_suffix(".separable.bin")
    text = wgsl.read_text()
    constant = next(line for line in text.splitlines() if line.startswith("const MATERIAL_CLAY: u32 = "))
    wgsl.write_text(text.replace(constant, constant.replace("= 0u;", "= 1u;").replace("= 1u;", "= 7u;")))
    data = bytearray(sidecar.read_bytes())
    data[-4:] = struct.pack("<f", 123.0)  # a table value, past the header and its recorded hash
    sidecar.write_bytes(bytes(data))
    atlas.with_suffix(".hlsl").write_text(atlas.with_suffix(".hlsl").read_text()[:200])  # cut, its first line kept
    assert companions() == {"wgsl": "edited since its bake", "glsl": "this bake", "hlsl": "edited since its bake",
                            "separable.bin": "edited since its bake"}  # fmt: skip
    lines = runner.invoke(app, ["info", str(atlas)]).output.splitlines()
    assert "  beside it: atlas.wgsl (edited since its bake), atlas.glsl (this bake), atlas.hlsl (edited since its bake), " \
           "atlas.separable.bin (edited since its bake)" in lines, lines  # fmt: skip

    manifest = atlas.with_suffix(".json")
    edited = manifest.read_text().replace('"type": "lambert"', '"type": "foo"')
    manifest.write_text(edited)
    res = runner.invoke(app, ["info", str(atlas)])
    assert res.exit_code == 3 and "field 'materials[0].type': expected one of the models atlasgen knows" in res.output
