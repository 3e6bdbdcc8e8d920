"""Material files: the ``[validate]`` table, a material's own look goal, and how it reaches the manifest."""

from __future__ import annotations

import pytest

from atlasgen.errors import MaterialError
from atlasgen.materials.material import read_material


def _material(tmp_path, extra: str):
    path = tmp_path / "velvet.toml"
    path.write_text('type = "lambert"\ncolour = [0.5, 0.2, 0.2]\n' + extra)
    return path


def test_a_validate_table_sets_the_materials_look_goal_and_the_bake_records_it(tmp_path):
    from atlasgen.bake.pipeline import bake_atlas

    material = read_material(_material(tmp_path, "[validate]\npsnr_db = 28\nflip = 0.08\n"))
    assert material.look_goal == {"psnr_db": 28.0, "flip": 0.08}
    entry = bake_atlas([material]).manifest.materials[0]
    assert entry.extra["validate"] == {"psnr_db": 28.0, "flip": 0.08} and entry.to_json()["validate"] == entry.extra["validate"]
    plain = read_material(_material(tmp_path, ""))
    assert plain.look_goal is None and "validate" not in bake_atlas([plain]).manifest.materials[0].to_json()


@pytest.mark.parametrize(
    "extra, field, expected",
    [
        ("validate = 3\n", "validate", "expected a table with psnr_db and/or flip"),
        ("[validate]\npsnr = 28\n", "validate.psnr", "unknown key; expected one of psnr_db, flip"),
        ("[validate]\npsnr_db = -1\n", "validate.psnr_db", "expected"),
        ("[validate]\nflip = 2\n", "validate.flip", "expected"),
    ],
)
def test_a_bad_validate_table_gets_one_line_naming_the_file_and_field(tmp_path, extra, field, expected):
    path = _material(tmp_path, extra)
    with pytest.raises(MaterialError) as info:
        read_material(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(path.as_posix()) and field in message and expected in message


@pytest.mark.parametrize("suffix", [".toml", ".mtlx"])
def test_a_material_file_whose_name_is_no_utf8_is_refused_on_one_line(tmp_path, suffix):
    """A manifest recording such a name (a lone surrogate) could not be read back: every later bake to the
    same -o, and `info`, failed on it until the folder was deleted."""
    import os

    from atlasgen.errors import InputError
    from atlasgen.materials.material import read_materials

    (tmp_path / os.fsdecode(b"bad\xff" + suffix.encode())).write_text('type = "lambert"\n')
    with pytest.raises(InputError) as info:
        read_materials([tmp_path])
    assert str(info.value) == f"{tmp_path.as_posix()}/bad\\udcff{suffix}: expected a file name in UTF-8"


def test_the_docstrings_examples_hold():
    import doctest

    from atlasgen.materials import material

    result = doctest.testmod(material)
    assert result.attempted > 0 and result.failed == 0
