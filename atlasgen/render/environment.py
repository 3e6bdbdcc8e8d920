"""Environment lighting on the GPU: the scene's radiance, its harmonics and prefiltered levels, and each material's tables.

Per scene, once (:func:`prepare_environment`): the environment image (:data:`IMAGE_HEIGHT` x 2
:data:`IMAGE_HEIGHT`, :func:`atlasgen.materials.environment.environment_image`), its order-4 SH
coefficients (:func:`atlasgen.optics.spherical_harmonics.project_equirect`) and its GGX-prefiltered
levels (:func:`atlasgen.optics.prefilter.prefilter_ggx`), uploaded as **one rgba16float texture
whose mip chain is the prefiltered levels** (rgba16float is filterable in core WebGPU, rgba32float
needs the ``float32-filterable`` feature; its 11-bit mantissa holds radiance to 5e-4 relative, up
to 65504) and the coefficients as the ``Environment`` uniform (:data:`atlasgen.render.layout.ENVIRONMENT`).

Per material, at load time, from its slice as the GPU reads it (level-0 texels decoded with
their scale and bias, as :meth:`atlasgen.io.atlas.Atlas.decode_slice`): :func:`material_tables`,
one layer of an rgba32float texture array per atlas slice, :data:`TABLE_COLUMNS` texels per N.V row
(the shader reads them with ``textureLoad`` and interpolates along N.V itself: rgba32float is
not filterable):

- columns 0..4: lambda_l(N.V), l = 0..4 (:func:`atlasgen.optics.environment_tables.slice_sh_table`);
- columns 5..8: S(N.V, gloss i/15), four glosses a texel (:func:`~atlasgen.optics.environment_tables.slice_specular_table`);
- column 9: S_sep(N.V) for a separable material (``custom_lighting``), whose f cos is 4D and has no
  A.a: ``int f cos dl`` from its rebuilt factors
  (:func:`~atlasgen.optics.environment_tables.directional_albedo_table`), and nothing in 0..8.
"""

from __future__ import annotations

import hashlib
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from atlasgen.bake.cache import tool_fingerprint
from atlasgen.contract import HEIGHT, LAYERS
from atlasgen.io.atlas import apply_slice_scale
from atlasgen.io.atomic import write_file_atomically
from atlasgen.io.digest import update_with_array
from atlasgen.io.manifest import MaterialEntry
from atlasgen.io.npz import read_npz_arrays
from atlasgen.materials.environment import Environment, environment_image
from atlasgen.models.separable import representation_radiance
from atlasgen.optics.environment_tables import (
    GLOSS_COUNT,
    directional_albedo_table,
    slice_sh_table,
    slice_specular_table,
)
from atlasgen.optics.prefilter import PREFILTER_LEVELS, prefilter_ggx
from atlasgen.optics.quantize import dequantize_rgba
from atlasgen.optics.spherical_harmonics import SH_ORDER, project_equirect
from atlasgen.render.layout import ENVIRONMENT
from atlasgen.separable.rebuild import evaluate_factors, factors_from_slices

__all__ = [
    "IMAGE_HEIGHT",
    "TABLE_COLUMNS",
    "EnvironmentData",
    "prepare_environment",
    "cached_environment",
    "decode_render_slice",
    "material_tables",
    "pack_environment",
    "shows_environment",
    "upload_environment",
    "upload_tables",
]

#: Rows of the environment image the renderer builds (256x128; prefiltered down to 8x4).
IMAGE_HEIGHT = 128
#: Texels per N.V row of a material's tables (module docstring).
TABLE_COLUMNS = 10
_SH_COLUMN, _SPECULAR_COLUMN, _SEPARABLE_COLUMN = 0, SH_ORDER + 1, SH_ORDER + 1 + GLOSS_COUNT // 4


@dataclass
class EnvironmentData:
    """What a scene's environment uploads: its image, harmonics ``(25, 3)`` and prefiltered levels."""

    image: np.ndarray
    sh: np.ndarray
    levels: list

    @classmethod
    def of(cls, env: Environment, height: int = IMAGE_HEIGHT) -> EnvironmentData:
        image = environment_image(env, height, 2 * height)
        return cls(image, project_equirect(image), prefilter_ggx(image, PREFILTER_LEVELS))


prepare_environment = EnvironmentData.of


#: Bytes a cached environment's arrays may hold (an entry of the built-in sky holds about 3 MB).
_MAX_ENTRY_BYTES = 256 << 20


def _environment_digest(data: EnvironmentData) -> str:
    """SHA-256 of an environment's arrays, each with its shape and type (:func:`~atlasgen.io.digest.update_with_array`)."""
    digest = hashlib.sha256()
    for array in (data.image, data.sh, *data.levels):
        update_with_array(digest, np.asarray(array))
    return digest.hexdigest()


def _load_environment(path: Path) -> EnvironmentData:
    """The environment an entry holds, or ValueError (OSError, KeyError) for anything but an entry this module
    wrote: :func:`~atlasgen.io.npz.read_npz_arrays` reads it (a pipe, a truncated archive or a header declaring
    112 GiB ended in a hang or an internal error), and its arrays must be the ones stored (their digest): images
    of NaN, an image of one texel or a ``count`` of -3 loaded as the sky, or failed in the renderer."""
    arrays = read_npz_arrays(path, _MAX_ENTRY_BYTES)
    count = arrays["count"]
    if count.shape != () or count.dtype.kind not in "iu" or int(count) != PREFILTER_LEVELS:
        raise ValueError(f"a level count of {count!r}")
    data = EnvironmentData(arrays["image"], arrays["sh"], [arrays[f"level_{k}"] for k in range(int(count))])
    if str(arrays["digest"]) != _environment_digest(data):
        raise ValueError("arrays other than the ones stored")
    # The digest is the entry's own, so a forged entry passes it: what the renderer uploads is checked as well. Ten
    # levels failed the texture's creation, harmonics of another shape their packing (internal errors), and NaN
    # drew the ball black.
    expected = [(IMAGE_HEIGHT >> k, (2 * IMAGE_HEIGHT) >> k, 3) for k in range(PREFILTER_LEVELS)]
    shapes = [data.image.shape, data.sh.shape, *(level.shape for level in data.levels)]
    if shapes != [expected[0], ((SH_ORDER + 1) ** 2, 3), *expected]:
        raise ValueError(f"arrays of shapes {shapes}")
    for array in (data.image, data.sh, *data.levels):
        if array.dtype.kind != "f" or not np.all(np.isfinite(array)):
            raise ValueError("arrays that are not finite numbers")
    if any(np.any(array < 0) for array in (data.image, *data.levels)):
        raise ValueError("negative radiance")
    return data


def cached_environment(env: Environment, cache_dir=None) -> EnvironmentData:
    """:meth:`EnvironmentData.of` ``env``, kept in ``cache_dir`` (``environment-<key>.npz``) for a built-in one.

    Prefiltering the sky and projecting it costs ~0.8 s of CPU, every time the same for the same
    parameters: a process that starts often (``atlasgen preview``) loads it instead. The key hashes the
    environment's parameters, the bake-relevant code (:func:`atlasgen.bake.cache.tool_fingerprint`, which
    covers ``optics`` and ``materials``) and this module. A ``file`` environment, whose image can change
    under the same name, is always built; so is any with ``cache_dir`` None. An entry that does not load
    as it was stored (:func:`_load_environment`) is built again and replaced.
    """
    if cache_dir is None or env.source == "file":
        return EnvironmentData.of(env)
    digest = hashlib.sha256(f"{env!r}:{IMAGE_HEIGHT}:{tool_fingerprint()}".encode())
    digest.update(Path(__file__).read_bytes())
    path = Path(cache_dir) / f"environment-{digest.hexdigest()[:24]}.npz"
    try:
        return _load_environment(path)
    except (OSError, ValueError, KeyError):
        pass
    data = EnvironmentData.of(env)
    out = io.BytesIO()
    np.savez(out, image=data.image, sh=data.sh, count=len(data.levels), digest=_environment_digest(data),
             **{f"level_{k}": v for k, v in enumerate(data.levels)})  # fmt: skip
    write_file_atomically(path, out.getvalue())
    return data


def decode_render_slice(levels, srgb: bool, entry: MaterialEntry, slice_index: int) -> np.ndarray:
    """Linear RGBA ``(32, 64, 4)`` of atlas slice ``slice_index`` at level 0: what ``atlas_sample`` returns."""
    rgba = dequantize_rgba(np.asarray(levels[0][slice_index]), srgb).astype(np.float64)
    k = slice_index - entry.first_slice
    return apply_slice_scale(rgba, entry.scale[k] if entry.scale else (1.0, 1.0), entry.bias[k] if entry.bias else (0.0, 0.0))


def separable_factors(levels, srgb: bool, entry: MaterialEntry):
    """The factors of a factored separable material as the GPU reads them (its level-0 slices decoded), or None."""
    if entry.factors is None:
        return None
    texels = np.asarray(levels[0])[entry.first_slice : entry.first_slice + entry.slice_count]
    decoded = dequantize_rgba(texels, srgb)
    f = entry.factors
    back = f.transmission
    pair = None if back is None else (entry.scale[back.slice][0], entry.bias[back.slice][0])
    return factors_from_slices(decoded, f.factor_scale, f.factor_bias, f.parametrization, f.target, pair)


def custom_f_cos(levels, srgb: bool, entry: MaterialEntry):
    """``f_cos(n, l, v)`` ``(N, 3)`` of a separable material as the lighting pass evaluates it, from the
    atlas as the GPU reads it: its factors' rebuild, or, held as one LUT slice or a closed form, that
    representation's (:func:`atlasgen.models.separable.representation_radiance`); None if it has neither."""
    factors = separable_factors(levels, srgb, entry)
    if factors is not None:
        return lambda n, l, v: evaluate_factors(factors, n, l, v, cosine=True)
    radiance = representation_radiance(entry, decode_render_slice(levels, srgb, entry, entry.first_slice))
    if radiance is None:
        return None

    def f_cos(n, l, v):
        one = np.ones(np.broadcast_shapes(np.shape(n), np.shape(l), np.shape(v)))
        return radiance(n, l, v, one, np.full(one.shape[:-1], 0.5), one)

    return f_cos


def separable_albedo_table(f_cos) -> np.ndarray:
    """S_sep(N.V) ``(HEIGHT, 3)`` of a :func:`custom_f_cos`, in the local frame (n = +z)."""
    # The rebuild's azimuths are unsigned (acos), so its f cos is even in the azimuth of l.
    return directional_albedo_table(lambda l, v: f_cos(np.broadcast_to([0.0, 0.0, 1.0], l.shape), l, v), HEIGHT, even=True)


def material_tables(levels, srgb: bool, entry: MaterialEntry, custom_lighting: bool) -> np.ndarray:
    """The tables layer of a material (its first slice, the ID the g-buffer holds): ``(32, TABLE_COLUMNS, 4)`` float32.

    A separable material (``custom_lighting``) gets S_sep from the f cos the lighting pass gives it:
    its factors', or, held as one LUT slice or a closed form, that representation's
    (:func:`atlasgen.models.separable.representation_radiance`).
    """
    out = np.zeros((HEIGHT, TABLE_COLUMNS, 4))
    if custom_lighting:
        f_cos = custom_f_cos(levels, srgb, entry)
        if f_cos is not None:
            out[:, _SEPARABLE_COLUMN, :3] = separable_albedo_table(f_cos)
        return out.astype(np.float32)
    values = decode_render_slice(levels, srgb, entry, entry.first_slice)
    nearest = entry.flag("nearest")
    out[:, _SH_COLUMN : _SH_COLUMN + SH_ORDER + 1, :3] = slice_sh_table(values, nearest=nearest)
    out[:, _SPECULAR_COLUMN:_SEPARABLE_COLUMN, :] = slice_specular_table(values, nearest=nearest).reshape(HEIGHT, -1, 4)
    return out.astype(np.float32)


def shows_environment(scene) -> bool:
    """Whether ``scene``'s background pixels show its environment (it has one and gives no background
    colour); otherwise they are the constant background colour."""
    return scene.environment is not None and not scene.background_given


def pack_environment(data: EnvironmentData | None, show_background: bool) -> bytes:
    """The ``Environment`` uniform: 25 coefficients, and (levels, level-0 rows, background flag)."""
    if data is None:
        return ENVIRONMENT.pack(sh=np.zeros((25, 4)), params=[2.0, 2.0, 0.0, 0.0])
    sh = np.zeros((25, 4))
    sh[:, :3] = data.sh
    return ENVIRONMENT.pack(sh=sh, params=[len(data.levels), data.levels[0].shape[0], float(show_background), 0.0])


def upload_environment(ctx, data: EnvironmentData | None):
    """The rgba16float texture whose mip k is prefiltered level k (a 4x2, 2-level placeholder for None)."""
    import wgpu

    levels = data.levels if data is not None else [np.zeros((2, 4, 3), np.float32), np.zeros((1, 2, 3), np.float32)]
    h, w = levels[0].shape[:2]
    texture = ctx.device.create_texture(
        label="environment",
        size=(w, h, 1),
        format=wgpu.TextureFormat.rgba16float,
        usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST,
        mip_level_count=len(levels),
    )
    for k, level in enumerate(levels):
        lh, lw = level.shape[:2]
        rgba = np.concatenate([level, np.ones((lh, lw, 1), np.float32)], -1).astype(np.float16)
        ctx.device.queue.write_texture(
            {"texture": texture, "mip_level": k, "origin": (0, 0, 0)},
            np.ascontiguousarray(rgba),
            {"offset": 0, "bytes_per_row": 8 * lw, "rows_per_image": lh},
            (lw, lh, 1),
        )
    return texture


def upload_tables(ctx, tables: np.ndarray):
    """The rgba32float texture array of :func:`material_tables` layers, ``(layers, 32, TABLE_COLUMNS, 4)``."""
    import wgpu

    layers = tables.shape[0]
    texture = ctx.device.create_texture(
        label="environment-tables",
        size=(TABLE_COLUMNS, HEIGHT, layers),
        format=wgpu.TextureFormat.rgba32float,
        usage=wgpu.TextureUsage.TEXTURE_BINDING | wgpu.TextureUsage.COPY_DST,
    )
    ctx.device.queue.write_texture(
        {"texture": texture, "mip_level": 0, "origin": (0, 0, 0)},
        np.ascontiguousarray(tables, dtype=np.float32),
        {"offset": 0, "bytes_per_row": 16 * TABLE_COLUMNS, "rows_per_image": HEIGHT},
        (TABLE_COLUMNS, HEIGHT, layers),
    )
    return texture


#: How many materials' tables :class:`EnvironmentLighting` keeps for atlases to come, the latest first.
_KEPT_TABLES = 64


def _tables_key(levels, srgb: bool, entry: MaterialEntry, custom_lighting: bool) -> tuple:
    """What :func:`material_tables` reads: the entry (its scales, biases, flags, factors) and its level-0 texels."""
    texels = np.asarray(levels[0][entry.first_slice : entry.first_slice + entry.slice_count])
    return repr(entry), srgb, custom_lighting, hashlib.sha256(texels.tobytes()).digest()


class EnvironmentLighting:
    """The renderer's environment resources on one device: per environment (cached) and per material slice.

    :meth:`bindings` gives what the lighting pass binds for a scene (placeholders without an
    environment: that scene's shader compiles the environment out and never reads them).
    """

    def __init__(self, ctx, atlas):
        self.ctx = ctx
        self.atlas = atlas
        self._environments: dict = {}
        self._tables = np.zeros((LAYERS, HEIGHT, TABLE_COLUMNS, 4), np.float32)
        self._done: set = set()
        self._tables_texture = None
        self._placeholder = None
        #: A material's tables by what they are made from (:func:`_tables_key`), kept across atlases.
        self._made: dict = {}
        #: Where prefiltered built-in environments are kept across processes (:func:`cached_environment`); None: nowhere.
        self.cache_dir = None

    def for_atlas(self, atlas) -> EnvironmentLighting:
        """The same for another atlas: the prefiltered environment is kept, and so are the tables of every
        material whose texels and entry are unchanged (a preview's floor, a material that was not edited)."""
        other = EnvironmentLighting(self.ctx, atlas)
        other._environments = self._environments
        other._made = self._made
        other.cache_dir = self.cache_dir
        return other

    def data(self, env: Environment) -> EnvironmentData:
        """The uploaded data of ``env`` (built once per environment)."""
        return self._entry(env)[0]

    def _entry(self, env):
        if env not in self._environments:
            data = cached_environment(env, self.cache_dir)
            self._environments = {env: (data, upload_environment(self.ctx, data))}  # keep one environment only
        return self._environments[env]

    def tables(self, entries, custom) -> object:
        """The tables texture holding every material of ``entries`` (``custom``: theirs is ``custom_lighting``)."""
        new = {e.first_slice: (e, c) for e, c in zip(entries, custom) if e.first_slice not in self._done}
        made = {}
        for entry, is_custom in new.values():
            key = _tables_key(self.atlas.levels, self.atlas.srgb, entry, is_custom)
            if key not in self._made:
                self._made[key] = material_tables(self.atlas.levels, self.atlas.srgb, entry, is_custom)
            made[key] = self._made[key]
            self._tables[entry.first_slice] = made[key]
            self._done.add(entry.first_slice)
        if new:
            self._made = {**made, **{k: v for k, v in self._made.items() if k not in made}}
            self._made = dict(list(self._made.items())[:_KEPT_TABLES])
        if new or self._tables_texture is None:
            self._tables_texture = upload_tables(self.ctx, self._tables)
        return self._tables_texture

    def bindings(self, scene, entries, custom):
        """(uniform buffer, environment texture, tables texture) for the lighting pass of ``scene``."""
        import wgpu

        device = self.ctx.device
        if scene.environment is None:
            if self._placeholder is None:
                buffer = device.create_buffer_with_data(data=pack_environment(None, False), usage=wgpu.BufferUsage.UNIFORM)
                empty = np.zeros((1, HEIGHT, TABLE_COLUMNS, 4), np.float32)
                self._placeholder = (buffer, upload_environment(self.ctx, None), upload_tables(self.ctx, empty))
            return self._placeholder
        data, texture = self._entry(scene.environment)
        buffer = device.create_buffer_with_data(
            data=pack_environment(data, shows_environment(scene)), usage=wgpu.BufferUsage.UNIFORM
        )
        return buffer, texture, self.tables(entries, custom)
