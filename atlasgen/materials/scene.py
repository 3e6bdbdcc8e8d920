"""The TOML scene format: camera, image, lights, objects and environment (documented in docs/scenes.md).

Every bad value raises :class:`atlasgen.errors.SceneError` naming the file, the field
(``objects[2].material``) and what was expected, on one line. Material names are
checked against the atlas later, by :func:`resolve_materials`, since a scene does not
know which atlas it will be rendered with.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from atlasgen.errors import SceneError, did_you_mean
from atlasgen.io.environment_file import ENVIRONMENT_SUFFIXES
from atlasgen.io.fields import FLOAT32_MAX, FLOAT32_MIN_NORMAL, Param, check_keys, is_number, shown
from atlasgen.io.manifest import Manifest, MaterialEntry
from atlasgen.io.text import MISSING, parse_toml, path_kind, read_input_text
from atlasgen.materials.environment import Environment
from atlasgen.models import get_model
from atlasgen.optics.sky import SkyParameters

__all__ = [
    "Camera",
    "MAX_LIGHTS",
    "SHAPES",
    "Light",
    "SceneObject",
    "RenderSettings",
    "Environment",
    "SKY_KEYS",
    "Scene",
    "read_scene",
    "parse_scene",
    "resolve_materials",
    "object_matrix",
    "with_fitted_surfaces",
    "ignored_gloss",
    "shading_gloss",
]

#: Lights one frame can take; they live in one texture (a row each) read by one lighting pass.
MAX_LIGHTS = 1024
#: The largest scene file read: one of MAX_LIGHTS lights and as many objects is under 1 MB, and a larger file (a
#: device, a runaway generator's) is refused before it is read whole.
MAX_SCENE_BYTES = 16 << 20
SHAPES = ("sphere", "plane", "box", "torus", "mesh")
#: The ``[environment]`` keys that only the built-in sky uses (:class:`atlasgen.optics.sky.SkyParameters`).
SKY_KEYS = ("sun_direction", "sun_irradiance", "sun_colour", "sun_radius", "zenith", "horizon", "ground")


#: Narrowest field of view, degrees: at 1e-10 a pixel spans less than float32 can place a vertex by, and
#: the image loses most of what it shows; 1e-6 still draws it whole.
MIN_FOV_DEGREES = 1e-4
#: Widest far / near ratio: the perspective depth of a point is about 1 - near / distance, whose steps a 24-bit
#: depth buffer (2^-24 apart) resolves ever more coarsely as near / far shrinks: at 1e-7 / 1000 the floor vanished;
#: at 1e7 two spheres crossing 10 away showed the wrong one in 66 of 316 pixels, and objects beyond far were drawn;
#: at 1e6 17 pixels, at 1e5 one (where their surfaces meet), at 1e4 none.
MAX_FAR_OVER_NEAR = 1e5


@dataclass(frozen=True)
class Camera:
    """A look-at pinhole camera; ``fov`` is the horizontal field of view in degrees, ``up`` a
    unit vector (scenes are read with it normalised)."""

    position: tuple
    target: tuple
    up: tuple = (0.0, 1.0, 0.0)
    fov: float = 40.0
    near: float = 0.05
    far: float = 1000.0


@dataclass(frozen=True)
class Light:
    """A point, spot or directional light.

    ``point``: ``intensity`` is radiant intensity I (W/sr, Mitsuba ``point.intensity``);
    irradiance at distance d is I W(d, range) / d^2, with the window W of
    :func:`atlasgen.optics.falloff.range_window` (1 everywhere without a range).
    ``spot``: a point light whose intensity is scaled off its axis ``direction`` by
    :func:`atlasgen.optics.falloff.spot_factor` of ``inner_angle`` and ``outer_angle`` (degrees,
    Mitsuba ``spot``). ``directional``: ``intensity`` is the irradiance E normal to ``direction``
    (Mitsuba ``directional.irradiance``), and ``direction`` is the direction the light travels;
    it has no range.
    """

    type: str
    colour: tuple
    intensity: float
    position: tuple | None = None
    direction: tuple | None = None
    range: float = math.inf
    inner_angle: float = 0.0
    outer_angle: float = 0.0

    @property
    def bounded(self) -> bool:
        """Whether the light reaches only points within ``range`` of its position (so it can be culled)."""
        return math.isfinite(self.range)


@dataclass(frozen=True)
class SceneObject:
    """One object: a shape, its transform and its surface."""

    index: int
    shape: str
    material: str
    albedo: tuple = (1.0, 1.0, 1.0)
    gloss: float = 0.5
    opacity: float = 1.0
    translate: tuple = (0.0, 0.0, 0.0)
    rotate: tuple = (0.0, 0.0, 0.0)  # degrees about x, then y, then z
    scale: tuple = (1.0, 1.0, 1.0)
    file: Path | None = None
    segments: int = 64
    minor_radius: float = 0.25
    gloss_given: bool = False  # the scene sets gloss (ignored_gloss warns where the material does not use it)

    @property
    def translucent(self) -> bool:
        return self.opacity < 1.0


@dataclass(frozen=True)
class RenderSettings:
    """Pipeline knobs: mip selection, outlines and the PNG's exposure."""

    mip_bias: float = 0.0
    mip_distance: float = 10.0
    outline_colour: tuple = (0.0, 0.0, 0.0)
    outline_depth: float = 0.05
    outline_normal_degrees: float = 35.0
    exposure: float = 1.0


@dataclass
class Scene:
    """A parsed scene; ``path`` is what error messages name. ``environment`` is ``None`` without one."""

    path: str
    camera: Camera
    width: int
    height: int
    background: tuple
    lights: list = field(default_factory=list)
    objects: list = field(default_factory=list)
    settings: RenderSettings = field(default_factory=RenderSettings)
    environment: Environment | None = None
    #: Whether ``[image].background`` was given: without it, a scene with an environment shows the environment there.
    background_given: bool = False

    def warnings(self) -> list[str]:
        """What a valid scene renders that its author likely did not mean, one line each.

        A scene with neither lights nor an environment is valid (its g-buffer layers, ``--aov``,
        are whole), but its lit image is the background and black objects.
        """
        if not self.lights and self.environment is None:
            return [f"{self.path}: no [[lights]] and no [environment]: every object renders black"]
        return []


class _Reader:
    """Scene fields through the one field validator (:class:`atlasgen.io.fields.Param`), with
    :class:`~atlasgen.errors.SceneError` naming the scene file and the field."""

    def __init__(self, path: str):
        self.path = path

    def fail(self, name, expected, value):
        # TOML has no null: None is a key the table lacks ("got None" read as a value of None).
        if value is None:
            raise SceneError(self.path, name, f"missing; expected {expected}")
        raise SceneError(self.path, name, f"expected {expected}, got {shown(value)}")

    def table(self, raw, name, allowed):
        if not isinstance(raw, dict):
            self.fail(name, "a table", raw)
        check_keys(raw, allowed, self.path, name, SceneError)
        return raw

    def _field(self, raw, key, name, default, param: Param, what: str):
        value = raw.get(key, default)
        if value is None:
            raise SceneError(self.path, name, f"missing; expected {what}")
        return param.coerce(value, self.path, SceneError, name)

    def number(self, raw, key, name, default=None, lo=-math.inf, hi=math.inf, lo_open=False):
        # Every number reaches the GPU as float32: the validator checks it is finite there too.
        param = Param(name, default, "float", _bound(lo), _bound(hi), lo_open)
        return self._field(raw, key, name, default, param, "a number")

    def integer(self, raw, key, name, default, lo, hi):
        return self._field(raw, key, name, default, Param(name, default, "int", lo, hi), "an integer")

    def vec3(self, raw, key, name, default=None, lo=-math.inf, hi=math.inf, nonzero=False):
        value = raw.get(key, default)
        if is_number(value) and key == "scale":
            # One factor for all three axes, checked and echoed as the number given, not as a list of three.
            factor = self.number(raw, key, name, lo=lo, hi=hi)
            return (factor, factor, factor)
        param = Param(name, default, "vec3", _bound(lo), _bound(hi), nonzero=nonzero)
        return self._field({key: value}, key, name, None, param, "[x, y, z]")


def _bound(x: float) -> float | None:
    return None if math.isinf(x) else x


def _direction(vector) -> np.ndarray:
    """``vector`` (not all zero) at unit length, scaled first so that tiny or huge components
    (1e-232, 3e38) neither underflow nor overflow in the norm."""
    v = np.asarray(vector, dtype=np.float64)
    v = v / np.abs(v).max()
    return v / np.linalg.norm(v)


def _read_camera(r: _Reader, raw) -> Camera:
    r.table(raw, "camera", ("position", "target", "up", "fov", "near", "far"))
    position = r.vec3(raw, "position", "camera.position")
    target = r.vec3(raw, "target", "camera.target")
    up = r.vec3(raw, "up", "camera.up", default=(0.0, 1.0, 0.0), nonzero=True)
    # Compared in float32, the renderer's precision, and with no absolute tolerance: a camera 5e-9 from its
    # target is a small scene's camera, not the same point.
    if np.array_equal(np.float32(position), np.float32(target)):
        raise SceneError(r.path, "camera.target", "expected a point different from camera.position")
    forward = np.subtract(target, position)
    if np.abs(forward).max() > FLOAT32_MAX:
        raise SceneError(r.path, "camera.target", "expected a point whose offset from camera.position float32 can hold")
    # Compared as unit vectors, to float32's precision: the renderer and Mitsuba build
    # their frames from these in float32.
    up = tuple(float(c) for c in _direction(up))
    if np.linalg.norm(np.cross(_direction(forward), up)) < 1e-6:
        raise SceneError(r.path, "camera.up", "expected a direction not parallel to target - position")
    fov = r.number(raw, "fov", "camera.fov", default=40.0, lo=MIN_FOV_DEGREES, hi=179.0)
    # Not subnormal in float32: the GPU flushes such a near plane to 0 and the scene came out empty, exit 0.
    near = r.number(raw, "near", "camera.near", default=0.05, lo=FLOAT32_MIN_NORMAL)
    far = r.number(raw, "far", "camera.far", default=1000.0, lo=near, lo_open=True)
    # Relative to a part in 1e9: near = far / MAX_FAR_OVER_NEAR written in decimal (3e-4 for far 30) is at the limit,
    # not refused for the rounding of its binary form.
    if far > MAX_FAR_OVER_NEAR * near * (1.0 + 1e-9):
        raise SceneError(r.path, "camera.near", f"expected at least camera.far / {MAX_FAR_OVER_NEAR:g} = "
                         f"{far / MAX_FAR_OVER_NEAR:.3g} (the depth buffer cannot tell depths apart across a wider "
                         f"range: the objects would vanish), got {near:g}")  # fmt: skip
    return Camera(position, target, up, fov, near, far)


#: The keys only a spot light uses.
_SPOT_KEYS = ("inner_angle", "outer_angle")


def _read_light(r: _Reader, raw, i) -> Light:
    name = f"lights[{i}]"
    r.table(raw, name, ("type", "colour", "intensity", "position", "direction", "range", *_SPOT_KEYS))
    kind = raw.get("type")
    if kind not in ("point", "spot", "directional"):
        r.fail(f"{name}.type", "'point', 'spot' or 'directional'", kind)
    colour = r.vec3(raw, "colour", f"{name}.colour", default=(1.0, 1.0, 1.0), lo=0.0)
    intensity = r.number(raw, "intensity", f"{name}.intensity", lo=0.0)
    # The renderer takes colour x intensity as one float32: beyond it the product is infinite, and the
    # GPU's inf x 0 (a pixel the light does not face) is NaN, written as black over the other lights too.
    if max(colour) * intensity > FLOAT32_MAX:
        raise SceneError(r.path, f"{name}.intensity", f"expected colour x intensity within float32 (at most "
                                                      f"{FLOAT32_MAX:.8g}), got {max(colour)!r} x {intensity!r}")  # fmt: skip
    if kind != "spot":
        for key in _SPOT_KEYS:
            if key in raw:
                raise SceneError(r.path, f"{name}.{key}", f"only used by a spot light, not a {kind} light")
    if kind in ("point", "spot"):
        # No range: the light reaches everywhere (infinite range), as before ranges existed.
        # At least float32's least normal number: a GPU flushes a smaller one to 0, which the renderer reads as no range.
        light_range = r.number(raw, "range", f"{name}.range", lo=FLOAT32_MIN_NORMAL) if "range" in raw else math.inf
        position = r.vec3(raw, "position", f"{name}.position")
        if kind == "point":
            if "direction" in raw:
                raise SceneError(r.path, f"{name}.direction", "not used by a point light; expected 'position'")
            return Light("point", colour, intensity, position=position, range=light_range)
        axis = np.asarray(r.vec3(raw, "direction", f"{name}.direction", nonzero=True))
        outer = r.number(raw, "outer_angle", f"{name}.outer_angle", lo=0.0, hi=90.0, lo_open=True)
        # Mitsuba's spot default: the full-intensity cone is 3/4 of the cut-off angle.
        inner = r.number(raw, "inner_angle", f"{name}.inner_angle", default=0.75 * outer, lo=0.0)
        # The fall-off divides by outer - inner in float32 radians (the renderer's and Mitsuba's spot): 29.999999999999996
        # below 30 degrees is the same angle there, and packing the light divided by zero (an internal error).
        if not np.float32(math.radians(inner)) < np.float32(math.radians(outer)):
            if "inner_angle" not in raw:
                # The default inner angle was blamed on a key the scene never set (outer_angle = 1e-43).
                raise SceneError(r.path, f"{name}.outer_angle", f"expected an angle whose default inner_angle (3/4 of it, "
                                                                f"{inner!r} degrees) is below it in float32 radians, got "
                                                                f"{outer!r}; give a wider cone, or an inner_angle below it")  # fmt: skip
            same = ", the same angle in float32 radians" if inner < outer else ""
            raise SceneError(r.path, f"{name}.inner_angle", f"expected an angle below outer_angle ({outer!r} degrees), "
                                                            f"got {inner!r}{same}")  # fmt: skip
        direction = tuple(float(c) for c in _direction(axis))
        return Light("spot", colour, intensity, position, direction, light_range, inner, outer)
    if "range" in raw:
        raise SceneError(r.path, f"{name}.range", "not used by a directional light, which reaches everywhere")
    if "position" in raw:
        raise SceneError(r.path, f"{name}.position", "not used by a directional light; expected 'direction'")
    direction = np.asarray(r.vec3(raw, "direction", f"{name}.direction", nonzero=True))
    return Light("directional", colour, intensity, direction=tuple(float(c) for c in _direction(direction)))


def _read_object(r: _Reader, raw, i, base: Path) -> SceneObject:
    name = f"objects[{i}]"
    keys = ("shape", "file", "material", "albedo", "gloss", "opacity", "translate", "rotate", "scale",
            "segments", "minor_radius")  # fmt: skip
    r.table(raw, name, keys)
    shape = raw.get("shape")
    if shape not in SHAPES:
        r.fail(f"{name}.shape", "one of " + ", ".join(SHAPES), shape)
    material = raw.get("material")
    if not isinstance(material, str) or not material:
        r.fail(f"{name}.material", "a material name from the atlas manifest", material)
    file = None
    if shape == "mesh":
        text = raw.get("file")
        if not isinstance(text, str) or not text:
            r.fail(f"{name}.file", "a path to an OBJ or PLY mesh", text)
        file = Path(text) if Path(text).is_absolute() else base / text
        kind = path_kind(file)
        if kind == MISSING:
            raise SceneError(r.path, f"{name}.file", f"no such mesh file {file.as_posix()!r}; expected an OBJ or PLY file")
        if kind is not None:
            raise SceneError(r.path, f"{name}.file", f"expected an OBJ or PLY file, got {kind} ({file.as_posix()!r})")
        if file.suffix.lower() not in (".obj", ".ply"):
            raise SceneError(r.path, f"{name}.file", f"expected an .obj or .ply file, got {file.name!r}")
    elif "file" in raw:
        raise SceneError(r.path, f"{name}.file", f"only used with shape = 'mesh', not {shape!r}")
    # Tessellation the shape does not have is a slip (a sphere's segments set on the box below it), not a no-op.
    for key, users in (("segments", ("sphere", "torus")), ("minor_radius", ("torus",))):
        if key in raw and shape not in users:
            shown = " or ".join(repr(u) for u in users)
            raise SceneError(r.path, f"{name}.{key}", f"only used with shape = {shown}, not {shape!r}")
    scale = r.vec3(raw, "scale", f"{name}.scale", default=(1.0, 1.0, 1.0))
    # A mirroring scale turns a closed shape's faces inside out (their back faces are culled) and its
    # normals with them; 0 in float32 (1e-300, say) flattens it to nothing, as 0 would.
    if any(s < 0 for s in scale):
        r.fail(f"{name}.scale", "positive scale factors (a negative one mirrors the shape inside out)", raw.get("scale"))
    if any(np.float32(s) == 0 for s in scale):
        r.fail(f"{name}.scale", "non-zero scale factors, in float32 too", raw.get("scale"))
    return SceneObject(
        index=i,
        shape=shape,
        material=material,
        albedo=r.vec3(raw, "albedo", f"{name}.albedo", default=(1.0, 1.0, 1.0), lo=0.0, hi=1.0),
        gloss=r.number(raw, "gloss", f"{name}.gloss", default=0.5, lo=0.0, hi=1.0),
        opacity=r.number(raw, "opacity", f"{name}.opacity", default=1.0, lo=0.0, hi=1.0),
        translate=r.vec3(raw, "translate", f"{name}.translate", default=(0.0, 0.0, 0.0)),
        rotate=r.vec3(raw, "rotate", f"{name}.rotate", default=(0.0, 0.0, 0.0)),
        scale=scale,
        file=file,
        segments=r.integer(raw, "segments", f"{name}.segments", 64, 3, 1024),
        minor_radius=r.number(raw, "minor_radius", f"{name}.minor_radius", default=0.25, lo=0.0, hi=1.0, lo_open=True),
        gloss_given="gloss" in raw,
    )


_ENVIRONMENT_EXPECTED = 'a radiance [r, g, b] in W/(m^2 sr), an image file (.exr, .hdr) or "sky"'


def _environment_source(r: _Reader, raw, name: str, base: Path):
    """(source, radiance, file) of an environment's ``source``: a list, ``"sky"`` or a file name."""
    if isinstance(raw, list):
        return "uniform", r.vec3({"source": raw}, "source", name, lo=0.0), None
    if raw == "sky":
        return "sky", (0.0, 0.0, 0.0), None
    if not isinstance(raw, str) or not raw:
        r.fail(name, _ENVIRONMENT_EXPECTED, raw)
    file = Path(raw) if Path(raw).is_absolute() else base / raw
    if file.suffix.lower() not in ENVIRONMENT_SUFFIXES:
        raise SceneError(r.path, name, f'expected an OpenEXR (.exr) or Radiance HDR (.hdr) image, or "sky", got {raw!r}')
    kind = path_kind(file)
    if kind == MISSING:
        raise SceneError(r.path, name, f"no such environment image {file.as_posix()!r}; expected an .exr or .hdr file")
    if kind is not None:
        raise SceneError(r.path, name, f"expected an .exr or .hdr file, got {kind} ({file.as_posix()!r})")
    return "file", (0.0, 0.0, 0.0), file


def _read_environment(r: _Reader, raw, base: Path) -> Environment:
    """The ``environment`` key: a source alone, or an ``[environment]`` table with ``source`` and its settings."""
    if not isinstance(raw, dict):
        source, radiance, file = _environment_source(r, raw, "environment", base)
        return Environment(source, radiance, file, sky=SkyParameters() if source == "sky" else None, scene=r.path)
    r.table(raw, "environment", ("source", "intensity", "rotate", *SKY_KEYS))
    if "source" not in raw:
        raise SceneError(r.path, "environment.source", f"missing; expected {_ENVIRONMENT_EXPECTED}")
    source, radiance, file = _environment_source(r, raw["source"], "environment.source", base)
    intensity = r.number(raw, "intensity", "environment.intensity", default=1.0, lo=0.0)
    # Whole turns off, exactly, once for every reader (the image's resampling, the sky's sun, Mitsuba's emitter):
    # 1e20 degrees is a column index no integer holds, and float32's 1e20 another angle than float64's.
    rotate = math.fmod(r.number(raw, "rotate", "environment.rotate", default=0.0), 360.0)
    if source != "sky":
        for key in SKY_KEYS:
            if key in raw:
                raise SceneError(r.path, f"environment.{key}", f'only used with source = "sky", not {shown(raw["source"])}')
        return Environment(source, radiance, file, intensity, rotate, scene=r.path)
    d = SkyParameters()
    sun = r.vec3(raw, "sun_direction", "environment.sun_direction", default=d.sun_direction, nonzero=True)
    sky = SkyParameters(
        sun_direction=tuple(float(c) for c in _direction(sun)),
        sun_irradiance=r.number(raw, "sun_irradiance", "environment.sun_irradiance", default=d.sun_irradiance, lo=0.0),
        sun_colour=r.vec3(raw, "sun_colour", "environment.sun_colour", default=d.sun_colour, lo=0.0),
        sun_radius=r.number(raw, "sun_radius", "environment.sun_radius", default=d.sun_radius, lo=0.0, hi=90.0, lo_open=True),
        zenith=r.vec3(raw, "zenith", "environment.zenith", default=d.zenith, lo=0.0),
        horizon=r.vec3(raw, "horizon", "environment.horizon", default=d.horizon, lo=0.0),
        ground=r.vec3(raw, "ground", "environment.ground", default=d.ground, lo=0.0),
    )
    return Environment(source, radiance, file, intensity, rotate, sky, scene=r.path)


def parse_scene(data: dict, path="<scene>", base=None) -> Scene:
    """Validate a scene already parsed from TOML; ``base`` resolves relative mesh paths."""
    path = str(path)
    r = _Reader(path)
    r.table(data, "", ("camera", "image", "render", "lights", "objects", "environment"))
    if "camera" not in data:
        raise SceneError(path, "camera", "missing; expected a [camera] table")
    camera = _read_camera(r, data["camera"])
    image = r.table(data.get("image", {}), "image", ("width", "height", "background"))
    width = r.integer(image, "width", "image.width", 640, 1, 8192)
    height = r.integer(image, "height", "image.height", 360, 1, 8192)
    background = r.vec3(image, "background", "image.background", default=(0.0, 0.0, 0.0), lo=0.0)
    rs = r.table(data.get("render", {}), "render",
                 ("mip_bias", "mip_distance", "outline_colour", "outline_depth", "outline_normal_degrees", "exposure"))  # fmt: skip
    settings = RenderSettings(
        mip_bias=r.number(rs, "mip_bias", "render.mip_bias", default=0.0, lo=-16.0, hi=16.0),
        mip_distance=r.number(rs, "mip_distance", "render.mip_distance", default=10.0, lo=0.0, lo_open=True),
        outline_colour=r.vec3(rs, "outline_colour", "render.outline_colour", default=(0.0, 0.0, 0.0), lo=0.0),
        outline_depth=r.number(rs, "outline_depth", "render.outline_depth", default=0.05, lo=0.0, lo_open=True),
        outline_normal_degrees=r.number(
            rs, "outline_normal_degrees", "render.outline_normal_degrees", default=35.0, lo=0.0, hi=180.0, lo_open=True
        ),  # fmt: skip
        exposure=r.number(rs, "exposure", "render.exposure", default=1.0, lo=0.0, lo_open=True),
    )
    lights_raw = data.get("lights", [])
    if not isinstance(lights_raw, list):
        r.fail("lights", "an array of tables [[lights]]", lights_raw)
    if len(lights_raw) > MAX_LIGHTS:
        raise SceneError(path, "lights", f"{len(lights_raw)} lights; expected at most {MAX_LIGHTS} (the renderer's limit)")
    lights = [_read_light(r, raw, i) for i, raw in enumerate(lights_raw)]
    objects_raw = data.get("objects", [])
    if not isinstance(objects_raw, list):
        r.fail("objects", "an array of tables [[objects]]", objects_raw)
    base = Path(base) if base is not None else Path(".")
    objects = [_read_object(r, raw, i, base) for i, raw in enumerate(objects_raw)]
    environment = _read_environment(r, data["environment"], base) if "environment" in data else None
    return Scene(path, camera, width, height, background, lights, objects, settings, environment, "background" in image)


def read_scene(path) -> Scene:
    """Read and validate a TOML scene file.

    Raises
    ------
    InputError
        The file is missing or unreadable.
    SceneError
        Malformed TOML or a bad field; the message names the file and the field.
    """
    path = Path(path)
    shown = path.as_posix()
    text = read_input_text(path, "no such scene file", "UTF-8 TOML text", SceneError, MAX_SCENE_BYTES)
    return parse_scene(parse_toml(text, shown, SceneError), shown, path.parent)


def resolve_materials(scene: Scene, manifest: Manifest, atlas_name: str = "atlas") -> list[MaterialEntry]:
    """The manifest entry of each object's material, in object order.

    Raises :class:`SceneError` for an unknown name, listing the names the atlas knows.
    """
    by_name = {m.name: m for m in manifest.materials}
    out = []
    for obj in scene.objects:
        entry = by_name.get(obj.material)
        if entry is None:
            known, hint = ", ".join(sorted(by_name)) or "none", did_you_mean(obj.material, by_name)
            raise SceneError(
                scene.path, f"objects[{obj.index}].material",
                f"unknown material {obj.material!r}{hint}; expected one of the names in {atlas_name}: {known}",
            )  # fmt: skip
        out.append(entry)
    return out


def object_matrix(obj: SceneObject) -> np.ndarray:
    """Object to world: translate . rotate_z . rotate_y . rotate_x . scale (column vectors)."""
    rx, ry, rz = (math.radians(a) for a in obj.rotate)
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    rot_x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    rot_y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rot_z = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = rot_z @ rot_y @ rot_x @ np.diag(obj.scale)
    m[:3, 3] = obj.translate
    return m


def shading_gloss(gloss: float, entry) -> float:
    """The gloss an object showing ``entry`` (a :class:`~atlasgen.io.manifest.MaterialEntry`) is shaded
    with: a slice fitted to a physical BSDF holds it only under the lobe of the gloss it was fitted
    for (its ``fit.gloss``), whatever the scene says; any other slice, the object's own ``gloss``."""
    return float(gloss) if entry is None or entry.fit is None else float(entry.fit.gloss)


def ignored_gloss(scene: Scene, entries) -> list[str]:
    """One line per object whose scene sets a ``gloss`` its material does not use (``entries``: each object's
    :class:`~atlasgen.io.manifest.MaterialEntry`, in object order): a slice fitted to a physical BSDF is shaded
    with the gloss it was fitted for (:func:`shading_gloss`), and a model that shades its materials itself
    (``custom_lighting``: a separable BRDF rebuilt from its terms) has no lobe a gloss sets. The render was
    the same whatever gloss such an object had, without a word."""
    lines = []
    for obj, entry in zip(scene.objects, entries):
        if not obj.gloss_given:
            continue
        if entry.fit is not None:
            why = f"its slice is shaded with the gloss it was fitted for, {entry.fit.gloss:g} (fit.gloss)"
        elif get_model(entry.type).custom_lighting:
            why = f"a {entry.type} material is shaded from its own terms, with no lobe a gloss sets"
        else:
            continue
        lines.append(f"{scene.path}: objects[{obj.index}].gloss = {obj.gloss:g} has no effect on {obj.material!r}: {why}")
    return lines


def with_fitted_surfaces(scene: Scene, entries) -> Scene:
    """A copy of ``scene`` whose objects showing a fitted material (``entries``: name ->
    :class:`~atlasgen.io.manifest.MaterialEntry` with a ``fit``) have its gloss and albedo 1.

    A slice fitted to a physical BSDF (``from = "physical"``, the ``bsdf`` model) reproduces
    that BSDF only under the lobe of the gloss it was fitted for, and holds the BSDF's own
    colour, so an albedo would tint it away from the physical material. The renderer applies
    the gloss to every such object whatever the scene says; validation applies both.
    """
    objects = []
    for o in scene.objects:
        entry = entries.get(o.material)
        if entry is not None and entry.fit is not None:
            o = replace(o, gloss=shading_gloss(o.gloss, entry), albedo=(1.0, 1.0, 1.0))
        objects.append(o)
    return replace(scene, objects=objects)
