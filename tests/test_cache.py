"""The per-material cache: only what changed is re-baked."""

import numpy as np
import pytest

from atlasgen.bake.cache import cache_path, load_cached
from atlasgen.bake.pipeline import bake_atlas
from atlasgen.materials.material import read_materials


def test_only_the_changed_material_is_rebaked(tmp_path, write_material):
    folder, cache = tmp_path / "materials", tmp_path / "cache"
    for name in ("a", "b", "c"):
        write_material(name, f'type = "lambert"\ncolour = [0.{ord(name) % 10}, 0.5, 0.5]\n')
    first = bake_atlas(read_materials([folder]), cache_dir=cache)
    assert sorted(first.timings["cache"]["baked"]) == ["a", "b", "c"]

    again = bake_atlas(read_materials([folder]), cache_dir=cache)
    assert again.timings["cache"] == {"hits": ["a", "b", "c"], "baked": []}
    # A hit still reports what the bake cost when it ran, not the time to load it.
    for name in "abc":
        assert again.timings["materials"][name]["bake_s"] == first.timings["materials"][name]["bake_s"]
        assert "loaded_from_cache_s" in again.timings["materials"][name]
    assert all(np.array_equal(x, y) for x, y in zip(first.levels, again.levels))

    write_material("b", 'type = "lambert"\ncolour = [0.9, 0.1, 0.1]\n')
    changed = bake_atlas(read_materials([folder]), cache_dir=cache)
    assert changed.timings["cache"]["baked"] == ["b"]
    assert changed.timings["cache"]["hits"] == ["a", "c"]
    facing = changed.levels[0][:, 31, 63, :3]
    assert facing[1].tolist() != first.levels[0][1, 31, 63, :3].tolist()


def test_a_stale_or_corrupt_cache_entry_is_rebaked(tmp_path, write_material):
    write_material("a", 'type = "lambert"\n')
    materials = read_materials([tmp_path / "materials"])
    bake_atlas(materials, cache_dir=tmp_path / "cache")
    cache_path(tmp_path / "cache", materials[0]).write_bytes(b"garbage")
    assert load_cached(tmp_path / "cache", materials[0]) is None
    assert bake_atlas(materials, cache_dir=tmp_path / "cache").timings["cache"]["baked"] == ["a"]


@pytest.mark.slow
def test_a_bake_from_the_cache_writes_the_bytes_of_a_bake_without_it(tmp_path, write_material):
    """Whole-library tests (the goldens, the containers, the installed wheel) assemble from a
    session's cache: every output of a cached bake must be the uncached bake's, byte for byte."""
    from atlasgen.bake.pipeline import write_bake

    write_material("clay", 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n')
    write_material("gloss", 'type = "fresnel"\n')
    write_material("lobe", 'type = "separable"\nsource = "blinn_phong"\nexponent = 8.0\nterms = 2\n')
    materials = read_materials([tmp_path / "materials"])
    write_bake(bake_atlas(materials), tmp_path / "plain" / "a.dds")
    bake_atlas(materials, cache_dir=tmp_path / "cache")  # fills the cache
    cached = bake_atlas(materials, cache_dir=tmp_path / "cache")
    assert sorted(cached.timings["cache"]["hits"]) == ["clay", "gloss", "lobe"]
    write_bake(cached, tmp_path / "cached" / "a.dds")
    for suffix in (".dds", ".json", ".wgsl", ".glsl", ".hlsl", ".separable.bin"):
        plain, again = (tmp_path / d / f"a{suffix}" for d in ("plain", "cached"))
        assert plain.read_bytes() == again.read_bytes(), suffix


def test_a_document_s_materials_get_one_cache_entry_each(tmp_path):
    from atlasgen.materials.material import Material

    def material(name, source):
        return Material(name=name, type="lambert", params={}, source=source, content_hash=name)

    assert cache_path(tmp_path, material("a", "materials/a.toml")) == tmp_path / "a.npz"
    assert cache_path(tmp_path, material("Gold", "materials/lib.mtlx")) == tmp_path / "lib.mtlx" / "Gold.npz"
    assert cache_path(tmp_path, material("Car", "materials/lib.mtlx")) == tmp_path / "lib.mtlx" / "Car.npz"
    # A TOML file named as a document's material once shared its entry: each re-baked the other on every bake.
    assert cache_path(tmp_path, material("lib.Gold", "materials/lib.Gold.toml")) != cache_path(
        tmp_path, material("Gold", "materials/lib.mtlx")
    )


@pytest.mark.slow
def test_editing_one_material_of_a_document_rebakes_that_one(tmp_path):
    """A document's materials are keyed by their own values (materialx_document.material_digest), not
    by the document's bytes: editing one input of one material re-bakes it alone (a 36-material
    library took a minute to re-bake for a one-number edit), and the other keeps its bytes."""
    pytest.importorskip("MaterialX")

    def document(roughness: str):
        path = tmp_path / "lib.mtlx"
        path.write_text('<?xml version="1.0"?>\n<materialx version="1.39">\n' + "".join(
            f'<standard_surface name="SR_{name}" type="surfaceshader">'
            f'<input name="base_color" type="color3" value="{colour}" /><input name="specular" type="float" value="0" />'
            f'<input name="specular_roughness" type="float" value="{r}" /></standard_surface>'
            f'<surfacematerial name="{name}" type="material">'
            f'<input name="surfaceshader" type="surfaceshader" nodename="SR_{name}" /></surfacematerial>\n'
            for name, colour, r in (("Clay", "0.6, 0.4, 0.3", "0.5"), ("Paint", "0.1, 0.2, 0.6", roughness))
        ) + "</materialx>\n")  # fmt: skip
        return path

    cache = tmp_path / "cache"
    first = bake_atlas(read_materials([document("0.5")]), cache_dir=cache)
    assert sorted(first.timings["cache"]["baked"]) == ["Clay", "Paint"]
    edited = bake_atlas(read_materials([document("0.3")]), cache_dir=cache)
    assert edited.timings["cache"] == {"hits": ["Clay"], "baked": ["Paint"]}
    assert np.array_equal(first.levels[0][0], edited.levels[0][0])
