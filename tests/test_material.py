"""Reading material files: every bad input is a one-line error naming file, field and expectation."""

import os
from pathlib import Path

import pytest

from atlasgen.errors import InputError, MaterialError
from atlasgen.materials.material import read_material, read_materials


def test_defaults_are_filled_and_hex_colours_decoded(write_material):
    m = read_material(write_material("clay", 'type = "lambert"\ndescription = "wet clay"\n'))
    assert m.name == "clay" and m.params == {"colour": (1.0, 1.0, 1.0)} and m.id is None
    assert m.constant_name == "MATERIAL_CLAY"
    m = read_material(write_material("red", 'type = "lambert"\ncolour = "#ff0000"\n'))
    assert m.params["colour"] == (1.0, 0.0, 0.0)


@pytest.mark.parametrize(
    "text, field, expected",
    [
        ('type = "lambert"\ncolour = [1, 2', None, "malformed TOML"),
        ('type = "lambertian"\n', "type", "unknown model 'lambertian' (did you mean 'lambert'?); expected one of lambert"),
        ("colour = [1, 1, 1]\n", "type", "missing"),
        ('type = "lambert"\ncolor = [1, 1, 1]\n', "color", "unknown key (did you mean 'colour'?)"),
        ('type = "lambert"\ncolour = [nan, 1, 1]\n', "colour", "finite numbers in [0, 1]"),
        ('type = "lambert"\ncolour = [inf, 1, 1]\n', "colour", "finite numbers in [0, 1]"),
        ('type = "lambert"\ncolour = [1.5, 1, 1]\n', "colour", "in [0, 1]"),
        ('type = "lambert"\ncolour = "#12345"\n', "colour", "'#rrggbb'"),
        ('type = "lambert"\nid = 256\n', "id", "expected an integer >= 0 and <= 255, got 256"),
        ('type = "lambert"\nid = 1.0\n', "id", "expected an integer >= 0 and <= 255, got 1.0"),
        ('type = "lambert"\nname = "9lives"\n', "name", "expected a letter"),
        ('type = "lambert"\nrgb_scale = -1\n', "rgb_scale", 'expected "auto" or a finite number > 0'),
        ('type = "lambert"\nalpha_scale = nan\n', "alpha_scale", 'expected "auto" or a finite number > 0'),
        # A TOML date as the file wrote it, not Python's datetime.date(1979, 5, 27).
        ('type = "lambert"\ncolour = 1979-05-27\n', "colour", "of 3 numbers in [0, 1], got a date 1979-05-27"),
        ('type = "lambert"\ncolour = 07:32:00\n', "colour", "got a time 07:32:00"),
    ],
)
def test_bad_definitions(expect_rejected, text, field, expected):
    expect_rejected(None, text, field, expected)


def test_duplicate_names_are_rejected(write_material, tmp_path):
    write_material("a", 'type = "lambert"\nname = "same"\n')
    write_material("b", 'type = "lambert"\nname = "same"\n')
    with pytest.raises(MaterialError, match=r"b\.toml: field 'name': duplicate material name 'same' \(also in .*a\.toml\); "
                       r"expected a name no other material has \(the file's name field\)$"):  # fmt: skip
        read_materials([tmp_path / "materials"])


def test_a_file_named_twice_is_read_once(write_material, tmp_path, monkeypatch):
    """``bake m ./m/`` refused 'clay' as a duplicate name "also in" its own file."""
    write_material("clay", 'type = "lambert"\n')
    monkeypatch.chdir(tmp_path)
    for paths in (["materials", "./materials/"], ["materials/clay.toml", "materials"]):
        assert [m.name for m in read_materials(paths)] == ["clay"]
    (tmp_path / "materials" / "link.toml").symlink_to("clay.toml")  # two names of one file: two materials
    assert [m.name for m in read_materials(["materials"])] == ["clay", "link"]


def test_a_duplicate_name_names_where_the_name_is_written(write_material, tmp_path):
    """The refusal named field 'name' even where the file has none (its name is the file's) and where the name is a
    MaterialX document's surfacematerial, which has no such field: it named no field the user could find."""
    write_material("clay", 'type = "lambert"\n')
    other = tmp_path / "other" / "clay.toml"
    other.parent.mkdir()
    other.write_text('type = "lambert"\n')
    with pytest.raises(MaterialError) as info:
        read_materials([tmp_path / "materials", other])
    assert str(info.value).endswith("expected a name no other material has (the file's name field, or the file's own "
                                    "name where it has none)")  # fmt: skip
    document = tmp_path / "lib.mtlx"
    document.write_text('<?xml version="1.0"?>\n<materialx version="1.39">\n'
                        '  <standard_surface name="SR_clay" type="surfaceshader" />\n'
                        '  <surfacematerial name="clay" type="material">\n'
                        '    <input name="surfaceshader" type="surfaceshader" nodename="SR_clay" />\n'
                        '  </surfacematerial>\n</materialx>\n')  # fmt: skip
    with pytest.raises(MaterialError) as info:
        read_materials([tmp_path / "materials", document])
    assert str(info.value).startswith(f"{document.as_posix()}: field 'clay': duplicate material name 'clay' (also in ")
    assert str(info.value).endswith("(the surfacematerial's name in the document)")


def test_a_name_ending_in_a_line_break_is_refused(write_material, tmp_path):
    """Python's ``$`` matches before a final line break: "abc\\n" was baked beside "abc", two rows named alike."""
    write_material("a", 'type = "lambert"\nname = "abc\\n"\n')
    with pytest.raises(MaterialError, match=r"a\.toml: field 'name': expected a letter then .*, got 'abc\\n'$"):
        read_materials([tmp_path / "materials"])


def test_names_colliding_as_shader_constants_are_duplicates(write_material, tmp_path):
    write_material("gold-film", 'type = "lambert"\n')
    write_material("Gold_film", 'type = "lambert"\n')
    # Sorted by name, "G" before "g": the lower-case file is the second.
    with pytest.raises(MaterialError, match=r"gold-film.toml: field 'name': duplicate material name 'gold-film': "
                       r"'Gold_film' \(in .*Gold_film.toml\) is the same shader constant MATERIAL_GOLD_FILM; "
                       r"expected names that differ in more than case or '-' against '_' \(the file's name field, or "
                       r"the file's own name where it has none\)$"):  # fmt: skip
        read_materials([tmp_path / "materials"])


def test_a_folder_s_hidden_files_are_not_its_materials(write_material, tmp_path):
    """An editor's lock link (Emacs's ``.#clay.toml``, pointing nowhere) failed the folder's whole bake, and a
    hidden copy was baked beside the material; make's ``$(wildcard materials/*.toml)`` leaves both out."""
    write_material("clay", 'type = "lambert"\n')
    folder = tmp_path / "materials"
    os.symlink("user@host.1234:1700000000", folder / ".#clay.toml")
    (folder / ".clay.toml").write_text('type = "lambert"\n')
    assert [m.name for m in read_materials([folder])] == ["clay"]


def test_missing_path(tmp_path):
    with pytest.raises(InputError, match="nope: no such file or folder"):
        read_materials([tmp_path / "nope"])


def test_not_utf8(tmp_path):
    p = tmp_path / "x.toml"
    p.write_bytes(b'type = "lambert"\n\xff\xfe')
    with pytest.raises(MaterialError, match="expected UTF-8"):
        read_material(p)


def _textured(tmp_path, colour=(255, 0, 0)):
    """A material naming an image beside it (a Mitsuba bitmap), and another image of the same name elsewhere."""
    import OpenImageIO as oiio

    folder = tmp_path / "materials"
    folder.mkdir(exist_ok=True)
    for path, value in ((folder / "tex.png", colour), (tmp_path / "tex.png", (0, 0, 255))):
        image = oiio.ImageBuf(oiio.ImageSpec(4, 4, 3, oiio.UINT8))
        oiio.ImageBufAlgo.fill(image, [c / 255 for c in value])
        assert image.write(str(path))
    material = folder / "tx.toml"
    material.write_text('type = "bsdf"\ngloss = 0.5\n'
                        'bsdf = { type = "diffuse", reflectance = { type = "bitmap", filename = "tex.png" } }\n')  # fmt: skip
    return material


@pytest.mark.slow
def test_a_file_a_material_names_is_read_from_the_material_s_folder(mitsuba_llvm, tmp_path, monkeypatch):
    """Mitsuba read a relative filename from the working folder: baked from materials/ or from the root, the same
    material file read two images (two atlases, one content hash), and from elsewhere none. It is now read from the
    material file's folder, its bytes are in the content hash (a changed image is another material, which the cache
    must see), and the bake depends on it."""
    material = _textured(tmp_path)
    monkeypatch.chdir(tmp_path)
    (m,) = read_materials([material])
    image = (tmp_path / "materials" / "tex.png").resolve()
    assert m.params["bsdf"]["reflectance"]["filename"] == str(image) and m.includes == (image.as_posix(),)
    monkeypatch.chdir(tmp_path / "materials")
    assert read_materials([Path("tx.toml")])[0].content_hash == m.content_hash
    _textured(tmp_path, colour=(0, 255, 0))
    assert read_materials([Path("tx.toml")])[0].content_hash != m.content_hash


def test_a_file_a_material_names_that_is_not_there_is_one_line(tmp_path):
    """Mitsuba's refusal came with OpenImageIO's complaints on stdout; it is refused before, naming the field."""
    (tmp_path / "m.toml").write_text('type = "bsdf"\nbsdf = { type = "diffuse", reflectance = { type = "bitmap", '
                                     'filename = "missing.png" } }\n')  # fmt: skip
    with pytest.raises(MaterialError) as info:
        read_materials([tmp_path / "m.toml"])
    assert str(info.value) == (f"{(tmp_path / 'm.toml').as_posix()}: field 'bsdf.reflectance.filename': expected a file "
                               "(a relative name is from the material file's folder), got 'missing.png': "
                               f"{(tmp_path / 'missing.png').as_posix()}: no such file")  # fmt: skip


@pytest.mark.slow
def test_an_atlas_of_a_material_naming_a_file_is_the_same_bytes_from_any_folder(mitsuba_llvm, tmp_path, monkeypatch):
    """The manifest holds the file relative to its own folder (as it holds source), and a reader takes it from
    there: validate by name from another folder reads the same image."""
    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.io.atlas import read_atlas

    material = _textured(tmp_path)
    written = []
    for cwd, given, out in ((tmp_path, "materials/tx.toml", "out1/a.dds"), (tmp_path / "materials", "tx.toml", "../out2/a.dds")):
        monkeypatch.chdir(cwd)
        write_bake(bake_atlas(read_materials([Path(given)])), Path(out))
        written.append({s: Path(out).with_suffix(s).read_bytes() for s in (".dds", ".json")})
    assert written[0] == written[1]
    assert b'"filename": "../materials/tex.png"' in written[0][".json"]
    monkeypatch.chdir(tmp_path / "out1")
    entry = read_atlas(tmp_path / "out2" / "a.dds").manifest.materials[0]
    assert entry.params["bsdf"]["reflectance"]["filename"] == str((tmp_path / "materials" / "tex.png").resolve())
    assert material.exists()


@pytest.mark.slow
def test_a_file_a_material_names_is_found_through_linked_folders(mitsuba_llvm, tmp_path, monkeypatch):
    """The manifest measured the name from the output folder's real place, and the reader joined it to the folder as
    given: an atlas written through a link (lnk -> real/deep/out) named /mat/tex.png. And a name with "link/.." was
    checked where the system finds it but hashed where the text folds."""
    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.io.atlas import read_atlas

    material = _textured(tmp_path)
    image = (tmp_path / "materials" / "tex.png").resolve()
    (tmp_path / "real" / "deep" / "out").mkdir(parents=True)
    (tmp_path / "lnk").symlink_to(tmp_path / "real" / "deep" / "out")
    monkeypatch.chdir(tmp_path)
    write_bake(bake_atlas(read_materials([material])), Path("lnk/a.dds"))
    entry = read_atlas(Path("lnk/a.dds")).manifest.materials[0]
    assert entry.params["bsdf"]["reflectance"]["filename"] == str(image)
    (tmp_path / "materials" / "sl").symlink_to(tmp_path / "real" / "deep")
    material.write_text(material.read_text().replace('"tex.png"', '"sl/../tex.png"'))  # the system: real/tex.png
    with pytest.raises(MaterialError, match=r"got 'sl/\.\./tex\.png': .*: no such file"):
        read_materials([material])
    (tmp_path / "real" / "tex.png").write_bytes(image.read_bytes())
    (m,) = read_materials([material])
    assert m.params["bsdf"]["reflectance"]["filename"] == str((tmp_path / "real" / "tex.png").resolve())


@pytest.mark.slow
def test_validating_an_atlas_whose_named_file_is_gone_is_one_line(mitsuba_llvm, tmp_path):
    """An atlas moved away from the file its material names: validate ended in OpenImageIO's complaints and an
    internal error. The manifest's field is named."""
    from click.testing import CliRunner

    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.cli.main import app

    material = _textured(tmp_path)
    write_bake(bake_atlas(read_materials([material])), tmp_path / "out" / "a.dds")
    (tmp_path / "elsewhere" / "deeper").mkdir(parents=True)
    for path in (tmp_path / "out").glob("a.*"):  # copied as files (the outputs are links into their store)
        (tmp_path / "elsewhere" / "deeper" / path.name).write_bytes(path.read_bytes())
    atlas = tmp_path / "elsewhere" / "deeper" / "a.dds"
    res = CliRunner().invoke(app, ["validate", "tx", "--atlas", str(atlas), "--no-physical", "--resolution", "32x24",
                                   "--no-reference-cache", "-o", str(tmp_path / "v")])  # fmt: skip
    assert res.exit_code == 3, res.output
    assert res.stderr.splitlines() == [
        f"atlasgen: error: {atlas.with_suffix('.json').as_posix()}: field 'materials[0].params.bsdf.reflectance.filename': "
        f"expected the file the material was baked from, got {tmp_path / 'elsewhere' / 'materials' / 'tex.png'}: no such "
        "file (moved since the bake? re-run atlasgen bake)"
    ]


def test_an_unknown_key_s_refusal_lists_every_key_a_material_file_may_hold(tmp_path):
    """It listed the model's parameters alone ("expected one of: colour"), though name, id, description and the
    rest are taken too; and a misspelt common key got no suggestion."""
    path = tmp_path / "u.toml"
    path.write_text('type = "lambert"\nname = "u"\nid = 3\ncolour = [1, 1, 1]\nbogus = 1\n')
    with pytest.raises(MaterialError) as info:
        read_materials([path])
    listed = str(info.value).split("expected one of: ")[1].split(", ")
    assert {"colour", "name", "id", "description", "rgb_scale", "error_budget", "validate", "type"} <= set(listed)
    path.write_text('type = "lambert"\ndescripton = "x"\n')
    with pytest.raises(MaterialError, match=r"field 'descripton': unknown key \(did you mean 'description'\?\)"):
        read_materials([path])


@pytest.mark.slow
def test_a_process_that_bakes_a_material_again_sees_its_image_saved_anew(mitsuba_llvm, tmp_path):
    """Found by a hostile sweep: the in-process fit cache was keyed on the BSDF's parameters, which name the image by
    its path, so `preview --watch` showed the first texture's fit after every later save of the texture."""
    from atlasgen.bake.adaptive import bake_material

    material = _textured(tmp_path)
    (red,) = read_materials([material])
    first = bake_material(red).values
    _textured(tmp_path, colour=(0, 255, 0))
    (green,) = read_materials([material])
    again = bake_material(green).values
    assert red.params == green.params  # the same path: only the image's bytes differ
    # The diffuse response's colour follows the image: red, then green.
    assert first[0, ..., 0].mean() > 10 * first[0, ..., 1].mean()
    assert again[0, ..., 1].mean() > 10 * again[0, ..., 0].mean()


@pytest.mark.slow
def test_an_image_that_is_no_image_is_one_line_to_the_process_s_end(mitsuba_llvm, tmp_path):
    """Found by a hostile sweep: after Mitsuba's one-line refusal, OpenImageIO printed three more lines at exit
    ("exited with a pending error message that was never retrieved"), left by the texture size check."""
    import subprocess
    import sys

    (tmp_path / "tex.png").write_text("garbage\n")
    (tmp_path / "tb.toml").write_text('type = "bsdf"\ngloss = 0.5\nbsdf = { type = "diffuse", reflectance = '
                                      '{ type = "bitmap", filename = "tex.png" } }\n')  # fmt: skip
    res = subprocess.run([sys.executable, "-m", "atlasgen", "bake", "tb.toml", "-o", "out/a.dds"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)  # fmt: skip
    assert res.returncode == 3, res.stderr
    assert res.stderr.startswith("atlasgen: error: tb.toml: field 'bsdf.reflectance.filename': Mitsuba rejected")
    assert len(res.stderr.splitlines()) == 1 and res.stdout == "", res.stderr
