"""A scene's environment: the parsed ``environment`` key, its radiance as an image, and Mitsuba's equivalent.

docs/scenes.md ("Environment") documents the key; :func:`atlasgen.materials.scene.parse_scene`
reads it into an :class:`Environment`. The environment lights every surface from every direction,
unshadowed and unoccluded, as the scene's lights are.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from atlasgen.errors import FieldError, SceneError
from atlasgen.io.environment_file import read_environment_file
from atlasgen.optics.equirect import resample_equirect, rotation_matrix
from atlasgen.optics.sky import SkyParameters, sky_image

__all__ = ["ENVIRONMENT_SOURCES", "Environment", "environment_image", "sky_parameters", "mitsuba_emitter"]

#: What an environment's radiance comes from.
ENVIRONMENT_SOURCES = ("uniform", "file", "sky")


@dataclass(frozen=True)
class Environment:
    """A scene's environment.

    ``source`` is ``uniform`` (``radiance`` [r, g, b], W/(m^2 sr), from every direction), ``file``
    (``file``, an equirectangular OpenEXR or Radiance HDR image) or ``sky`` (the procedural sky of
    ``sky``, :class:`atlasgen.optics.sky.SkyParameters`). Its radiance is the source's times
    ``intensity``, turned by ``rotate`` degrees about +y (:func:`atlasgen.optics.equirect.rotate`).
    """

    source: str
    radiance: tuple = (0.0, 0.0, 0.0)
    file: Path | None = None
    intensity: float = 1.0
    rotate: float = 0.0
    sky: SkyParameters | None = None
    #: The scene file that gave it, for the one-line refusals (not part of what it is: no cache key holds it).
    scene: str = field(default="<scene>", compare=False, repr=False)


#: The most radiance the renderer's environment texture holds: rgba16float's largest finite value.
HALF_MAX = 65504.0


def sky_parameters(env: Environment) -> SkyParameters:
    """The sky's parameters in the world: the sun direction turned by ``rotate`` (the gradient is symmetric about +y)."""
    if env.source != "sky" or env.sky is None:
        raise ValueError(f"not a sky environment: {env.source!r}")
    sun = rotation_matrix(env.rotate) @ np.asarray(env.sky.sun_direction, dtype=np.float64)
    return replace(env.sky, sun_direction=tuple(float(c) for c in sun))


def environment_image(env: Environment, height: int, width: int) -> np.ndarray:
    """The environment's radiance as an equirectangular float32 image ``(height, width, 3)`` (Mitsuba's layout).

    ``uniform``: the constant radiance x intensity. ``file``: the image read
    (:func:`atlasgen.io.environment_file.read_environment_file`, errors naming the scene, its ``environment``
    and that file as a :class:`~atlasgen.errors.SceneError`), turned and resampled in one step
    (:func:`atlasgen.optics.equirect.resample_equirect`: point-sampled up, averaged down), times
    intensity. ``sky``: built at this size with its sun turned (:func:`sky_parameters`), times
    intensity.
    """
    if env.source == "uniform":
        image = np.broadcast_to(np.asarray(env.radiance, dtype=np.float64) * env.intensity, (height, width, 3))
    elif env.source == "file":
        if env.file is None:
            raise ValueError("a file environment needs its file")
        try:
            pixels = read_environment_file(env.file)
        except FieldError as exc:
            # The image alone was named ("one.exr: expected an equirectangular image ..."): the scene and its field too,
            # as a too-bright image is.
            raise SceneError(env.scene, "environment", f"{exc.path}: {exc.expected}") from None
        same = pixels.shape[:2] == (height, width) and env.rotate == 0.0
        image = pixels.astype(np.float64) if same else resample_equirect(pixels, height, width, env.rotate).astype(np.float64)
        image = image * env.intensity
    elif env.source == "sky":
        image = sky_image(height, width, sky_parameters(env), scale=env.intensity).astype(np.float64)
    else:
        raise ValueError(f"unknown environment source {env.source!r}; expected one of {ENVIRONMENT_SOURCES}")
    peak = float(np.max(image))
    if peak > HALF_MAX:
        _refuse_beyond_half(env, _peak_at_unit_intensity(env, image, height, width))
    return image.astype(np.float32)


def _peak_at_unit_intensity(env: Environment, image: np.ndarray, height: int, width: int) -> float:
    """The image's peak with intensity 1: what the source reaches before intensity scales it."""
    if env.source == "sky":
        return float(np.max(sky_image(height, width, sky_parameters(env), scale=1.0)))
    if env.source == "uniform":
        return float(max(env.radiance))
    return float(np.max(image)) / env.intensity if env.intensity > 0.0 else 0.0


def _refuse_beyond_half(env: Environment, alone: float) -> None:
    """One line for an image whose radiance (``alone`` at intensity 1, times it) exceeds :data:`HALF_MAX`: the
    renderer's rgba16float texture would hold infinity there, and its prefiltered levels and harmonics NaN, which
    render black. It names the field to change: ``intensity`` where the source alone fits (a sky's default horizon
    at intensity 1e6 was blamed on a ``horizon`` the scene never set, with the sun's peak as its value), else the
    source's own field, with the value that field reaches."""
    k = env.intensity
    field, what, value = "environment", {"uniform": "the radiance", "file": f"the image {env.file.as_posix() if env.file else ''}",
                                         "sky": "the sky's sun disc (sun_irradiance over the disc's solid angle)"}[env.source], alone  # fmt: skip
    if env.source == "sky" and env.sky is not None:
        # The gradient's colours reach the peak themselves, the sun adding to them: name the brightest where it is
        # over (a ground of 1e5 with no sun was blamed on the sun's disc), else the disc.
        colours = {name: float(max(getattr(env.sky, name))) for name in ("zenith", "horizon", "ground")}
        brightest = max(colours, key=colours.get)
        if colours[brightest] * k > HALF_MAX:
            field, what, value = f"environment.{brightest}", f"the sky's {brightest} colour", colours[brightest]
        else:
            field = "environment.sun_irradiance"
    if value <= HALF_MAX and k != 1.0:
        raise SceneError(env.scene, "environment.intensity", f"intensity {k:.6g} takes {what} ({value:.6g}) to "
                         f"{value * k:.6g} W/(m^2 sr), beyond the {HALF_MAX:g} the renderer's half-float environment "
                         f"texture holds; expected an intensity of at most {HALF_MAX / max(alone, value):.6g}"
                         f"{'' if alone <= value else f' (the whole image peaks at {alone:.6g} with intensity 1)'}")  # fmt: skip
    raise SceneError(env.scene, field, f"{what} reaches {value * k:.6g} W/(m^2 sr)"
                     f"{' with intensity' if k != 1.0 else ''}, beyond the {HALF_MAX:g} the renderer's half-float "
                     f"environment texture holds; expected at most {HALF_MAX:g}"
                     f"{' (lower intensity)' if k != 1.0 else ''}")  # fmt: skip


def mitsuba_emitter(env: Environment, sky_height: int = 512) -> dict:
    """The Mitsuba 3 emitter that is this environment (docs/scenes.md, "Environment"), for ``mi.load_dict``.

    ``uniform``: ``constant`` with ``radiance`` = radiance x intensity. ``file``: ``envmap`` with
    the file's absolute ``filename``, ``scale`` = intensity and ``to_world`` =
    ``rotate([0, 1, 0], rotate)``. ``sky``: ``envmap`` of the :func:`environment_image` at
    ``sky_height`` x 2 ``sky_height`` as a bitmap (intensity and the sun's turn already in it).
    """
    import mitsuba as mi

    if env.source == "uniform":
        value = [float(c) * env.intensity for c in env.radiance]
        return {"type": "constant", "radiance": {"type": "rgb", "value": value}}
    if env.source == "file":
        return {
            "type": "envmap",
            "filename": str(Path(env.file).resolve()),
            "scale": float(env.intensity),
            "to_world": mi.ScalarTransform4f().rotate([0.0, 1.0, 0.0], float(env.rotate)),
        }
    return {"type": "envmap", "bitmap": mi.Bitmap(environment_image(env, sky_height, 2 * sky_height))}
