"""Validation test fixtures, shared by tests/validate and tests/cli/test_validate_cmd.py."""

from __future__ import annotations

import pickle
import textwrap

import pytest

from tests.conftest import shared_folder

#: One material per LUT model type; names are what the tests look up.
MATERIALS = {
    "matte": 'type = "lambert"\ncolour = [0.8, 0.5, 0.3]\n',
    "coat": 'type = "fresnel"\ncolour = [0.2, 0.35, 0.6]\nior = 1.5\n',
    "film": 'type = "iridescent"\ncolour = [0.05, 0.05, 0.05]\nthickness = 420.0\nbacklight = 0.5\n',
    "skin": 'type = "sss"\ncolour = [0.9, 0.7, 0.6]\nradius = 8.0\n',
    "leaf": 'type = "backlit"\ncolour = [0.2, 0.5, 0.1]\ntransmission_colour = [0.6, 0.9, 0.2]\n',
    "cel": 'type = "toon"\nsilhouette = 0.2\noutline = true\n',
    "gloss": 'type = "separable"\nsource = "ggx"\nalpha = 0.3\nterms = 2\ndiffuse = [0.2, 0.2, 0.2]\n',
}

#: Tiny images keep every Mitsuba and GPU render in the tens of milliseconds.
TINY = (40, 30)


@pytest.fixture(scope="session")
def validation_atlas(tmp_path_factory):
    """``atlas.dds`` (with manifest and include) holding :data:`MATERIALS`, baked once per test run
    for every xdist worker (:func:`tests.conftest.shared_folder`): the tests only read it."""

    def build(root):
        from atlasgen.bake.pipeline import bake_atlas, write_bake
        from atlasgen.materials.material import read_materials

        folder = root / "materials"
        folder.mkdir()
        for name, text in MATERIALS.items():
            (folder / f"{name}.toml").write_text(textwrap.dedent(text))
        write_bake(bake_atlas(read_materials([folder])), root / "atlas.dds")

    return shared_folder(tmp_path_factory, "validation-atlas", build) / "atlas.dds"


@pytest.fixture(scope="session")
def mitsuba_rgb():
    """Mitsuba in ``llvm_ad_rgb`` through atlasgen's loader; skips where the LLVM backend is missing."""
    from atlasgen.errors import BackendError

    try:
        from atlasgen.validate.backend import load_mitsuba

        return load_mitsuba("llvm_ad_rgb")
    except BackendError as exc:
        pytest.skip(str(exc))


@pytest.fixture(scope="session")
def validation_run(validation_atlas, mitsuba_rgb, gpu_context, tmp_path_factory):
    """validate_atlas at :data:`TINY`: every test material on ``front`` (with physical
    references), and the ones with back-lighting or the gate on ``back``.

    Run once per test run: the first xdist worker to ask pickles it for the others (its Mitsuba
    and GPU renders are a good part of a minute of CPU), and every worker reads that pickle, so
    they all test the same object."""

    def build(folder):
        from atlasgen.validate.run import validate_atlas

        # An explicit cap (16x the start): the library's default lets references grow to 8192 spp.
        run = validate_atlas(validation_atlas, scenes=["front"], resolution=TINY, physical_spp=4, max_physical_spp=64)
        back = validate_atlas(validation_atlas, ["matte", "skin", "leaf", "film"], scenes=["back"], resolution=TINY,
                              physical_spp=4, max_physical_spp=64)  # fmt: skip
        run.runs += back.runs
        run.settings["scenes"] += back.settings["scenes"]  # as one run on both scenes lists them
        (folder / "run.pickle").write_bytes(pickle.dumps(run))

    folder = shared_folder(tmp_path_factory, "validation-run", build)
    return pickle.loads((folder / "run.pickle").read_bytes())
