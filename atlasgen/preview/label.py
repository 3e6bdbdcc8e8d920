"""The label under a preview: the material's name, how it is stored, and its error from the manifest.

The text comes from the manifest entry's typed fields (:class:`atlasgen.io.manifest.MaterialEntry`):
what the representation is (a LUT slice, a fitted one, K separable terms, a closed form) and
the one figure the docs call that representation's error:

========================  ==================================================================
representation            error shown
========================  ==================================================================
separable terms           ``errors_8bit.relative_rms``: the atlas as written, relative RMS of
                          f cos over the report sample (docs/separable.md, "Error")
slice fitted to physics   ``fit.relative_rms``: the fit's relative RMS of f cos against its
                          physical reference (docs/materials.md, ``from = "physical"``)
LUT within a budget       ``representation.reconstruction_error``: RMS of the slice as sampled
                          against the model (docs/materials.md, "Error budgets")
any other LUT slice       ``quantization_error.rms``: the 8-bit texels against the float model
                          (docs/atlas-format.md, "Texel values")
closed form               none: exact
========================  ==================================================================
"""

from __future__ import annotations

import numpy as np

from atlasgen.errors import BackendError
from atlasgen.io.manifest import AnalyticRepresentation, LutRepresentation, MaterialEntry

__all__ = ["representation_text", "error_text", "label_lines", "draw_label", "LABEL_FONT_SIZE", "MEASURING"]

#: The error line of a picture drawn from a draft bake (watch mode) while its figure is measured.
MEASURING = "error: measuring ... (the picture is final)"
#: Pixel size of the label's font (Pillow's built-in one).
LABEL_FONT_SIZE = 14
_LINE, _PAD = LABEL_FONT_SIZE + 5, 6
_BAND, _TEXT, _TITLE = (24, 24, 27), (190, 190, 195), (245, 245, 245)


#: What a fitted slice was fitted to, by the manifest's ``fit.from`` (:class:`atlasgen.io.manifest.Fit`).
_FIT_SOURCES = {"physical": "its physical reference", "bsdf": "its Mitsuba BSDF", "auto": "its source BRDF"}


def representation_text(entry: MaterialEntry) -> str:
    """How ``entry`` is stored and drawn, e.g. ``LUT slice``, ``separable, 4 terms``, ``analytic ggx``.

    >>> from atlasgen.io.manifest import MaterialEntry
    >>> representation_text(MaterialEntry(name="clay", id=0, constant="MATERIAL_CLAY", first_slice=0, type="lambert"))
    'LUT slice'
    """
    rep, factors, fit = entry.representation, entry.factors, entry.fit
    if isinstance(rep, AnalyticRepresentation):
        return f"analytic {rep.distribution} (closed form in the shader)"
    if factors is not None:
        text = f"separable, {factors.term_slices} term{'s' if factors.term_slices != 1 else ''}"
        return text + (" + transmission slice" if factors.transmission is not None else "")
    text = "LUT slice"
    if fit is not None:
        text += f" fitted to {_FIT_SOURCES.get(fit.source, fit.source)} (shaded at gloss {fit.gloss:g})"
    if isinstance(rep, LutRepresentation) and rep.supersampling > 1:
        text += f", {rep.supersampling}x supersampled"
    return text


def error_text(entry: MaterialEntry) -> str | None:
    """The manifest's error figure for ``entry`` (module table), or None for a closed form.

    >>> from atlasgen.io.manifest import ErrorSummary, MaterialEntry
    >>> error_text(MaterialEntry(name="clay", id=0, constant="MATERIAL_CLAY", first_slice=0, type="lambert",
    ...                          quantization_error=ErrorSummary(max=0.002, rms=0.00037)))
    'error: 8-bit quantisation RMS 0.00037'
    """
    rep, factors, fit = entry.representation, entry.factors, entry.fit
    if isinstance(rep, AnalyticRepresentation):
        return None
    if factors is not None and factors.errors_8bit is not None:
        e = factors.errors_8bit
        se = f" +- {100 * e.relative_rms_se:.2f}%" if e.relative_rms_se is not None else ""
        return f"error: {100 * e.relative_rms:.2f}%{se} relative RMS of f cos (8-bit)"
    relative_rms = fit.details.get("relative_rms") if fit is not None else None
    if isinstance(relative_rms, (int, float)):
        return f"error: {100 * relative_rms:.2f}% relative RMS against {_FIT_SOURCES.get(fit.source, fit.source)} (fit)"
    if isinstance(rep, LutRepresentation):
        return f"error: reconstruction RMS {rep.reconstruction_error:.2g} (budget {rep.error_budget:g})"
    return f"error: 8-bit quantisation RMS {entry.quantization_error.rms:.2g}"


def label_lines(entry: MaterialEntry, measuring: bool = False) -> list[str]:
    """The label's lines: ``name (type)``, :func:`representation_text`, :func:`error_text` if any;
    ``measuring`` (``entry`` is a draft's, its figure still to come): :data:`MEASURING` in its place.

    >>> from atlasgen.io.manifest import MaterialEntry
    >>> label_lines(MaterialEntry(name="gold", id=0, constant="MATERIAL_GOLD", first_slice=0, type="separable"), True)[2]
    'error: measuring ... (the picture is final)'
    """
    error = MEASURING if measuring else error_text(entry)
    return [f"{entry.name} ({entry.type})", representation_text(entry)] + ([error] if error else [])


def draw_label(codes: np.ndarray, lines: list[str]) -> np.ndarray:
    """``codes`` (``(h, w, 3)`` uint8) with a band below it holding ``lines``, the first brighter.

    Drawn with Pillow's built-in font (:data:`LABEL_FONT_SIZE` px); the picture above is unchanged.
    """
    try:
        from PIL import Image, ImageDraw, ImageFont
    except ImportError:
        raise BackendError("the preview's labels need the Python package Pillow (pip install 'atlasgen[render]')") from None

    h, w, _ = codes.shape
    band = _PAD * 2 + _LINE * len(lines)
    image = Image.new("RGB", (w, h + band), _BAND)
    image.paste(Image.fromarray(np.ascontiguousarray(codes, dtype=np.uint8), "RGB"), (0, 0))
    draw = ImageDraw.Draw(image)
    font = ImageFont.load_default(size=LABEL_FONT_SIZE)
    for i, line in enumerate(lines):
        draw.text((_PAD + 2, h + _PAD + i * _LINE), line, fill=_TITLE if i == 0 else _TEXT, font=font)
    return np.asarray(image, dtype=np.uint8)
