"""Reading material files: every bad input is a one-line error naming file, field and expectation."""

import os

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
