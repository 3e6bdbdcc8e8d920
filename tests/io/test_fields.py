"""The field validator's pure helpers (atlasgen/io/fields.py): its docstrings' examples."""

from __future__ import annotations

import doctest

import pytest

from atlasgen.io import fields


def test_the_docstrings_examples_hold():
    result = doctest.testmod(fields)
    assert result.attempted > 0 and result.failed == 0


def test_negative_zero_is_read_as_zero_so_the_manifest_does_not_echo_it(tmp_path):
    """A material written with -0.0 (a number or a colour channel) is the same material as one with 0.0: it must
    reach the manifest, and so the atlas's bytes, as 0.0. Every other value passes unchanged."""
    import math

    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.io.fields import Param, validate_params
    from atlasgen.materials.material import read_materials

    schema = (Param("colour", (1.0, 1.0, 1.0), "colour"), Param("ambient", 0.0, "float", lo=-1.0, hi=1.0))
    values = validate_params(schema, {"colour": [-0.0, 0.5, 1.0], "ambient": -0.0}, "m.toml")
    assert math.copysign(1.0, values["colour"][0]) == 1.0 and math.copysign(1.0, values["ambient"]) == 1.0
    assert values["colour"][1:] == (0.5, 1.0)
    written = {}
    for zero in ("0.0", "-0.0"):
        folder = tmp_path / zero
        (folder / "materials").mkdir(parents=True)
        (folder / "materials" / "m.toml").write_text(f'type = "lambert"\ncolour = [{zero}, 0.5, 1.0]\n')
        write_bake(bake_atlas(read_materials([folder / "materials"])), folder / "a.dds")
        manifest = (folder / "a.json").read_text()
        written[zero] = (manifest.replace(folder.as_posix(), "FOLDER"), (folder / "a.dds").read_bytes())
    assert "-0.0" not in written["-0.0"][0]
    assert written["-0.0"][1] == written["0.0"][1]


@pytest.mark.parametrize(
    "body, field",
    [('type = "lambert"\nid = {big}\n', "id"), ('type = "lambert"\ncolour = [{big}, 0, 0]\n', "colour"),
     ("type = {big}\n", "type"), ('type = "toon"\nthresholds = [{big}]\n', "thresholds[0]")],
)  # fmt: skip
def test_an_integer_too_long_for_python_to_write_gets_the_field_s_line(tmp_path, body, field):
    """The finding: a 3.6 kB TOML hex literal is an integer of over 4300 digits, which Python refuses to write out;
    the message's repr of it raised ValueError, and the bake exited 1 ("internal error") instead of 3."""
    from atlasgen.errors import MaterialError
    from atlasgen.materials.material import read_materials

    path = tmp_path / "big.toml"
    path.write_text(body.replace("{big}", "0x" + "f" * 3600))
    with pytest.raises(MaterialError) as info:
        read_materials([path])
    message = str(info.value)
    assert (
        message.startswith(f"{path.as_posix()}: field '{field}': ") and "an integer of 14400 bits (about 4335 digits)" in message
    )
    assert "\n" not in message and len(message) < 300
