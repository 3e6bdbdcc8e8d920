"""Numbers at the float32/shader boundary: every material, scene and command-line number is
checked where it is read, with one line naming the file and the field; what a model
produces is checked per material; renders never hold a NaN or infinite pixel."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from atlasgen.errors import MaterialError, SceneError
from atlasgen.io.fields import FLOAT32_MAX, Param, fits_float32, to_float32

HUGE_INT = "1" + "0" * 400


def test_fits_float32_is_the_float32_range():
    assert fits_float32(FLOAT32_MAX) and fits_float32(-FLOAT32_MAX) and fits_float32(0) and fits_float32(10**38)
    assert not fits_float32(np.nextafter(FLOAT32_MAX, np.inf)) and not fits_float32(10**39)
    assert not fits_float32(int(HUGE_INT)) and not fits_float32(float("nan")) and not fits_float32(float("inf"))
    assert not fits_float32(True) and not fits_float32("1")
    assert to_float32(0.1) == float(np.float32(0.1)) and to_float32(1e-50) == 0.0


@pytest.mark.parametrize("body,field,expected", [
    ("rgb_scale = 1e300", "rgb_scale", "got 1e+300"),
    (f"rgb_scale = {HUGE_INT}", "rgb_scale", "(401 characters)"),
    ("alpha_scale = 1e-50", "alpha_scale", "got 1e-50"),
    ("error_budget = 1e-50", "error_budget", "got 1e-50"),
    (f"error_budget = {HUGE_INT}", "error_budget", "(401 characters)"),
    ("colour = [1e400, 0, 0]", "colour", "got [inf, 0, 0]"),
    (f"id = {HUGE_INT}", "id", "(401 characters)"),
])  # fmt: skip
def test_common_fields_must_fit_float32(expect_rejected, body, field, expected):
    message = expect_rejected("lambert", body, field, expected)
    assert len(message) < 300


@pytest.mark.parametrize("type_name,body,field,expected", [
    ("separable", "source = \"blinn_phong\"\nexponent = 1e-50", "exponent", "got 1e-50 (0 in float32)"),
    ("separable", f"terms = {HUGE_INT}", "terms", "expected an integer >= 1 and <= 32"),
    ("separable", "terms = 4294967297", "terms", "got 4294967297"),
    ("sss", "variances = [1e-300]\nweights = [[1, 1, 1]]", "variances[0]", "got 1e-300 (0 in float32)"),
    ("sss", "variances = [1e-310]\nweights = [[1, 1, 1]]", "variances[0]", "(0 in float32)"),
    ("iridescent", "thickness = 1e39", "thickness", "(beyond float32's range)"),
    ("fresnel", f"ior = {HUGE_INT}", "ior", "(beyond float32's range)"),
])  # fmt: skip
def test_model_parameters_must_fit_float32_and_keep_their_bounds(expect_rejected, type_name, body, field, expected):
    expect_rejected(type_name, body, field, expected)


def test_a_bound_is_checked_after_rounding_to_float32():
    param = Param("x", 0.5, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    assert param.coerce(0.25, "m.toml") == 0.25
    for value in (1e-46, 1.0 - 1e-12):  # > 0 and < 1, but 0 and 1 in float32
        with pytest.raises(MaterialError, match="in float32"):
            param.coerce(value, "m.toml")


def _model_output(monkeypatch, values):
    from atlasgen.models.lambert import Lambert

    monkeypatch.setattr(Lambert, "evaluate", lambda self, v, nl, nv: np.broadcast_to(values, np.broadcast_shapes(
        np.shape(nl), np.shape(nv)) + (4,)))  # fmt: skip


@pytest.mark.parametrize("texel,expected", [
    ([np.nan, 0.0, 0.0, 0.0], "model 'lambert' produced 2048 non-finite texels"),
    ([1e39, 0.0, 0.0, 0.0], "model 'lambert' produced a slice scale that float32 cannot hold"),
])  # fmt: skip
def test_model_output_is_checked_per_material(write_material, tmp_path, monkeypatch, texel, expected):
    from atlasgen.cli.main import app

    write_material("fine", 'type = "fresnel"\n')
    write_material("odd", 'type = "lambert"\n')
    _model_output(monkeypatch, np.array(texel))
    # -j 1: the patched model exists in this process only, not in bake workers.
    res = CliRunner().invoke(app, ["bake", str(tmp_path / "materials"), "-o", str(tmp_path / "a.dds"), "-j", "1"])
    assert res.exit_code == 3
    (line,) = res.stderr.splitlines()
    assert f"{(tmp_path / 'materials' / 'odd.toml').as_posix()}: material 'odd': {expected}" in line
    assert not (tmp_path / "a.dds").exists()


SCENE = """\
[camera]
position = {camera}
target = [0, 0, 0]
[image]
width = {width}
height = 8
[[lights]]
type = "point"
position = [0, 3, 3]
intensity = {intensity}
[[objects]]
shape = "sphere"
material = "clay"
translate = {translate}
"""


@pytest.mark.parametrize("change,field,expected", [
    ({"intensity": "1e39"}, "lights[0].intensity", "expected a finite number >= 0, got 1e+39 (beyond float32"),
    ({"camera": "[0, 1, 1e308]"}, "camera.position", "3 finite float32 numbers, got [0, 1, 1e+308]"),
    ({"camera": "[0, 0, 3e38]", "translate": "[0, 0, 0]"}, "camera.position", None),
    ({"width": HUGE_INT}, "image.width", "(401 characters)"),
    ({"translate": "[1e39, 0, 0]"}, "objects[0].translate", "float32"),
])  # fmt: skip
def test_scene_numbers_must_fit_float32(tmp_path, change, field, expected):
    from atlasgen.materials.scene import read_scene

    values = {"camera": "[0, 1, 5]", "width": "8", "intensity": "10", "translate": "[0, 0, 0]", **change}
    path = tmp_path / "s.toml"
    path.write_text(SCENE.format(**values))
    if expected is None:  # 3e38 is float32, and so is the offset to the target
        read_scene(path)
        return
    with pytest.raises(SceneError) as info:
        read_scene(path)
    message = str(info.value)
    assert message.startswith(f"{path.as_posix()}: field '{field}': ") and expected in message and len(message) < 300


def test_a_camera_close_to_its_target_is_a_small_scene_s_camera(tmp_path):
    """The camera's target was compared with an absolute tolerance of 1e-8: a camera 5e-9 from it was refused."""
    from atlasgen.materials.scene import read_scene

    path = tmp_path / "s.toml"
    path.write_text("[camera]\nposition = [0, 0, 5e-9]\ntarget = [0, 0, 0]\nnear = 1e-10\nfar = 1e-8\n")
    assert read_scene(path).camera.position == (0.0, 0.0, 5e-9)
    path.write_text("[camera]\nposition = [0, 0, 1]\ntarget = [0, 0, 1.00000001]\n")  # one point in float32
    with pytest.raises(SceneError, match=r"field 'camera.target': expected a point different"):
        read_scene(path)


def test_a_camera_offset_beyond_float32_is_refused(tmp_path):
    from atlasgen.materials.scene import read_scene

    path = tmp_path / "s.toml"
    path.write_text("[camera]\nposition = [0, 0, 3e38]\ntarget = [0, 0, -3e38]\n")
    with pytest.raises(SceneError, match=r"field 'camera.target': expected a point whose offset"):
        read_scene(path)


@pytest.mark.parametrize("obj,expected", [
    ("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "vertex 2 is [nan, 0.0, 0.0]; expected finite float32 coordinates"),
    ("v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n", "vertex 2 is [1e+39, 0.0, 0.0]"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 5\n", "objects[0].file"),
])  # fmt: skip
def test_mesh_errors_name_the_scene_file_and_field(tmp_path, obj, expected):
    pytest.importorskip("trimesh")
    from atlasgen.materials.scene import read_scene
    from atlasgen.render.meshes import build_mesh

    (tmp_path / "m.obj").write_text(obj)
    path = tmp_path / "s.toml"
    path.write_text('[camera]\nposition = [0, 0, 5]\ntarget = [0, 0, 0]\n'
                    '[[objects]]\nshape = "mesh"\nfile = "m.obj"\nmaterial = "clay"\n')  # fmt: skip
    scene = read_scene(path)
    with pytest.raises(SceneError) as info:
        build_mesh(scene.objects[0], scene.path)
    message = str(info.value)
    assert message.startswith(f"{path.as_posix()}: field 'objects[0].file': ") and expected in message


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "17"])
def test_cli_floats_are_finite_and_bounded(tmp_path, value):
    from atlasgen.cli.main import app

    (tmp_path / "s.toml").write_text("")
    res = CliRunner().invoke(app, ["render", str(tmp_path / "s.toml"), "-o", str(tmp_path / "r.exr"), "--mip-bias", value])
    assert res.exit_code == 2 and len(res.stderr.splitlines()) == 1 and "--mip-bias" in res.stderr


@pytest.mark.mitsuba
@pytest.mark.parametrize("bsdf,field,expected", [
    ('{ type = "null" }', "bsdf.type", "expected a BSDF with a diffuse or glossy reflection, got 'null'"),
    ('{ type = "dielectric" }', "bsdf.type", "a 'dielectric' BSDF transmits light"),
    ('{ type = ["lambert"] }', "bsdf.type", "expected a Mitsuba plugin name (a string), got ['lambert']"),
    ('{ type = "roughconductor", alpha = -0.2 }', "bsdf.alpha", "expected a roughness > 0 and <= 4, got -0.2"),
    ('{ type = "roughconductor", alpha_u = 0.1, alpha_v = 0 }', "bsdf.alpha_v", "got 0"),
    ('{ type = "twosided", bsdf = { type = "roughplastic", alpha = 9 } }', "bsdf.bsdf.alpha", "got 9"),
    ('{ type = "principled", roughness = 1.5 }', "bsdf.roughness", "expected a roughness in [0, 1]"),
    ('{ type = "roughconductor", eta = 1e39 }', "bsdf.eta", "expected a finite float32 number"),
])  # fmt: skip
def test_mitsuba_bsdf_tables_are_checked(expect_rejected, mitsuba_llvm, bsdf, field, expected):
    expect_rejected("separable", f'source = "mitsuba"\nterms = 2\nbsdf = {bsdf}', field, expected)


@pytest.mark.gpu
@pytest.mark.slow
def test_adversarial_scenes_render_only_finite_pixels(tmp_path, gpu_device):
    """The largest float32 intensities, lights and objects far away or inside each other,
    degenerate meshes and scales: every pixel of the EXR and of the PNG's source is finite. (A light
    whose colour x intensity passes float32 is refused: tests/render/test_scene.py.)"""
    import OpenImageIO as oiio

    from atlasgen.cli.main import app

    folder = tmp_path / "materials"
    folder.mkdir()
    (folder / "clay.toml").write_text('type = "lambert"\n')
    (folder / "gloss.toml").write_text('type = "fresnel"\n')
    atlas = tmp_path / "a.dds"
    assert CliRunner().invoke(app, ["bake", str(folder), "-o", str(atlas), "-q"]).exit_code == 0
    (tmp_path / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 0 0\nf 1 2 3\nf 1 4 2\n")  # zero-area faces
    big = repr(FLOAT32_MAX)
    scenes = {
        "intense": f"""
            [[lights]]
            type = "point"
            position = [0, 2, 3]
            intensity = {big}
            [[lights]]
            type = "directional"
            direction = [0, -1, -1]
            intensity = {big}
            colour = [1, 0.5, 1]
            [[objects]]
            shape = "sphere"
            material = "gloss"
            """,
        "inside": """
            [[lights]]
            type = "point"
            position = [0, 0, 0]
            intensity = 1e30
            [[objects]]
            shape = "sphere"
            material = "clay"
            scale = 1e-30
            [[objects]]
            shape = "box"
            material = "clay"
            translate = [0, 0, 1e30]
            scale = [1e30, 1e-30, 3e38]
            [[objects]]
            shape = "mesh"
            file = "flat.obj"
            material = "gloss"
            opacity = 0.5
            """,
        "far": """
            [[lights]]
            type = "point"
            position = [3e38, 3e38, 3e38]
            intensity = 3e38
            [[objects]]
            shape = "torus"
            material = "clay"
            minor_radius = 1e-30
            rotate = [3e38, -3e38, 1e30]
            opacity = 0.0
            """,
    }
    for name, body in scenes.items():
        # The widest depth range a camera may have (far = 1e5 near; near 1e-30 with far 3e38 is refused now).
        text = "[camera]\nposition = [0, 1, 5]\ntarget = [0, 0, 0]\nnear = 3e-4\nfar = 30\n"
        text += "[image]\nwidth = 24\nheight = 16\n" + "\n".join(line.strip() for line in body.splitlines()) + "\n"
        (tmp_path / f"{name}.toml").write_text(text)
        out = tmp_path / f"{name}.exr"
        res = CliRunner().invoke(app, ["render", str(tmp_path / f"{name}.toml"), "--atlas", str(atlas), "-o", str(out)])
        assert res.exit_code == 0, (name, res.output)
        pixels = oiio.ImageBuf(str(out)).get_pixels(oiio.FLOAT)
        assert pixels.shape == (16, 24, 3) and np.isfinite(pixels).all(), name


@pytest.mark.parametrize("key,value", [("up", "[0, 0, 3.9e-232]"), ("up", "[1e38, 3e38, 0]")])
def test_camera_directions_of_any_magnitude_give_a_unit_up(tmp_path, key, value):
    """Found by the fuzz suite: an ``up`` of 1e-232 passed as not parallel, then its norm
    underflowed to 0 and the camera frame was NaN."""
    from atlasgen.materials.scene import read_scene
    from atlasgen.render.camera import camera_basis

    path = tmp_path / "s.toml"
    path.write_text(f"[camera]\nposition = [0, 1, 5]\ntarget = [0, 0, 0]\n{key} = {value}\n")
    camera = read_scene(path).camera
    assert np.isclose(np.linalg.norm(camera.up), 1.0)
    assert all(np.isfinite(v).all() and np.isclose(np.linalg.norm(v), 1.0) for v in camera_basis(camera))


def test_a_tiny_light_direction_is_normalised(tmp_path):
    from atlasgen.materials.scene import read_scene

    path = tmp_path / "s.toml"
    path.write_text('[camera]\nposition = [0, 1, 5]\ntarget = [0, 0, 0]\n'
                    '[[lights]]\ntype = "directional"\ndirection = [0, -1e-300, 0]\nintensity = 1\n')  # fmt: skip
    assert read_scene(path).lights[0].direction == (0.0, -1.0, 0.0)


def test_the_materials_doc_states_the_ranges_as_the_code_checks_them():
    """docs/materials.md's paragraph on float32 ranges: each figure it gives, measured here."""
    from atlasgen.io.fields import MAX_TABLE_DEPTH, MAX_TABLE_ENTRIES
    from atlasgen.models.backlit import Backlit

    doc = (Path(__file__).resolve().parents[1] / "docs" / "materials.md").read_text(encoding="utf-8")
    paragraph = " ".join(doc.split("Every range below is checked twice", 1)[1].split("\n\n", 1)[0].split())
    smallest = float(np.nextafter(np.float32(0), np.float32(1)))
    assert f"at least {smallest:.2g}:" in paragraph
    power = next(p for p in Backlit.params if p.name == "power")
    assert power.coerce(smallest, "m.toml") == smallest
    with pytest.raises(MaterialError) as refused:
        power.coerce(1e-300, "m.toml")
    message = str(refused.value).split(": ", 2)[2]
    assert f"(`{message}`)" in paragraph
    below_one = Param("x", 0.5, lo=0.0, hi=1.0, hi_open=True)
    with pytest.raises(MaterialError, match="1 in float32"):
        below_one.coerce(1 - 1e-12, "m.toml")
    assert "`< 1` likewise refuses 1 - 1e-12, which is 1 in float32" in paragraph
    assert f"about {float(np.finfo(np.float32).max):.2g}".replace("e+", "e") in paragraph
    assert f"nests at most {MAX_TABLE_DEPTH} tables" in paragraph and f"at most {MAX_TABLE_ENTRIES} keys" in paragraph
