"""The interface every material model implements, and the default way its slices are encoded."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from atlasgen.contract import HEIGHT, WIDTH, texel_centres
from atlasgen.materials.params import Param

__all__ = ["Model", "SliceSet", "EncodedSlices", "encode_scaled"]


@dataclass
class SliceSet:
    """Float slices a model wants in the atlas: ``values`` is ``(n, HEIGHT, WIDTH, 4)`` linear RGBA."""

    values: np.ndarray
    extra: dict = field(default_factory=dict)  # model-specific manifest fields (must be deterministic)
    timings: dict = field(default_factory=dict)  # seconds per stage, for atlas.timings.json


@dataclass
class EncodedSlices:
    """Slices mapped into [0, 1] for 8-bit storage.

    A renderer recovers the linear value as ``stored * scale + bias``, with one
    ``(rgb, alpha)`` pair of each per slice.
    """

    stored: np.ndarray  # (n, H, W, 4) in [0, 1]
    scale: np.ndarray  # (n, 2): rgb, alpha
    bias: np.ndarray  # (n, 2)
    clamped_fraction: float
    extra: dict = field(default_factory=dict)  # model-specific manifest fields (e.g. per-factor scale/bias)


def encode_scaled(values: np.ndarray, rgb_scale="auto", alpha_scale="auto") -> EncodedSlices:
    """Divide each slice by a scale so it fits UNORM8; report what had to be clamped.

    With ``"auto"`` the scale is max(1, max value) of the slice's RGB (or A), so nothing
    clamps; a fixed scale trades range for precision, and what exceeds it is clamped
    and counted. Negative values (never produced by a valid LUT model) clamp to 0 and
    are counted too.
    """
    n = values.shape[0]
    peaks = np.stack([values[..., :3].max(axis=(1, 2, 3)), values[..., 3].max(axis=(1, 2))], axis=1)
    scale = np.empty((n, 2))
    for g, fixed in enumerate((rgb_scale, alpha_scale)):
        scale[:, g] = np.maximum(1.0, peaks[:, g]) if fixed == "auto" else float(fixed)
    scaled = values / scale[:, [0, 0, 0, 1]][:, None, None, :]
    out_of_range = (scaled > 1.0) | (scaled < 0.0)
    stored = np.clip(scaled, 0.0, 1.0)
    return EncodedSlices(stored, scale, np.zeros((n, 2)), float(out_of_range.mean()))


class Model:
    """A material model: a TOML ``type``, its parameter schema and its evaluation.

    Subclasses set ``type_name``, ``params`` and ``reference``, and implement
    :meth:`evaluate`; multi-slice models override :meth:`bake` and :meth:`encode`.
    """

    type_name: ClassVar[str] = ""
    params: ClassVar[tuple[Param, ...]] = ()
    reference: ClassVar[str] = ""

    def check(self, values: dict, path) -> None:
        """Cross-parameter checks beyond each parameter's own range; raise MaterialError."""

    def evaluate(self, values: dict, n_dot_l: np.ndarray, n_dot_v: np.ndarray) -> np.ndarray:
        """Linear RGBA at arbitrary (N.L, N.V): RGB the diffuse response, A the specular scale."""
        raise NotImplementedError

    def apply_budget(self, values: dict, budget: float, path) -> dict:
        """Parameters for a material that carries an ``error_budget``.

        LUT models keep theirs: the bake meets the budget by supersampling
        (:mod:`atlasgen.bake.adaptive`). Models with their own knob (the separable term
        count) map the budget onto it here.
        """
        return values

    def flags(self, values: dict) -> dict:
        """Render-time requests recorded in the manifest (e.g. ``{"outline": True}``)."""
        return {}

    def slice_count(self, values: dict) -> int:
        return 1

    def bake(self, values: dict) -> SliceSet:
        """Evaluate at the texel centres of one slice.

        The axes go in as a row and a column, so a model that separates its N.L and
        N.V work (a spectral film, a profile integral) computes each only once.
        """
        nl, nv = texel_centres(WIDTH, HEIGHT)
        rgba = np.asarray(self.evaluate(values, nl[None, :], nv[:, None]), dtype=np.float64)
        rgba = np.broadcast_to(rgba, (HEIGHT, WIDTH, 4))
        return SliceSet(np.array(rgba).reshape(1, HEIGHT, WIDTH, 4))

    def encode(self, values: dict, slices: SliceSet, rgb_scale="auto", alpha_scale="auto") -> EncodedSlices:
        return encode_scaled(slices.values, rgb_scale, alpha_scale)

    def finalize(self, values: dict, slices: SliceSet, encoded: EncodedSlices, decoded: np.ndarray) -> dict:
        """Extra manifest fields measured on the 8-bit result.

        ``decoded`` is what a sampler returns at level 0, ``(n, H, W, 4)``, sRGB
        already decoded, before the slice's scale and bias.
        """
        return {}

    @classmethod
    def include_wgsl(cls, entries: list[dict]) -> str:
        """WGSL this model type adds to the shader include, given its manifest entries."""
        return ""
