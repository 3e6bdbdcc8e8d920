"""The preview's label: what it says of each kind of manifest entry, and how it is drawn."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.io.manifest import (
    AnalyticRepresentation,
    BrdfError,
    ErrorSummary,
    Fit,
    LutRepresentation,
    MaterialEntry,
    SeparableFactors,
    SeparableTransmission,
)
from atlasgen.preview.label import LABEL_FONT_SIZE, draw_label, error_text, label_lines, representation_text


def entry(**parts) -> MaterialEntry:
    count = parts.pop("slice_count", 1)
    return MaterialEntry(name="m", id=3, constant="MATERIAL_M", first_slice=3, slice_count=count, type=parts.pop("type", "lambert"),
                         quantization_error=ErrorSummary(max=0.002, rms=0.00037), **parts)  # fmt: skip


def factors(terms: int, transmission: bool = False) -> SeparableFactors:
    table = [[[1.0, 1.0, 1.0], [1.0, 1.0, 1.0]]] * terms
    return SeparableFactors(parametrization="half_diff", factor_scale=table, factor_bias=table,
                            errors_8bit=BrdfError(relative_rms=0.0174581, relative_rms_se=0.000143, log_error=0.0037),
                            transmission=SeparableTransmission(slice=terms) if transmission else None)  # fmt: skip


CASES = {
    "plain LUT": (entry(), "LUT slice", "error: 8-bit quantisation RMS 0.00037"),
    "fitted to physics": (
        entry(type="fresnel", fit=Fit(source="physical", gloss=0.55, details={"relative_rms": 0.0208151834393869})),
        "LUT slice fitted to its physical reference (shaded at gloss 0.55)",
        "error: 2.08% relative RMS against its physical reference (fit)",
    ),
    "a separable material's auto choice of one slice": (
        entry(type="separable", fit=Fit(source="auto", gloss=0.5, details={"relative_rms": 0.0571})),
        "LUT slice fitted to its source BRDF (shaded at gloss 0.5)",
        "error: 5.71% relative RMS against its source BRDF (fit)",
    ),
    "LUT within a budget": (
        entry(
            type="toon",
            representation=LutRepresentation(
                supersampling=4, error_budget=0.01, reconstruction_error=0.0031, meets_budget=True, candidates=[]
            ),
        ),  # fmt: skip
        "LUT slice, 4x supersampled",
        "error: reconstruction RMS 0.0031 (budget 0.01)",
    ),
    "separable": (
        entry(type="separable", slice_count=4, factors=factors(4)),
        "separable, 4 terms",
        "error: 1.75% +- 0.01% relative RMS of f cos (8-bit)",
    ),
    "separable with a back-light": (
        entry(type="separable", slice_count=2, factors=factors(1, transmission=True)),
        "separable, 1 term + transmission slice",
        "error: 1.75% +- 0.01% relative RMS of f cos (8-bit)",
    ),
    "closed form": (
        entry(
            type="separable",
            representation=AnalyticRepresentation(
                distribution="ggx", alpha=0.2, fresnel="schlick", f0=[0.04] * 3, ior=1.5, specular=[1.0] * 3, diffuse=[0.5] * 3
            ),
        ),  # fmt: skip
        "analytic ggx (closed form in the shader)",
        None,
    ),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_the_label_names_the_representation_and_its_error(case):
    material, representation, error = CASES[case]
    assert representation_text(material) == representation
    assert error_text(material) == error
    assert label_lines(material) == [f"m ({material.type})", representation] + ([error] if error else [])


def test_the_label_is_drawn_below_an_unchanged_picture():
    rng = np.random.default_rng(1)
    picture = rng.integers(0, 256, (40, 300, 3), dtype=np.uint8)
    two, three = draw_label(picture, ["clay (lambert)", "LUT slice"]), draw_label(picture, ["a", "b", "c"])
    np.testing.assert_array_equal(two[:40], picture)
    assert three.shape[0] - two.shape[0] == LABEL_FONT_SIZE + 5 and two.shape[1] == 300
    band = two[40:].astype(int)
    lines = np.split(band[6:-6], 2)
    # Text is drawn: light pixels on the dark band, on each line, the first line's brightest.
    assert all(line.max() > 150 for line in lines) and np.median(band) < 40
    assert lines[0].max() > lines[1].max()
    assert (
        draw_label(picture, ["clay (lambert)", "x"])[40:].tolist() != draw_label(picture, ["clay (lambert)", "y"])[40:].tolist()
    )
