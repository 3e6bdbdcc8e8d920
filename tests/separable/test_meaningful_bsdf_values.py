"""Bad inputs that are meaningless rather than hard: a negative colour, a weight outside [0, 1], a
conductor with eta = k = 0 (issue 21). Each is one line naming the file and the dotted field, and the
bake writes nothing. The table is checked before Mitsuba is loaded, so these tests need no Mitsuba."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app
from atlasgen.errors import MaterialError
from atlasgen.separable.mitsuba_source import load_mitsuba_bsdf

RGB = {"type": "rgb", "value": [0.5, -0.1, 0.2]}


@pytest.mark.parametrize("spec, field, expected", [
    ({"type": "plastic", "diffuse_reflectance": -1}, "bsdf.diffuse_reflectance", "a reflectance >= 0 in every channel, got -1"),
    ({"type": "diffuse", "reflectance": RGB}, "bsdf.reflectance", "a reflectance >= 0 in every channel"),
    ({"type": "diffuse", "reflectance": {"type": "spectrum", "value": [[400.0, 0.2], [700.0, -0.3]]}}, "bsdf.reflectance",
     "a reflectance >= 0"),
    ({"type": "roughplastic", "specular_reflectance": -0.5}, "bsdf.specular_reflectance", "a reflectance >= 0"),
    ({"type": "principled", "base_color": RGB}, "bsdf.base_color", "a reflectance >= 0"),
    ({"type": "twosided", "material": {"type": "diffuse", "reflectance": -0.2}}, "bsdf.material.reflectance", ">= 0"),
    ({"type": "blendbsdf", "weight": 2.0, "a": {"type": "diffuse"}, "b": {"type": "diffuse"}}, "bsdf.weight",
     "a weight in [0, 1], got 2.0"),
    ({"type": "blendbsdf", "weight": -0.1, "a": {"type": "diffuse"}, "b": {"type": "diffuse"}}, "bsdf.weight", "[0, 1]"),
    ({"type": "principled", "metallic": 1.5}, "bsdf.metallic", "a weight in [0, 1], got 1.5"),
    ({"type": "conductor", "eta": 0, "k": 0}, "bsdf.eta", "eta or k > 0 for a conductor, got eta = k = 0"),
    ({"type": "roughconductor", "alpha": 0.2, "eta": {"type": "rgb", "value": [0, 0, 0]}, "k": 0.0}, "bsdf.eta", "eta = k = 0"),
    ({"type": "roughconductor", "alpha": 0.2, "eta": 1.0, "k": -2.0}, "bsdf.k", "a complex index part >= 0"),
])  # fmt: skip
def test_meaningless_values_are_refused_naming_the_field(spec, field, expected):
    with pytest.raises(MaterialError) as info:
        load_mitsuba_bsdf(spec, "materials/bad.toml")
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"materials/bad.toml: field '{field}': expected "), message
    assert expected in message, message


@pytest.mark.parametrize("spec", [
    {"type": "blendbsdf", "weight": 0.0, "a": {"type": "diffuse"}, "b": {"type": "diffuse"}},
    {"type": "blendbsdf", "weight": 1.0, "a": {"type": "diffuse", "reflectance": 0.0}, "b": {"type": "diffuse"}},
    {"type": "roughconductor", "alpha": 0.2, "eta": 0.0, "k": 1.0},  # a perfect mirror's index: meaningful
])  # fmt: skip
def test_the_bounds_themselves_are_accepted(spec):
    from atlasgen.separable.mitsuba_source import _check_bsdf_values

    _check_bsdf_values(spec, "materials/ok.toml", "bsdf")  # raises nothing


@pytest.mark.parametrize("body, field", [
    ('type = "bsdf"\nbsdf = { type = "plastic", diffuse_reflectance = -1 }\n', "bsdf.diffuse_reflectance"),
    ('type = "separable"\nsource = "mitsuba"\nterms = 1\nbsdf = { type = "blendbsdf", weight = 2.0, '
     'a = { type = "diffuse" }, b = { type = "diffuse" } }\n', "bsdf.weight"),
    ('type = "separable"\nsource = "mitsuba"\nterms = 1\nbsdf = { type = "conductor", eta = 0, k = 0 }\n', "bsdf.eta"),
])  # fmt: skip
def test_the_bake_refuses_them_with_one_line_and_writes_nothing(write_material, tmp_path, body, field):
    write_material("bad", body)
    out = tmp_path / "out" / "a.dds"
    result = CliRunner().invoke(app, ["bake", str(tmp_path / "materials"), "-o", str(out)])
    assert result.exit_code == 3, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("atlasgen: error: ") and f"field '{field}'" in lines[0], lines
    assert "bad.toml" in lines[0] and not (tmp_path / "out").exists()
