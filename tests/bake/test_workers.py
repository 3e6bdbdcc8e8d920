"""Materials baked in worker processes: the same bytes as in process, the cache filled once, the
first failing material's own error, the progress in order, and typed errors across processes."""

from __future__ import annotations

import pickle
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner

from atlasgen.bake import cache as bake_cache
from atlasgen.bake import workers
from atlasgen.bake.cache import cache_path
from atlasgen.bake.pipeline import bake_atlas
from atlasgen.bake.workers import fill_cache, load_or_bake_all
from atlasgen.cli.main import app
from atlasgen.errors import FieldError, ManifestError, MaterialError, SceneError
from atlasgen.io.manifest import format_manifest
from atlasgen.materials.material import read_materials

LIBRARY = {
    "clay": 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n',
    "shell": 'type = "iridescent"\nthickness = 420.0\n',
    "rim": 'type = "backlit"\n',
    "band": 'type = "toon"\nthresholds = [0.05, 0.55]\n',
}


@pytest.fixture
def library(write_material):
    return read_materials([write_material(name, body) for name, body in LIBRARY.items()])


@pytest.mark.slow
def test_two_jobs_bake_the_bytes_of_one_and_fill_the_cache_once(tmp_path, library, monkeypatch):
    serial = bake_atlas(library, jobs=1)
    pools = []

    class Spy(workers.ProcessPoolExecutor):
        def __init__(self, jobs, **kwargs):
            pools.append(jobs)
            super().__init__(jobs, **kwargs)

    monkeypatch.setattr(workers, "ProcessPoolExecutor", Spy)
    seen = []
    parallel = bake_atlas(library, jobs=2, cache_dir=tmp_path / "cache", progress=seen.append)
    assert all(np.array_equal(a, b) for a, b in zip(serial.levels, parallel.levels, strict=True))
    assert format_manifest(serial.manifest) == format_manifest(parallel.manifest)
    assert serial.include == parallel.include
    assert seen == [m.name for m in library] and pools == [2]
    assert parallel.timings["cache"]["baked"] == [m.name for m in library]
    assert all(parallel.timings["materials"][m.name]["bake_s"] > 0 for m in library)
    # Every entry was written by this process, once: a second bake loads them all.
    again = bake_atlas(library, jobs=2, cache_dir=tmp_path / "cache")
    assert again.timings["cache"]["hits"] == [m.name for m in library]
    assert all(np.array_equal(a, b) for a, b in zip(serial.levels, again.levels, strict=True))


@pytest.mark.slow
def test_the_first_failing_material_s_own_error_is_raised_and_the_bakes_before_it_are_cached(tmp_path, library):
    broken = replace(library[1], params={**library[1].params, "thickness": "thick"})
    materials = [library[0], broken, *library[2:]]
    with pytest.raises(ValueError, match="'thick'"):
        load_or_bake_all(tmp_path, materials, jobs=2)
    assert cache_path(tmp_path, library[0]).is_file()
    assert not cache_path(tmp_path, broken).exists()


def test_one_job_or_one_material_to_bake_stays_in_process(tmp_path, library, monkeypatch):
    def no_pool(*args, **kwargs):
        raise AssertionError("a process pool was started")

    monkeypatch.setattr(workers, "ProcessPoolExecutor", no_pool)
    fill_cache(tmp_path, library[:1], jobs=4)
    assert fill_cache(tmp_path, library, jobs=1)["hits"] == [library[0].name]
    assert all(cache_path(tmp_path, m).is_file() for m in library)


def test_slices_given_to_the_bake_are_used_not_baked_again(library, monkeypatch):
    """A preview's completed drafts reach the atlas as they are (``bake_atlas(baked=...)``)."""
    first = bake_atlas(library[:1])
    slices = bake_cache.load_or_bake(None, library[0])[0]

    def refuse(material):
        raise AssertionError(f"{material.name} baked again")

    monkeypatch.setattr(bake_cache, "bake_material", refuse)
    given = bake_atlas(library[:1], baked={library[0].name: slices})
    assert all(np.array_equal(a, b) for a, b in zip(first.levels, given.levels, strict=True))


@pytest.mark.parametrize("kind", [FieldError, MaterialError, SceneError, ManifestError])
def test_typed_errors_cross_a_process_boundary_whole(kind):
    error = kind("materials/gold.toml", "ior", "expected a finite number >= 1, got nan")
    back = pickle.loads(pickle.dumps(error))
    assert type(back) is kind and str(back) == str(error) and back.exit_code == error.exit_code
    assert (back.path, back.field, back.expected) == (error.path, error.field, error.expected)


def test_jobs_must_be_a_positive_count(tmp_path, write_material):
    clay = write_material("clay", LIBRARY["clay"])
    res = CliRunner().invoke(app, ["bake", str(clay), "-o", str(tmp_path / "a.dds"), "-j", "0"])
    assert res.exit_code == 2 and "'-j' / '--jobs'" in res.stderr
