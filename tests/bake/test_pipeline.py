"""The bake's output set (issue 24): one container beside its side files, no sibling of an
earlier bake left behind, one writer at a time."""

from __future__ import annotations

import struct
from dataclasses import replace

import pytest
from click.testing import CliRunner

from atlasgen.bake.pipeline import bake_atlas, other_container_path, write_bake
from atlasgen.cli.main import app
from atlasgen.errors import InputError
from atlasgen.io import atomic
from atlasgen.io.atlas import read_atlas
from atlasgen.io.sidecar import SIDECAR_MAGIC, sidecar_manifest_sha256
from atlasgen.materials.material import read_materials


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pipeline")
    (folder / "clay.toml").write_text('type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n')
    return bake_atlas(read_materials([folder]), "array")


def _names(folder) -> list[str]:
    """The outputs in ``folder`` (not the sets' stores of generations)."""
    return sorted(p.name for p in folder.iterdir() if not p.name.endswith(atomic.STORE_SUFFIX))


@pytest.mark.parametrize("first,second", [("dds", "ktx2"), ("ktx2", "dds")])
def test_a_bake_to_one_container_removes_the_other(tmp_path, baked, first, second):
    """X.dds and X.ktx2 would share X.json and the includes: only the one baked last stays."""
    write_bake(baked, tmp_path / f"atlas.{first}")
    write_bake(baked, tmp_path / f"atlas.{second}")
    assert _names(tmp_path) == sorted([f"atlas.{second}", "atlas.json", "atlas.wgsl", "atlas.glsl", "atlas.hlsl",
                                       "atlas.timings.json"])  # fmt: skip
    read_atlas(tmp_path / f"atlas.{second}")
    with pytest.raises(InputError, match="no such atlas"):
        read_atlas(tmp_path / f"atlas.{first}")


def test_other_container_path():
    assert other_container_path("b/x.dds").as_posix() == "b/x.ktx2"
    assert other_container_path("b/x.ktx2").as_posix() == "b/x.dds"


def _with_sidecar(result):
    header = SIDECAR_MAGIC + struct.pack("<3I", 2, 1, 32) + bytes(32)
    return replace(result, separable_data=header + struct.pack("<4f", 1, 2, 3, 4))


def test_a_bake_without_separable_materials_removes_the_old_side_car(tmp_path, baked):
    write_bake(_with_sidecar(baked), tmp_path / "atlas.dds")
    sidecar = tmp_path / "atlas.separable.bin"
    assert sidecar_manifest_sha256(sidecar.read_bytes()) is not None
    write_bake(baked, tmp_path / "atlas.dds")
    assert not sidecar.exists()


@pytest.mark.parametrize("representation", ["analytic", "lut"])
def test_separable_materials_without_factors_write_no_side_car(tmp_path, write_material, representation):
    """Held in closed form or as one LUT slice, no entry has factors and the include no SEPARABLE_TABLE: a side-car of
    one header row was written beside it, which docs/engine-integration.md calls exactly the include's table."""
    write_material("gloss", f'type = "separable"\nsource = "beckmann"\nalpha = 0.3\nrepresentation = "{representation}"\n')
    out = tmp_path / "build" / "atlas.dds"
    res = CliRunner().invoke(app, ["bake", str(tmp_path / "materials"), "-o", str(out), "-q"])
    assert res.exit_code == 0, res.output
    assert "SEPARABLE_TABLE" not in out.with_suffix(".wgsl").read_text()
    assert not out.with_suffix(".separable.bin").exists()


def test_includes_of_languages_not_asked_for_are_removed(tmp_path, write_material):
    write_material("clay", 'type = "lambert"\n')
    out = tmp_path / "build" / "atlas.dds"
    runner = CliRunner()
    assert runner.invoke(app, ["bake", str(tmp_path / "materials"), "-o", str(out), "-q"]).exit_code == 0
    assert {"atlas.glsl", "atlas.hlsl", "atlas.wgsl"} <= set(_names(out.parent))
    res = runner.invoke(app, ["bake", str(tmp_path / "materials"), "-o", str(out), "--include", "wgsl", "-q"])
    assert res.exit_code == 0, res.output
    assert _names(out.parent) == ["atlas.dds", "atlas.json", "atlas.timings.json", "atlas.wgsl"]


def test_a_second_writer_of_the_set_is_refused_after_the_lock_timeout(tmp_path, write_material, monkeypatch):
    write_material("clay", 'type = "lambert"\n')
    out = tmp_path / "build" / "atlas.dds"
    out.parent.mkdir()
    monkeypatch.setenv("ATLASGEN_LOCK_TIMEOUT_S", "0.1")
    with atomic.output_lock(out.parent, "atlas") as lock:  # another writer of build/atlas.*
        res = CliRunner().invoke(app, ["bake", str(tmp_path / "materials"), "-o", str(out), "-q"])
    assert res.exit_code == 4
    assert res.stderr.splitlines() == [f"atlasgen: error: {lock.as_posix()}: another atlasgen process is writing this "
                                       "output set (waited 0.1 s); expected one writer at a time"]  # fmt: skip
    assert _names(out.parent) == []


@pytest.mark.parametrize("value", ["nan", "inf", "1e999", "-1", "abc", ""])
def test_a_lock_timeout_that_is_no_number_of_seconds_is_refused(tmp_path, write_material, monkeypatch, value):
    """nan or inf would wait forever on a held lock, and a word was silently read as 120 s."""
    write_material("clay", 'type = "lambert"\n')
    out = tmp_path / "build" / "atlas.dds"
    monkeypatch.setenv("ATLASGEN_LOCK_TIMEOUT_S", value)
    res = CliRunner().invoke(app, ["bake", str(tmp_path / "materials"), "-o", str(out), "-q"])
    assert res.exit_code == 3, res.output
    assert res.stderr.splitlines() == ["atlasgen: error: ATLASGEN_LOCK_TIMEOUT_S: expected a finite number of seconds "
                                       f">= 0, got {value!r}"]  # fmt: skip
    assert not out.exists()
    # Refused before any work, by every command (it was read at the commit, after a validation's renders).
    res = CliRunner().invoke(app, ["info", str(tmp_path / "none.dds")])
    assert res.exit_code == 3 and res.stderr.startswith("atlasgen: error: ATLASGEN_LOCK_TIMEOUT_S"), res.output


@pytest.mark.parametrize(
    ("count", "ids", "expected"),
    [(257, {}, "the materials need 257 slices; expected at most 256"),
     (2, {"m0": 5, "m1": 5}, r"slice 5 \(explicit id\) conflicts with material 'm0'"),
     # Nine separable materials of 32 terms each: their slice counts are fixed, so known before any bake.
     (9, "terms = 32", "the materials need 288 slices; expected at most 256"),
     # Auto materials may take one slice each: 190 of them and 8 of 8 terms (64) fit as far as is known.
     (0, "fits", None)],
    ids=["257 materials", "one explicit id twice", "9 x 32 terms", "auto may fit"],
)  # fmt: skip
def test_what_no_atlas_holds_is_refused_before_anything_is_baked(tmp_path, monkeypatch, count, ids, expected):
    """More slices than the atlas holds, or two explicit ids on one slice: the slot check runs before the
    bakes, which for a MaterialX library of 300 materials would take a quarter of an hour first. Fixed
    separable term counts count in full (9 materials of 32 terms were refused only after all 9 bakes)."""
    from atlasgen.bake import pipeline
    from atlasgen.errors import MaterialError

    separable = 'type = "separable"\nsource = "ggx"\nalpha = 0.3\n'
    if ids == "terms = 32":
        for i in range(count):
            (tmp_path / f"s{i}.toml").write_text(separable + "terms = 32\n")
        ids, count = {}, 0
    elif ids == "fits":
        for i in range(190):
            (tmp_path / f"a{i}.toml").write_text(separable + 'representation = "auto"\n')
        for i in range(8):
            (tmp_path / f"s{i}.toml").write_text(separable + "terms = 8\n")
        ids = {}
    for i in range(count):
        extra = f"id = {ids[f'm{i}']}\n" if f"m{i}" in ids else ""
        (tmp_path / f"m{i}.toml").write_text(f'type = "lambert"\ncolour = [0.5, 0.5, 0.5]\n{extra}')
    materials = read_materials([tmp_path])

    def no_bake(*args, **kwargs):
        raise AssertionError("a material was baked before the slots were checked")

    monkeypatch.setattr(pipeline, "load_or_bake_all", no_bake)
    if expected is None:
        with pytest.raises(AssertionError, match="was baked before"):  # past the check, at the bakes
            bake_atlas(materials, "array")
        return
    with pytest.raises(MaterialError, match=expected):
        bake_atlas(materials, "array")
