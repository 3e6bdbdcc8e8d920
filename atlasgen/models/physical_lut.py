"""One LUT slice fitted from physics and drawn by the renderer: the LUT candidate of every representation choice.

The renderer draws a slice A at gloss g as (docs/atlas-format.md, albedo 1)

    f cos = A.rgb / pi + A.a * D(N.H) V(N.L, N.V) max(N.L, 0),

A read bilinearly at (N.L, N.V). :func:`fit_lut` fits A to a BRDF source
(:func:`atlasgen.models.physical_fit.fit_slice`) at the gloss, of :data:`LUT_GLOSSES`, whose
8-bit slice errs least on the selection sample of :mod:`atlasgen.separable.error`; the
figures are then reported on the independent report sample.
"""

from __future__ import annotations

import json
from functools import lru_cache

import numpy as np

from atlasgen.io.referenced_files import files_state
from atlasgen.models.base import encode_scaled
from atlasgen.models.physical_fit import AZIMUTHS, fit_slice
from atlasgen.optics.interpolation import sample_slice
from atlasgen.optics.quantize import dequantize_rgba, quantize_rgba
from atlasgen.optics.specular import half_vector_cosine, renderer_f_cos
from atlasgen.separable.approximate import reference_values
from atlasgen.separable.error import SELECTION_SEED, error_sample_for, measure_errors, relative_log_errors
from atlasgen.separable.source import make_source

__all__ = ["LUT_GLOSSES", "SELECTION_AZIMUTHS", "pair_geometry", "slice_f_cos", "stored_slice", "fit_lut", "lut_errors"]

#: Azimuths per texel of the slices the glosses are screened with (the best two are fitted with
#: :data:`~atlasgen.models.physical_fit.AZIMUTHS`).
SELECTION_AZIMUTHS = 32
#: Renderer glosses a LUT fitted from physics chooses among (on the selection sample).
LUT_GLOSSES = (0.0, 0.25, 0.5, 0.625, 0.75, 0.875)


def pair_geometry(l, v):
    """N.L, N.V, N.H and where l + v = 0, for unit (l, v) ``(N, 3)`` with n = +z."""
    return (l[:, 2], v[:, 2], *half_vector_cosine(l, v))


def slice_f_cos(rgba: np.ndarray, gloss: float, l: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The renderer's f cos(theta_l) (``(N, 3)``) drawing the slice ``rgba`` ``(H, W, 4)`` at renderer gloss ``gloss``.

    f cos = A.rgb / pi + A.a D(N.H) V(N.L, N.V) max(N.L, 0) with A read bilinearly at
    (N.L, N.V) (:func:`~atlasgen.optics.interpolation.sample_slice`), albedo 1.
    """
    nl, nv, nh, degenerate = pair_geometry(l, v)
    m = sample_slice(np.asarray(rgba, dtype=np.float64), np.clip(nl, -1.0, 1.0), np.clip(nv, 0.0, 1.0))
    return renderer_f_cos(m, 1.0, gloss, nl, nv, nh, degenerate)


def stored_slice(rgba: np.ndarray, srgb: bool = True) -> np.ndarray:
    """``rgba`` as the atlas stores and the sampler returns it: per-slice scale
    (:func:`~atlasgen.models.base.encode_scaled`), 8 bits (sRGB RGB, linear A), decoded and rescaled."""
    enc = encode_scaled(np.asarray(rgba, dtype=np.float64)[None])
    decoded = dequantize_rgba(quantize_rgba(enc.stored, srgb), srgb)
    return decoded[0] * enc.scale[0][[0, 0, 0, 1]]


class _Memo:
    """f cos evaluated once: :func:`fit_slice` asks for the same pairs at every gloss."""

    def __init__(self, f_cos):
        self.f_cos, self.last = f_cos, None

    def __call__(self, l, v):
        if (
            self.last is None
            or self.last[0].shape != l.shape
            or not (np.array_equal(self.last[0], l) and np.array_equal(self.last[1], v))
        ):
            self.last = (l.copy(), v.copy(), self.f_cos(l, v))
        return self.last[2]


@lru_cache(maxsize=32)
def _fit_lut(params_json: str, glosses: tuple, srgb: bool, measure: str = "relative_rms", files: tuple = ()):
    source = make_source(json.loads(params_json))
    selection = error_sample_for(source, SELECTION_SEED)
    reference, _ = reference_values(source, selection)
    # The glosses are screened on slices fitted with SELECTION_AZIMUTHS azimuths (a quarter of
    # the cost); the best two are fitted with the full AZIMUTHS and the better one kept.
    coarse = _Memo(source.f_cos)
    screened = []
    for g in glosses:
        rgba, _ = fit_slice(coarse, float(g), azimuths=SELECTION_AZIMUTHS, srgb=srgb)
        screened.append((lut_errors(stored_slice(rgba, srgb), float(g), reference, selection)[measure], float(g)))
    fine = _Memo(source.f_cos)
    best = None
    for _, g in sorted(screened)[:2]:
        rgba, info = fit_slice(fine, g, azimuths=AZIMUTHS, srgb=srgb)
        error = lut_errors(stored_slice(rgba, srgb), g, reference, selection)[measure]
        if best is None or error < best[2]:
            best = (rgba, info, error)
    rgba, info, error = best
    rgba.setflags(write=False)
    return rgba, {**info, f"selection_{measure}": error, "selection_seed": selection.seed}


def fit_lut(params: dict, glosses=LUT_GLOSSES, srgb: bool = True, measure: str = "relative_rms"):
    """The slice fitted from physics to the separable-model source ``params`` (:func:`~atlasgen.models.physical_fit.fit_slice`) for the renderer
    gloss of ``glosses`` whose 8-bit slice errs least on the *selection* sample
    (:data:`~atlasgen.separable.error.SELECTION_SEED`), and its fit description.

    The fit's own texel grid with 128 azimuths undersamples a sharp lobe, so the gloss is judged on
    the importance-sampled selection pairs instead; never on the sample the figures are reported on.
    ``measure`` is the error the gloss is judged by: a key of :func:`lut_errors`.
    """
    return _fit_lut(
        json.dumps(params, sort_keys=True), tuple(float(g) for g in glosses), bool(srgb), str(measure), files_state(params)
    )


def lut_errors(rgba: np.ndarray, gloss: float, reference: np.ndarray, sample) -> dict:
    """Relative RMS of f cos, log error and relative log RMS
    (:func:`~atlasgen.separable.error.relative_log_errors`) with standard errors of the slice drawn
    at ``gloss``, against ``reference`` (f cos at ``sample``'s pairs)."""
    approx = slice_f_cos(rgba, gloss, sample.l, sample.v)
    return {**measure_errors(reference, approx, sample.weight), **relative_log_errors(reference, approx, sample.weight)}
