"""``atlasgen render``: outputs, AOVs and one-line errors with their exit codes."""

from __future__ import annotations

import os

import numpy as np
import pytest
from click.testing import CliRunner

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.cli.main import app
from atlasgen.materials.material import read_materials

SCENE = """
[camera]
position = [0, 0, 4]
target = [0, 0, 0]
[image]
width = 40
height = 30
[[lights]]
type = "directional"
direction = [0, 0, -1]
intensity = 3.14159265
[[objects]]
shape = "sphere"
material = "{material}"
"""


@pytest.fixture
def atlas(tmp_path, write_material):
    write_material("clay", 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n')
    write_material("snow", 'type = "lambert"\nid = 9\n')
    path = tmp_path / "build" / "atlas.dds"
    path.parent.mkdir()
    write_bake(bake_atlas(read_materials([tmp_path / "materials"])), path)
    return path


def write_scene(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def read_exr(path):
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(str(path))
    return buf.get_pixels(oiio.FLOAT), buf.spec()


@pytest.mark.slow
def test_render_writes_exr_png_and_aov(gpu_device, atlas, tmp_path):
    scene = write_scene(tmp_path, SCENE.format(material="snow"))
    out = tmp_path / "out.exr"
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert out.exists() and out.with_suffix(".png").exists()
    pixels, spec = read_exr(out)
    assert spec.width == 40 and spec.height == 30
    # Centre pixel: N.L = N.V = 1 on a white lambert with E = pi: radiance 1.
    assert pixels[15, 20, 0] == pytest.approx(1.0, abs=0.01)
    ids = tmp_path / "ids.exr"
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(ids), "--aov", "id"])
    assert res.exit_code == 0, res.output
    pixels, spec = read_exr(ids)
    assert list(spec.channelnames) == ["id"]
    assert set(np.unique(pixels)) == {9.0, 65535.0}
    # An AOV over a lit render's EXR: the lit PNG beside it goes in the same commit, not left showing another run.
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(out), "--aov", "depth"])
    assert res.exit_code == 0, res.output
    assert list(read_exr(out)[1].channelnames) == ["Z"]
    assert not os.path.lexists(out.with_suffix(".png"))


@pytest.mark.slow
def test_a_scene_without_lights_or_environment_warns_after_rendering(gpu_device, atlas, tmp_path):
    """Valid, and black: the lit render says so once, after its outputs; an AOV, which needs no light, does not."""
    unlit = SCENE.format(material="snow").replace('[[lights]]\ntype = "directional"\ndirection = [0, 0, -1]\n'
                                                  'intensity = 3.14159265\n', "")  # fmt: skip
    scene = write_scene(tmp_path, unlit)
    out = tmp_path / "out.exr"
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert res.stderr.splitlines() == [
        f"atlasgen: warning: {scene}: no [[lights]] and no [environment]: every object renders black"
    ]
    assert read_exr(out)[0][15, 20, :3].max() == 0.0
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(tmp_path / "n.exr"), "--aov", "normal"])
    assert res.exit_code == 0 and res.stderr == ""
    lit = write_scene(tmp_path, SCENE.format(material="snow"), "lit.toml")
    res = CliRunner().invoke(app, ["render", str(lit), "--atlas", str(atlas), "-o", str(out)])
    assert res.exit_code == 0 and res.stderr == ""


@pytest.mark.parametrize(
    "scene_text, words",
    [
        (SCENE.format(material="gold"), "unknown material 'gold'; expected one of the names in"),
        (SCENE.format(material="clay").replace('shape = "sphere"', 'shape = "mesh"\nfile = "nope.obj"'), "no such mesh file"),
        (
            SCENE.format(material="clay") + "[[lights]]\ntype = 'point'\nposition = [0, 0, 1]\nintensity = 1\n" * 1025,
            "expected at most 1024",
        ),
    ],
)
def test_bad_scenes_fail_with_one_line(atlas, tmp_path, scene_text, words):
    scene = write_scene(tmp_path, scene_text)
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(tmp_path / "o.exr")])
    assert res.exit_code == 3
    assert res.stderr.count("\n") == 1 and words in res.stderr
    assert res.stderr.startswith(f"atlasgen: error: {scene.as_posix()}: field '")
    if "unknown material" in words:
        assert "clay, snow" in res.stderr
    assert not (tmp_path / "o.exr").exists()


def test_no_adapter(atlas, tmp_path, monkeypatch):
    wgpu = pytest.importorskip("wgpu")
    # Loading the native backend replaces ``wgpu.gpu``: patch the object create_device will call,
    # not the placeholder a bare ``import wgpu`` gives (the test passed only after another had loaded it).
    pytest.importorskip("wgpu.backends.wgpu_native")
    from atlasgen.render import device

    monkeypatch.setattr(device, "_shared", None)
    monkeypatch.setattr(wgpu.gpu, "request_adapter_sync", lambda **kwargs: None)
    scene = write_scene(tmp_path, SCENE.format(material="clay"))
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(tmp_path / "o.exr")])
    assert res.exit_code == 5, (res.stdout, res.stderr)
    assert "apt-get install mesa-vulkan-drivers" in res.stderr and res.stderr.count("\n") == 1


def test_missing_atlas(tmp_path):
    scene = write_scene(tmp_path, SCENE.format(material="clay"))
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(tmp_path / "x.dds"), "-o", str(tmp_path / "o.exr")])
    assert res.exit_code == 3 and "no such atlas; bake one first (atlasgen bake MATERIAL_FILES_OR_FOLDERS -o" in res.stderr
    # The manifest given for the atlas is named as what it is.
    (tmp_path / "x.json").write_text("{}")
    res = CliRunner().invoke(app, ["info", str(tmp_path / "x.json")])
    assert res.exit_code == 3 and "expected the atlas texture (.dds or .ktx2) beside this manifest" in res.stderr


def test_an_output_of_another_kind_is_a_usage_error(atlas, tmp_path):
    """``-o x.png`` is a bad option value (exit 2, docs/cli.md), not an output that cannot be written (4)."""
    scene = write_scene(tmp_path, SCENE.format(material="clay"))
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(tmp_path / "x.png")])
    assert (res.exit_code, res.stderr) == (
        2,
        f"atlasgen: error: {(tmp_path / 'x.png').as_posix()}: expected an .exr output path\n",
    )
    assert not (tmp_path / "x.png").exists()


@pytest.mark.gpu
@pytest.mark.parametrize("flag", ["-q", "-v"])
@pytest.mark.slow
def test_quiet_prints_nothing_and_verbose_describes_the_scene(gpu_device, atlas, tmp_path, flag):
    scene = write_scene(tmp_path, SCENE.format(material="snow"))
    out = tmp_path / "out.exr"
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(out), flag])
    assert res.exit_code == 0, res.output
    assert out.exists() and out.with_suffix(".png").exists()
    if flag == "-q":
        assert res.output == ""
    else:
        assert res.stderr == f"{scene.as_posix()}: 40x30, 1 object, 1 light; materials snow\n"
        assert res.stdout.splitlines() == [f"wrote {out.as_posix()}", f"wrote {out.with_suffix('.png').as_posix()}"]
    assert gpu_device.take_errors() == []


@pytest.mark.slow
def test_an_object_beyond_float32_once_transformed_is_refused_not_rendered_black(gpu_device, atlas, tmp_path):
    """scale and translate each fit float32; the transformed sphere does not, and would draw nothing."""
    scene = write_scene(tmp_path, SCENE.format(material="snow") + "scale = 3e38\ntranslate = [3e38, 0, 0]\n")
    out = tmp_path / "out.exr"
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(out)])
    assert res.exit_code == 3, res.output
    assert res.stderr.splitlines() == [f"atlasgen: error: {scene.as_posix()}: field 'objects[0]': expected the object within "
                                       "float32's range once scaled, rotated and translated, got a bounding-box corner at "
                                       "6e+38"]  # fmt: skip
    assert not out.exists()


#: SCENE's camera and image, lit by a sky image, with one mesh object.
MESH_SCENE = ('environment = "env/sky.exr"\n' + SCENE.split("[[lights]]")[0]
              + '[[objects]]\nshape = "mesh"\nfile = "meshes/tri.obj"\nmaterial = "clay"\n')  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("aov", [None, "depth"])
def test_the_depfile_names_the_image_against_every_file_the_render_read(gpu_device, atlas, tmp_path, aov):
    """The Makefile's render rule listed scenes/meshes/* and no environment image: a new sky.exr, or a mesh kept
    elsewhere, left the image stale with make -q at 0. The depfile names what this scene reads, wherever it is."""
    from atlasgen.io.images import write_exr

    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "tri.obj").write_text("v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "env").mkdir()
    write_exr(tmp_path / "env" / "sky.exr", np.full((8, 16, 3), 0.5, dtype=np.float32))
    scene = write_scene(tmp_path, MESH_SCENE)
    out, dep = tmp_path / "out" / "r.exr", tmp_path / "out" / "r.d"
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(out), "--depfile", str(dep),
                                   *(["--aov", aov] if aov else [])])  # fmt: skip
    assert res.exit_code == 0, res.output
    image = out if aov else out.with_suffix(".png")
    inputs = [scene, atlas, atlas.with_suffix(".json"), atlas.with_suffix(".wgsl"), tmp_path / "meshes" / "tri.obj",
              tmp_path / "env" / "sky.exr"]  # fmt: skip
    expected = [f"{image.as_posix()}: \\"] + [f"  {p.as_posix()} \\" for p in inputs[:-1]] + [f"  {inputs[-1].as_posix()}", ""]
    expected += [f"{p.as_posix()}:" for p in inputs]
    assert dep.read_text().splitlines() == expected
    assert gpu_device.take_errors() == []


def test_no_depfile_is_written_when_the_render_fails(atlas, tmp_path):
    """It is one commit with the image: a render that fails changes neither."""
    scene = write_scene(tmp_path, SCENE.format(material="nope"))
    dep = tmp_path / "r.d"
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(tmp_path / "r.exr"),
                                   "--depfile", str(dep)])  # fmt: skip
    assert res.exit_code == 3 and not dep.exists() and not (tmp_path / "r.png").exists()


def test_a_depfile_may_not_overwrite_an_input(atlas, tmp_path):
    scene = write_scene(tmp_path, SCENE.format(material="clay"))
    before = scene.read_bytes()
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(tmp_path / "r.exr"),
                                   "--depfile", str(scene)])  # fmt: skip
    assert res.exit_code == 4 and "--depfile would overwrite the scene" in res.stderr, res.output
    assert scene.read_bytes() == before


@pytest.mark.slow
def test_a_render_beside_its_scene_s_atlas_keeps_to_its_own_files(gpu_device, atlas, tmp_path):
    """The scene's bake (b/x.dds, b/x.d) and render (b/x.exr) share one set: render --depfile b/x.d replaced the
    bake's depfile (exit 0), and a render without --depfile left the earlier render's beside the new image."""
    from atlasgen.materials.material import read_material

    scene = write_scene(tmp_path, SCENE.format(material="clay"), "x.toml")
    b = tmp_path / "b"
    baked = CliRunner().invoke(app, ["bake", str(read_material(tmp_path / "materials" / "clay.toml").source), "--scene",
                                     str(scene), "-o", str(b / "x.dds"), "--depfile", str(b / "x.d"), "-q"])  # fmt: skip
    assert baked.exit_code == 0, baked.output
    rule = (b / "x.d").read_bytes()
    args = ["render", str(scene), "--atlas", str(b / "x.dds"), "-o", str(b / "x.exr")]
    res = CliRunner().invoke(app, [*args, "--depfile", str(b / "x.d")])
    assert res.exit_code == 4 and "already written by `atlasgen bake -o x.dds/.ktx2` into the same output set" in res.stderr
    assert (b / "x.d").read_bytes() == rule and not (b / "x.png").exists()
    assert CliRunner().invoke(app, [*args, "--depfile", str(b / "x.png.d")]).exit_code == 0
    assert CliRunner().invoke(app, args).exit_code == 0
    assert not os.path.lexists(b / "x.png.d") and (b / "x.d").read_bytes() == rule and (b / "x.json").exists()
    assert gpu_device.take_errors() == []


def test_render_neither_removes_an_input_with_aov_nor_writes_a_depfile_named_as_a_material(atlas, tmp_path):
    """A hostile sweep: a scene named k.png rendered to k.exr with --aov was deleted (the commit removes the PNG name
    beside an AOV), and --depfile terracotta.toml replaced that material file with a make fragment, which a later
    render without --depfile then removed. Both are refused before anything renders."""
    scene = write_scene(tmp_path, SCENE.format(material="snow"), name="k.png")
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(tmp_path / "k.exr"), "--aov", "depth"])
    assert res.exit_code == 4 and res.stderr == (
        f"atlasgen: error: {scene.as_posix()}: the PNG beside the render (removed with --aov) would overwrite the scene "
        f"({scene.as_posix()}); expected an output path that is not an input\n"), res.output  # fmt: skip
    assert scene.read_text() == SCENE.format(material="snow") and not (tmp_path / "k.exr").exists()
    material = tmp_path / "materials" / "clay.toml"
    before = material.read_bytes()
    res = CliRunner().invoke(app, ["render", str(scene), "--atlas", str(atlas), "-o", str(tmp_path / "o.exr"),
                                   "--depfile", str(material)])  # fmt: skip
    assert res.exit_code == 2 and "--depfile must not end in .toml or .mtlx" in res.stderr, res.output
    assert material.read_bytes() == before and not material.is_symlink()
