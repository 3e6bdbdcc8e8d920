"""Stable slice allocation."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.bake.slots import assign_slices
from atlasgen.errors import MaterialError


def req(name, count=1, explicit=None):
    return (name, count, explicit, f"{name}.toml")


def test_explicit_then_previous_then_lowest_free():
    slots = assign_slices([req("a"), req("b", explicit=0), req("c", 2), req("d")], previous={"d": 5})
    assert slots == {"b": 0, "d": 5, "a": 1, "c": 2}


def test_a_material_that_grew_into_the_next_one_s_slices_moves_not_the_next_one():
    """A MaterialX velvet of 7 slices (25..31) grew to 8: it took red-plastic's slice 32, red-plastic moved to 51,
    and scene atlases baked with red-plastic at 32 went stale, though red-plastic had not changed."""
    previous = {"a": 0, "mx_velvet": 25, "red-plastic": 32, "z": 33}
    slots = assign_slices([req("a"), req("mx_velvet", 8), req("red-plastic"), req("z", 2)], previous)
    assert slots == {"a": 0, "red-plastic": 32, "z": 33, "mx_velvet": 1}  # the lowest free run of 8
    # Shrunk, or grown into free slices, it stays.
    assert assign_slices([req("a"), req("mx_velvet", 6), req("red-plastic"), req("z")], previous)["mx_velvet"] == 25
    assert assign_slices([req("mx_velvet", 10)], previous)["mx_velvet"] == 25


def test_an_ids_from_manifest_wins_over_the_previous_one_whatever_the_names():
    """The previous manifest's 'grey' at 0 came before the library's 'terracotta' at 0 by name: terracotta moved to 1,
    and the same bake into an empty folder gave other bytes. 'zz' in grey's place yielded, as all now do."""
    library = ("lib/atlas.json", {"terracotta": 0, "toon": 1})
    for name in ("grey", "zz"):
        slots = assign_slices([req(name), req("terracotta")], previous={name: 0}, pinned=library)
        assert slots == {"terracotta": 0, name: 2}  # not toon's 1 either (below)
    # A run the previous manifest gives that reaches into the library's slice moves too.
    assert assign_slices([req("aa", 3), req("toon")], previous={"aa": 0}, pinned=library) == {"toon": 1, "aa": 2}


def test_a_material_the_ids_from_manifest_lacks_takes_none_of_its_ids():
    """A hostile sweep: glazed-ceramic, which the library lacks, took the library's red-plastic's ID 0 in a scene atlas
    baked --ids-from it, so one g-buffer ID meant two materials across the atlases. It takes the lowest ID the library
    does not give (an earlier one of the scene atlas moving off a library ID too), and a library ID only where the
    atlas has no other slice left."""
    library = ("lib/atlas.json", {"red-plastic": 0, "toon": 1, "gold": 3})
    assert assign_slices([req("glazed"), req("toon")], pinned=library) == {"toon": 1, "glazed": 2}
    assert assign_slices([req("glazed", 2), req("toon")], pinned=library) == {"toon": 1, "glazed": 4}
    assert assign_slices([req("glazed"), req("toon")], previous={"glazed": 0}, pinned=library)["glazed"] == 2
    assert assign_slices([req("glazed")], previous={"glazed": 7}, pinned=library)["glazed"] == 7
    full = ("lib/atlas.json", {f"m{i}": i for i in range(256)})
    assert assign_slices([req("glazed"), req("m5")], pinned=full) == {"m5": 5, "glazed": 0}
    assert assign_slices([req("glazed")]) == {"glazed": 0}  # no --ids-from: nothing is reserved


def test_an_ids_from_slice_the_atlas_cannot_give_is_refused():
    library = ("lib/atlas.json", {"terracotta": 0, "sharp": 254})
    with pytest.raises(MaterialError, match=r"terracotta.toml: material 'terracotta' needs slice 0 where --ids-from "
                                            r"lib/atlas.json puts it, and slice 0 holds 'grey'"):  # fmt: skip
        assign_slices([req("grey", explicit=0), req("terracotta")], pinned=library)
    with pytest.raises(MaterialError, match=r"material 'sharp' needs slices 254..257 where --ids-from lib/atlas.json "
                                            r"puts it, beyond the atlas's 256"):  # fmt: skip
        assign_slices([req("sharp", 4)], pinned=library)


def test_overlapping_explicit_ids_conflict():
    with pytest.raises(MaterialError, match="y.toml: field 'id'.*conflicts with material 'x'"):
        assign_slices([req("x", 3, explicit=10), req("y", explicit=12)])


def test_more_slices_than_layers():
    with pytest.raises(MaterialError, match="need 257 slices; expected at most 256"):
        assign_slices([req(f"m{i}") for i in range(257)])


def test_no_gap_large_enough():
    with pytest.raises(MaterialError, match="consecutive free slices"):
        assign_slices([req("a", explicit=1), req("b", 255)])


@given(st.lists(st.integers(1, 4), min_size=1, max_size=40), st.randoms(use_true_random=False))
@pytest.mark.slow
def test_allocation_never_overlaps_and_respects_previous(counts, rnd):
    names = [f"m{i}" for i in range(len(counts))]
    first = assign_slices([req(n, c) for n, c in zip(names, counts)])
    used = [s for n, c in zip(names, counts) for s in range(first[n], first[n] + c)]
    assert len(used) == len(set(used)) and max(used) < 256
    keep = rnd.sample(names, k=len(names) // 2)
    again = assign_slices(
        [req(n, c) for n, c in zip(names, counts) if n in keep] + [req("new", 2)], previous={n: first[n] for n in names}
    )
    assert all(again[n] == first[n] for n in keep)


@given(st.lists(st.tuples(st.integers(1, 4), st.one_of(st.none(), st.integers(0, 250))), min_size=1, max_size=30),
       st.randoms(use_true_random=False))  # fmt: skip
@pytest.mark.slow
def test_slices_do_not_depend_on_the_order_materials_are_given(specs, rnd):
    requests, taken = [], set()
    for i, (count, explicit) in enumerate(specs):
        span = set(range(explicit, explicit + count)) if explicit is not None else set()
        if explicit is not None and (span & taken or explicit + count > 256):
            explicit, span = None, set()
        taken |= span
        requests.append(req(f"m{i:02d}", count, explicit))
    shuffled = rnd.sample(requests, k=len(requests))
    assert assign_slices(shuffled) == assign_slices(requests)
    previous = {name: slot for name, slot in assign_slices(requests).items() if rnd.random() < 0.5}
    fewer = [r for r in requests if r != shuffled[0]] + [req("new", 3)]  # one gone, one added
    assert assign_slices(rnd.sample(fewer, k=len(fewer)), previous) == assign_slices(fewer, previous)


def test_a_bake_is_the_same_whatever_the_argument_order(tmp_path, write_material):
    from click.testing import CliRunner

    from atlasgen.cli.main import app

    paths = [str(write_material(name, 'type = "lambert"\n')) for name in ("zinc", "amber", "moss")]
    outputs = []
    for order, args in (("given", paths), ("reversed", paths[::-1])):
        out = tmp_path / order / "atlas.dds"
        assert CliRunner().invoke(app, ["bake", *args, "-o", str(out), "-q"]).exit_code == 0
        outputs.append([out.read_bytes(), out.with_suffix(".json").read_bytes(), out.with_suffix(".wgsl").read_bytes()])
    assert outputs[0] == outputs[1]
    assert b'"name": "amber", "id": 0' in outputs[0][1]
