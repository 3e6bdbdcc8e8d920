"""The scene's ``environment`` key: every form it takes, its defaults, and one line for every bad value."""

import math
import textwrap
import tomllib

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.errors import SceneError
from atlasgen.io.images import write_exr
from atlasgen.materials.scene import SKY_KEYS, parse_scene, read_scene
from atlasgen.optics.sky import SkyParameters

CAMERA = "[camera]\nposition = [0, 0, 5]\ntarget = [0, 0, 0]\n"


def _scene(text, base=None, path="scenes/x.toml"):
    # Top-level keys come before the first table.
    return parse_scene(tomllib.loads(textwrap.dedent(text) + "\n" + CAMERA), path, base)


def _rejects(text, field, words, base=None):
    with pytest.raises(SceneError) as info:
        _scene(text, base)
    message = str(info.value)
    assert message.startswith(f"scenes/x.toml: field '{field}': ") and "\n" not in message, message
    assert words in message, message
    return message


def test_no_environment_by_default():
    assert _scene("").environment is None


def test_a_uniform_radiance():
    env = _scene("environment = [0.5, 1, 2]").environment
    assert (env.source, env.radiance, env.intensity, env.rotate, env.file, env.sky) == (
        "uniform",
        (0.5, 1.0, 2.0),
        1.0,
        0.0,
        None,
        None,
    )


def test_the_built_in_sky_with_defaults_and_with_its_parameters():
    assert _scene('environment = "sky"').environment.sky == SkyParameters()
    env = _scene("""
        [environment]
        source = "sky"
        intensity = 2.5
        rotate = -30
        sun_direction = [0, 3, 4]
        sun_irradiance = 5
        sun_colour = [1, 0.9, 0.8]
        sun_radius = 1.5
        zenith = [0.1, 0.2, 0.9]
        horizon = [0.7, 0.8, 0.9]
        ground = [0.2, 0.2, 0.2]
    """).environment
    assert (env.source, env.intensity, env.rotate) == ("sky", 2.5, -30.0)
    assert env.sky == SkyParameters((0.0, 0.6, 0.8), 5.0, (1.0, 0.9, 0.8), 1.5, (0.1, 0.2, 0.9), (0.7, 0.8, 0.9), (0.2, 0.2, 0.2))
    assert {f.name for f in SkyParameters.__dataclass_fields__.values()} == set(SKY_KEYS)


def test_a_file_relative_to_the_scene(tmp_path):
    (tmp_path / "hdri").mkdir()
    write_exr(tmp_path / "hdri" / "studio.exr", np.ones((4, 8, 3), np.float32))
    scene_file = tmp_path / "s.toml"
    scene_file.write_text('[environment]\nsource = "hdri/studio.exr"\nintensity = 0.5\nrotate = 90\n' + CAMERA)
    env = read_scene(scene_file).environment
    assert (env.source, env.file, env.intensity, env.rotate) == ("file", tmp_path / "hdri" / "studio.exr", 0.5, 90.0)
    assert _scene('environment = "hdri/studio.exr"', base=tmp_path).environment.file == tmp_path / "hdri" / "studio.exr"


def test_a_scene_may_have_an_environment_and_no_lights_or_objects(tmp_path):
    scene_file = tmp_path / "only-sky.toml"
    scene_file.write_text('environment = "sky"\n' + CAMERA)
    scene = read_scene(scene_file)
    assert scene.lights == [] and scene.objects == [] and scene.environment.source == "sky"


@pytest.mark.parametrize(
    "text, field, words",
    [
        ("environment = -1", "environment", "expected a radiance [r, g, b] in W/(m^2 sr), an image file (.exr, .hdr) or \"sky\", got -1"),
        ("environment = true", "environment", "an image file (.exr, .hdr) or \"sky\", got true"),
        ('environment = ""', "environment", "got ''"),
        ("environment = [1, -1, 0]", "environment", ">= 0"),
        ("environment = [1, 2]", "environment", "[x, y, z] of 3 finite float32 numbers"),
        ("environment = [1, 2, nan]", "environment", "[x, y, z] of 3 finite float32 numbers"),
        ("environment = [1, 2, 1e39]", "environment", "[x, y, z] of 3 finite float32 numbers"),
        ('environment = "sky.png"', "environment", "expected an OpenEXR (.exr) or Radiance HDR (.hdr) image, or \"sky\", got 'sky.png'"),
        ('environment = "Sky"', "environment", "got 'Sky'"),
        ('environment = "gone.exr"', "environment", "no such environment image 'gone.exr'; expected an .exr or .hdr file"),
        ("[environment]\nintensity = 2", "environment.source", "missing; expected a radiance [r, g, b]"),
        ("[environment]\nsource = 3", "environment.source", "got 3"),
        ('[environment]\nsource = "sky"\nintensity = -1', "environment.intensity", ">= 0"),
        ('[environment]\nsource = "sky"\nintensity = 1e39', "environment.intensity", "beyond float32's range"),
        ('[environment]\nsource = "sky"\nrotate = nan', "environment.rotate", "not finite"),
        ('[environment]\nsource = "sky"\nrotate = "90"', "environment.rotate", "expected a finite number, got '90'"),
        ('[environment]\nsource = "sky"\nsun_direction = [0, 0, 0]', "environment.sun_direction", "not all zero"),
        ('[environment]\nsource = "sky"\nsun_irradiance = -3', "environment.sun_irradiance", ">= 0"),
        ('[environment]\nsource = "sky"\nsun_radius = 0', "environment.sun_radius", "> 0 and <= 90"),
        ('[environment]\nsource = "sky"\nsun_radius = 91', "environment.sun_radius", "> 0 and <= 90"),
        ('[environment]\nsource = "sky"\nsun_colour = [1, 1]', "environment.sun_colour", "[x, y, z]"),
        ('[environment]\nsource = "sky"\nzenith = [-1, 0, 0]', "environment.zenith", ">= 0"),
        ('[environment]\nsource = "sky"\nhorizon = "blue"', "environment.horizon", "[x, y, z]"),
        ('[environment]\nsource = "sky"\nground = [0, 0, -0.1]', "environment.ground", ">= 0"),
        ("[environment]\nsource = [1, 1, 1]\nsun_direction = [0, 1, 0]", "environment.sun_direction",
         'only used with source = "sky", not [1, 1, 1]'),
        ('[environment]\nsource = "sky"\nturbidity = 3', "environment.turbidity", "unknown key"),
        ('[environment]\nsource = "sky"\nsun_directon = [0, 1, 0]', "environment.sun_directon", "did you mean 'sun_direction'?"),
    ],
)  # fmt: skip
def test_every_bad_value_is_one_line(text, field, words):
    _rejects(text, field, words)


@pytest.mark.slow
@given(st.one_of(st.integers(), st.floats(allow_nan=True), st.booleans(), st.none(), st.text(max_size=8),
                 st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(), st.text(max_size=2)), max_size=5)))  # fmt: skip
def test_any_value_parses_or_is_refused_on_one_line(value):
    data = tomllib.loads(CAMERA)
    data["environment"] = value
    try:
        env = parse_scene(data, "scenes/x.toml", base="/nonexistent-folder").environment
    except SceneError as exc:
        message = str(exc)
        assert message.startswith("scenes/x.toml: field 'environment': ") and "\n" not in message, message
        return
    if env.source == "uniform":
        assert len(value) == 3 and all(0.0 <= float(c) and math.isfinite(float(c)) for c in value)
    else:
        assert value == "sky" and env.source == "sky"


@pytest.mark.parametrize(
    ("text", "field", "words"),
    [
        ("environment = [70000, 1, 1]", "environment", "the radiance reaches 70000 W/(m^2 sr), beyond the 65504"),
        ("[environment]\nsource = [70000, 1, 1]\nintensity = 2", "environment",
         "the radiance reaches 140000 W/(m^2 sr) with intensity, beyond the 65504"),
        # Where the source alone fits, intensity is what to change, and the line says how far.
        ("[environment]\nsource = [40000, 1, 1]\nintensity = 2", "environment.intensity",
         "intensity 2 takes the radiance (40000) to 80000 W/(m^2 sr), beyond the 65504 the renderer's half-float "
         "environment texture holds; expected an intensity of at most 1.6376"),
        ('[environment]\nsource = "sky"\nsun_irradiance = 3e38', "environment.sun_irradiance",
         "the sky's sun disc (sun_irradiance over the disc's solid angle) reaches"),
        # Found by a hostile sweep: a sky's own colour over the limit, with no sun, was blamed on the sun's disc.
        ('[environment]\nsource = "sky"\nsun_irradiance = 0\nground = [1e5, 1, 1]', "environment.ground",
         "the sky's ground colour reaches 100000"),
        ('[environment]\nsource = "sky"\nzenith = [4e4, 1, 1]\nintensity = 2', "environment.intensity",
         "intensity 2 takes the sky's zenith colour (40000) to 80000"),
        # Found by a hostile sweep: a bright sky of default colours named a horizon (and the sun's peak, 6.8e8) and a
        # sun_irradiance the scene never set.
        ('[environment]\nsource = "sky"\nintensity = 1e6', "environment.intensity",
         "intensity 1e+06 takes the sky's horizon colour (1) to 1e+06 W/(m^2 sr)"),
        ('[environment]\nsource = "sky"\nintensity = 1e38', "environment.intensity",
         "intensity 1e+38 takes the sky's horizon colour (1) to 1e+38 W/(m^2 sr)"),
        ('[environment]\nsource = "sky"\nintensity = 5000', "environment.intensity",
         "intensity 5000 takes the sky's sun disc (sun_irradiance over the disc's solid angle) (40.0882) to 200441"),
    ],
)  # fmt: skip
@pytest.mark.filterwarnings("error::RuntimeWarning")  # the overflow is expected, and refused, not warned about
def test_an_environment_beyond_half_float_is_refused_when_it_is_built(text, field, words):
    """The renderer uploads the environment as rgba16float: beyond 65504 it would hold infinity, and its
    prefiltered levels NaN, which rendered the whole image black (the refusal names the scene and the field)."""
    from atlasgen.materials.environment import environment_image

    env = _scene(text).environment
    with pytest.raises(SceneError) as info:
        environment_image(env, 32, 64)
    assert str(info.value).startswith(f"scenes/x.toml: field '{field}': {words}"), str(info.value)


@pytest.mark.parametrize("intensity", ["70000", "1e6", "5000"])
@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_the_intensity_a_refusal_suggests_is_built(intensity):
    """A hostile sweep: a sky at intensity 70000 was told to use at most 65504 (its horizon's limit), which was then
    refused for the sun disc's peak. The suggested intensity builds, and a little more does not."""
    import re

    from atlasgen.materials.environment import environment_image

    with pytest.raises(SceneError) as info:
        environment_image(_scene(f'[environment]\nsource = "sky"\nintensity = {intensity}').environment, 32, 64)
    suggested = float(re.search(r"expected an intensity of at most ([0-9.e+]+)", str(info.value)).group(1))
    assert environment_image(_scene(f'[environment]\nsource = "sky"\nintensity = {suggested * 0.9999}').environment,
                             32, 64).max() <= 65504.0  # fmt: skip
    with pytest.raises(SceneError):
        environment_image(_scene(f'[environment]\nsource = "sky"\nintensity = {suggested * 1.001}').environment, 32, 64)


def test_an_environment_at_half_float_s_largest_value_is_built():
    from atlasgen.materials.environment import environment_image

    assert environment_image(_scene("environment = [65504, 1, 1]").environment, 8, 16).max() == 65504.0
    assert environment_image(_scene('environment = "sky"').environment, 32, 64).max() <= 65504.0


@pytest.mark.parametrize(
    ("scale", "words"),
    [("-1.0", "expected positive scale factors (a negative one mirrors the shape inside out), got -1.0"),
     ("[-1.0, 1.0, 1.0]", "positive scale factors"),
     ("1e-300", "expected non-zero scale factors, in float32 too, got 1e-300")],
)  # fmt: skip
def test_a_mirroring_or_vanishing_scale_is_refused(scale, words):
    """A negative factor turned a closed shape inside out (its front faces culled: a dark sphere); one that is 0 in
    float32 flattened it to nothing."""
    with pytest.raises(SceneError) as info:
        parse_scene(tomllib.loads(f'{CAMERA}[[objects]]\nshape = "sphere"\nmaterial = "m"\nscale = {scale}\n'), "scenes/x.toml")
    assert str(info.value).startswith(f"scenes/x.toml: field 'objects[0].scale': expected {words.removeprefix('expected ')}")


@pytest.mark.parametrize(("scale", "got"), [("1e40", "got 1e+40 (beyond float32's range)"), ("nan", "got nan (not finite)")])
def test_a_single_scale_factor_is_echoed_as_given(scale, got):
    """One factor for all three axes was checked as the list of three it stands for, and the line echoed a list the
    file does not hold ([1e+40, 1e+40, 1e+40])."""
    with pytest.raises(SceneError) as info:
        parse_scene(tomllib.loads(f'{CAMERA}[[objects]]\nshape = "sphere"\nmaterial = "m"\nscale = {scale}\n'), "scenes/x.toml")
    assert str(info.value) == f"scenes/x.toml: field 'objects[0].scale': expected a finite number, {got}"
    ok = parse_scene(tomllib.loads(f'{CAMERA}[[objects]]\nshape = "sphere"\nmaterial = "m"\nscale = 2\n'), "x.toml")
    assert ok.objects[0].scale == (2.0, 2.0, 2.0)


@pytest.mark.parametrize(
    ("shape", "key", "users"),
    [("box", "segments", "'sphere' or 'torus'"), ("plane", "segments", "'sphere' or 'torus'"),
     ("sphere", "minor_radius", "'torus'"), ("box", "minor_radius", "'torus'")],
)  # fmt: skip
def test_tessellation_a_shape_does_not_have_is_refused(shape, key, users):
    """segments on a box, or minor_radius on a sphere, was read and ignored: a slip (set on the wrong object),
    refused as 'file' on a sphere always was."""
    _rejects(f'[[objects]]\nshape = "{shape}"\nmaterial = "clay"\n{key} = 8', f"objects[0].{key}",
             f"only used with shape = {users}, not '{shape}'")  # fmt: skip
    assert _scene('[[objects]]\nshape = "torus"\nmaterial = "clay"\nsegments = 8\nminor_radius = 0.3').objects[0].segments == 8


def test_a_named_pipe_as_mesh_or_environment_is_named(tmp_path):
    """A named pipe is neither missing nor readable (it would wait for a writer): the line says what it is."""
    import os

    for name in ("m.obj", "sky.exr"):
        os.mkfifo(tmp_path / name)
    _rejects('environment = "sky.exr"', "environment", f"expected an .exr or .hdr file, got a named pipe ('{(tmp_path / 'sky.exr').as_posix()}')",
             base=tmp_path)  # fmt: skip
    _rejects('[[objects]]\nshape = "mesh"\nfile = "m.obj"\nmaterial = "clay"', "objects[0].file",
             f"expected an OBJ or PLY file, got a named pipe ('{(tmp_path / 'm.obj').as_posix()}')", base=tmp_path)  # fmt: skip
    (tmp_path / "folder.obj").mkdir()
    _rejects('[[objects]]\nshape = "mesh"\nfile = "folder.obj"\nmaterial = "clay"', "objects[0].file",
             f"expected an OBJ or PLY file, got a directory ('{(tmp_path / 'folder.obj').as_posix()}')", base=tmp_path)  # fmt: skip


def test_a_gloss_the_material_does_not_use_is_named():
    """A fitted slice is shaded with its fit.gloss and a separable material from its terms: the scene's gloss on
    them changed nothing, without a word. Only a gloss the scene sets is named."""
    from types import SimpleNamespace

    from atlasgen.materials.scene import ignored_gloss, parse_scene

    objects = "".join(f"[[objects]]\nshape = 'sphere'\nmaterial = '{m}'\n{g}\n" for m, g in
                      [("fitted", "gloss = 0.2"), ("terms", "gloss = 0.3"), ("table", "gloss = 0.4"), ("fitted", "")])  # fmt: skip
    scene = parse_scene(tomllib.loads("[camera]\nposition = [0, 0, 5]\ntarget = [0, 0, 0]\n" + objects), "s.toml")
    entries = {"fitted": SimpleNamespace(type="fresnel", fit=SimpleNamespace(gloss=0.55)),
               "terms": SimpleNamespace(type="separable", fit=None), "table": SimpleNamespace(type="fresnel", fit=None)}  # fmt: skip
    assert ignored_gloss(scene, [entries[o.material] for o in scene.objects]) == [
        "s.toml: objects[0].gloss = 0.2 has no effect on 'fitted': its slice is shaded with the gloss it was fitted "
        "for, 0.55 (fit.gloss)",
        "s.toml: objects[1].gloss = 0.3 has no effect on 'terms': a separable material is shaded from its own terms, "
        "with no lobe a gloss sets",
    ]


def test_a_scene_file_over_its_limit_is_refused_unread(tmp_path):
    """A 3 GB file was read whole: a MemoryError (exit 1) on a smaller machine, or the machine's memory."""
    from atlasgen.materials.scene import MAX_SCENE_BYTES

    path = tmp_path / "huge.toml"
    with open(path, "wb") as f:
        f.truncate(MAX_SCENE_BYTES + 1)  # sparse: no disk used
    with pytest.raises(SceneError, match=rf"huge.toml: expected UTF-8 TOML text, at most {MAX_SCENE_BYTES} bytes, got"):
        read_scene(path)
