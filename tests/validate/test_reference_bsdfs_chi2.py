"""Chi-square tests of the sampling of atlasgen's Python Mitsuba BSDFs.

Each BSDF's ``sample`` must draw directions with the density its ``pdf`` reports, or a
path tracer weighting by ``f / pdf`` is biased. Mitsuba's own test (``mitsuba.chi2``,
as used by its ``src/bsdfs/tests``) histograms samples on the sphere (200,000 here), integrates
``pdf`` over the same cells and runs Pearson's chi-square test on the two. Custom Python
BSDFs need a vectorised variant: ``llvm_ad_rgb``.
"""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.io.manifest import MaterialEntry
from atlasgen.materials.material import read_material
from atlasgen.validate.references import model_reference, physical_reference

# ~0.5 s a test on 2 cores (the mitsuba marker comes with the mitsuba_rgb fixture).
pytestmark = pytest.mark.slow


def register(mi) -> None:
    """Register atlasgen's reference BSDFs for ``mi``'s variant (the one place this file imports them from)."""
    from atlasgen.validate.references import register_references

    register_references(mi)


def _direction(theta_degrees: float, below: bool = False) -> list:
    theta = np.radians(theta_degrees)
    return [float(np.sin(theta)), 0.0, float(-np.cos(theta) if below else np.cos(theta))]


#: Incident directions: along the normal, grazing, and from below (a back face, which the
#: model and BRDF references shade with the flipped normal, so they sample below too).
NORMAL, GRAZING, BELOW = _direction(0.0), _direction(85.0), _direction(40.0, below=True)


@pytest.fixture
def mi(mitsuba_rgb, tmp_path, monkeypatch):
    register(mitsuba_rgb)
    monkeypatch.chdir(tmp_path)  # a failing ChiSquareTest writes chi2_data.py into the working folder
    return mitsuba_rgb


@pytest.fixture
def entry(write_material):
    """The manifest entry (name, type, resolved params) of a material written from TOML text."""

    def make(name: str, text: str) -> MaterialEntry:
        material = read_material(write_material(name, text))
        return MaterialEntry(
            name=material.name, id=0, constant="MATERIAL_M", first_slice=0, type=material.type, params=material.params
        )

    return make


def back_face_adapter(mi, bsdf: dict, wi: list):
    """``BSDFAdapter``'s two functors on a back face (wi.z < 0).

    ``BSDFAdapter``'s interaction has no geometric normal, and the model and BRDF
    references tell a back face by it (as the renderer's g-buffer does), so this one has
    the normal and shading frame (0, 0, 1).
    """
    import drjit as dr

    plugin, ctx = mi.load_dict(bsdf), mi.BSDFContext()

    def interaction(n):
        si = dr.zeros(mi.SurfaceInteraction3f, n)
        si.wi, si.n, si.sh_frame = wi, mi.Normal3f(0, 0, 1), mi.Frame3f(mi.Vector3f(0, 0, 1))
        return si

    def sample_func(sample):
        bs, weight = plugin.sample(ctx, interaction(dr.width(sample)), sample[0], mi.Vector2f(sample[1], sample[2]))
        return bs.wo, dr.select(dr.all(weight == 0), 0.0, 1.0)

    def pdf_func(wo):
        return plugin.pdf(ctx, interaction(dr.width(wo)), wo)

    return sample_func, pdf_func


def assert_sampling_matches_pdf(mi, bsdf: dict, wi: list) -> None:
    """Pearson's chi-square test of ``sample`` against ``pdf`` at the 1% level (200k samples)."""
    from mitsuba.chi2 import BSDFAdapter, ChiSquareTest, SphericalDomain

    sample_func, pdf_func = BSDFAdapter(bsdf["type"], bsdf, wi=wi) if wi[2] > 0 else back_face_adapter(mi, bsdf, wi)
    # ires = 64 integration points per cell side: the model reference's GGX lobe at gloss 0.8
    # (alpha 0.04) is narrower than a cell, and the default 4 overestimates its integral (>1).
    test = ChiSquareTest(SphericalDomain(), sample_func, pdf_func, sample_dim=3, sample_count=200_000, ires=64, seed=3)
    assert test.run(significance_level=0.01, quiet=True), test.messages


@pytest.mark.parametrize("wi", [NORMAL, GRAZING, BELOW], ids=["normal", "grazing", "below"])
@pytest.mark.parametrize("gloss", [0.2, 0.8])
def test_model_reference_samples_its_pdf(mi, entry, wi, gloss):
    coat = entry("coat", 'type = "fresnel"\ncolour = [0.2, 0.35, 0.6]\nior = 1.5\n')
    assert_sampling_matches_pdf(mi, model_reference(coat, (0.9, 0.8, 0.7), gloss).bsdf, wi)


@pytest.mark.parametrize("wi", [NORMAL, GRAZING, BELOW], ids=["normal", "grazing", "below"])
@pytest.mark.parametrize("alpha", [0.1, 0.5])
def test_brdf_reference_samples_its_pdf(mi, entry, wi, alpha):
    gloss = entry("gloss", f'type = "separable"\nsource = "ggx"\nalpha = {alpha}\nterms = 2\ndiffuse = [0.2, 0.2, 0.2]\n')
    assert_sampling_matches_pdf(mi, model_reference(gloss, (0.9, 0.8, 0.7)).bsdf, wi)


@pytest.mark.parametrize("wi", [NORMAL, GRAZING], ids=["normal", "grazing"])
@pytest.mark.parametrize("gloss", [0.2, 0.8])
def test_thin_film_reference_samples_its_pdf(mi, entry, wi, gloss):
    film = entry("film", 'type = "iridescent"\ncolour = [0.3, 0.2, 0.1]\nthickness = 420.0\n')
    assert_sampling_matches_pdf(mi, physical_reference(film, (0.9, 0.8, 0.7), gloss).bsdf, wi)


@pytest.mark.parametrize("wi", [NORMAL, GRAZING, BELOW], ids=["normal", "grazing", "below"])
@pytest.mark.parametrize("colour", ["[0.6, 0.5, 0.4]", "[0.05, 0.1, 0.02]"], ids=["reflective", "transmissive"])
def test_thin_sheet_reference_samples_its_pdf(mi, entry, wi, colour):
    """The backlit reference samples both hemispheres: reflection on w_i's side, transmission through the sheet."""
    sheet = entry("sheet", f'type = "backlit"\ncolour = {colour}\nscale = 2.0\nspecular = 0.1\n')
    assert_sampling_matches_pdf(mi, physical_reference(sheet, (0.9, 0.8, 0.7), 0.5).bsdf, wi)
