"""Binary inputs are untrusted: a DDS header is checked against the file before anything
is allocated, and a damaged cache entry is baked again with a warning."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from atlasgen.bake.cache import cache_key, cache_path, load_cached
from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.bake.workers import fill_cache
from atlasgen.errors import InputError
from atlasgen.io.dds import read_dds
from atlasgen.materials.material import read_materials

#: Byte offsets of the DDS header fields (after the 4-byte magic; DirectXTex DDS.h).
FIELDS = {"flags": 8, "height": 12, "width": 16, "depth": 24, "mipMapCount": 28, "ddspf.size": 76, "ddspf.flags": 80, "caps2": 112,
          "resourceDimension": 132, "miscFlag": 136, "arraySize": 140, "miscFlags2": 144}  # fmt: skip


@pytest.fixture(scope="module")
def atlases(tmp_path_factory):
    """A baked array atlas and a volume one, as bytes."""
    root = tmp_path_factory.mktemp("atlases")
    (root / "clay.toml").write_text('type = "lambert"\n')
    materials = read_materials([root / "clay.toml"])
    out = {}
    for layout in ("array", "volume"):
        write_bake(bake_atlas(materials, layout), root / f"{layout}.dds")
        out[layout] = (root / f"{layout}.dds").read_bytes()
    return out


def _patched(data: bytes, field: str, value: int) -> bytes:
    out = bytearray(data)
    struct.pack_into("<I", out, FIELDS[field], value)
    return bytes(out)


CASES = [
    ("array", "mipMapCount", 0xFFFFFFFF, "header field mipMapCount is 4294967295; expected at most 7"),
    ("array", "mipMapCount", 8, "header field mipMapCount is 8; expected at most 7 for 64x32"),
    ("array", "width", 0, "header field width is 0; expected at least 1"),
    ("array", "height", 0, "header field height is 0"),
    ("array", "arraySize", 0, "header field arraySize is 0"),
    ("array", "width", 0xFFFFFFFF, "header fields width, height, arraySize and mipMapCount describe"),
    ("array", "height", 0x7FFFFFFF, "header fields width, height, arraySize and mipMapCount describe"),
    ("array", "arraySize", 0xFFFFFFFF, "describe 4"),
    ("volume", "depth", 0xFFFFFFFF, "header fields width, height, depth and mipMapCount describe"),
    ("volume", "depth", 0, "header field depth is 0"),
    ("volume", "mipMapCount", 0xFFFFFFFF, "expected at most 9 for 64x32x256"),
    # Another kind of texture than the one the reader returned, to DirectXTex (a cube map, a 1D texture):
    # each was read as the 2D array, exit 0.
    ("array", "resourceDimension", 2, "header field resourceDimension is 2; expected 3 (a 2D array) or 4 (a volume)"),
    ("array", "miscFlag", 0x4, "header field miscFlag is 0x4; expected no TEXTURECUBE bit"),
    ("array", "resourceDimension", 4, "header field flags is 0x2100f; expected the DDSD_DEPTH bit (0x800000) in a volume"),
    ("volume", "flags", 0x2100F, "header field flags is 0x2100f; expected the DDSD_DEPTH bit (0x800000)"),
    ("volume", "arraySize", 2, "header field arraySize is 2; expected 1 in a volume"),
    ("array", "miscFlags2", 7, "header field miscFlags2 is 0x7; expected an alpha mode of 0 to 4 in its low bits"),
    # DirectXTex refuses the first, and without the second reads no DX10 header: each was read, exit 0.
    ("array", "ddspf.size", 0, "header field ddspf.size is 0; expected 32"),
    ("volume", "ddspf.flags", 0xFB, "header field ddspf.flags is 0xfb; expected the DDPF_FOURCC bit (0x4)"),
]


@pytest.mark.parametrize("layout,field,value,expected", CASES)
def test_every_dds_size_field_is_checked_before_allocating(tmp_path, atlases, layout, field, value, expected):
    path = tmp_path / "bad.dds"
    path.write_bytes(_patched(atlases[layout], field, value))
    with pytest.raises(InputError) as info:
        read_dds(path)
    message = str(info.value)
    assert message.startswith(f"{path.as_posix()}: ") and expected in message and "\n" not in message


@pytest.mark.parametrize(("layout", "caps2"), [("array", 0x200000), ("volume", 0)])
def test_caps2_is_ignored_as_directxtex_ignores_it_in_a_dx10_header(tmp_path, atlases, layout, caps2):
    """The resource dimension (with DDSD_DEPTH) says what the texture is; a VOLUME cap, set or clear, changes nothing."""
    path = tmp_path / "caps2.dds"
    path.write_bytes(_patched(atlases[layout], "caps2", caps2))
    assert read_dds(path).layout == layout


def test_a_huge_mip_count_fails_at_once_under_a_memory_limit(tmp_path, atlases):
    """``atlasgen info`` on a 0xFFFFFFFF mip count, in a process allowed 2 GiB more than it
    starts with: any allocation sized by the header would end in MemoryError (exit 1)."""
    path = tmp_path / "bad.dds"
    path.write_bytes(_patched(atlases["array"], "mipMapCount", 0xFFFFFFFF))
    code = (
        "import resource, sys\n"
        "from atlasgen.cli.main import main\n"
        "used = int(open('/proc/self/statm').read().split()[0]) * resource.getpagesize()\n"
        "resource.setrlimit(resource.RLIMIT_AS, (used + (2 << 30), resource.RLIM_INFINITY))\n"
        f"main(['info', {str(path)!r}])\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 3, result.stderr
    assert result.stderr.strip().endswith("header field mipMapCount is 4294967295; expected at most 7 for 64x32")


@pytest.mark.parametrize("length", [148, 149, 1000, -1])
def test_a_truncated_dds_names_its_length(tmp_path, atlases, length):
    path = tmp_path / "short.dds"
    path.write_bytes(atlases["array"][:length])
    with pytest.raises(InputError, match=r"describe \d+ bytes, the file has"):
        read_dds(path)


def _forged(values: np.ndarray, meta: dict) -> dict:
    """Entries edited and given the digest of their new contents (which finds damage, not a forgery): each
    failed the bake (a fit record of 5: exit 1), wrote invalid JSON (NaN seconds in X.timings.json) or
    baked five slices for a one-slice lambert."""
    import io

    from atlasgen.bake.cache import _entry_digest

    def signed(values, **changes) -> bytes:
        edited = {**meta, **changes}
        edited["digest"] = _entry_digest(values, edited)
        buffer = io.BytesIO()
        np.savez(buffer, values=values, meta=np.array(json.dumps(edited)))
        return buffer.getvalue()

    return {
        "forged: more slices": signed(np.repeat(values, 5, axis=0)),
        "forged: seconds as text": signed(values, timings={**meta["timings"], "bake_s": "abc"}),
        "forged: NaN seconds": signed(values, timings={**meta["timings"], "bake_s": float("nan")}),
        "forged: a fit record of 5": signed(values, extra={**meta["extra"], "fit": 5}),
        # The bake judged the fit's error as a float (exit 1), and wrote a NaN one into the manifest, which no reader
        # then read.
        "forged: a fit error as text": signed(values, extra={**meta["extra"], "fit": {"relative_rms": "bad"}}),
        "forged: a NaN fit error": signed(values, extra={**meta["extra"], "fit": {"relative_rms": float("nan")}}),
        "forged: NaN deep in the metadata": signed(values, extra={**meta["extra"], "notes": [{"x": float("inf")}]}),
    }


def _damaged(data: bytes, key: str) -> dict:
    """Ways a cache entry breaks: truncation, garbage, another file type, wrong contents, contents edited
    in a whole archive."""
    import io

    wrong_shape = io.BytesIO()
    meta = json.dumps({"key": key, "extra": {}, "timings": {}})
    np.savez(wrong_shape, values=np.zeros((1, 2, 2, 4)), meta=np.array(meta))
    npy = io.BytesIO()
    np.save(npy, np.zeros(3))
    beyond_float32 = io.BytesIO()  # no bake writes these: it refuses a material whose slice scale float32 cannot hold
    np.savez(beyond_float32, values=np.full((1, 32, 64, 4), 1e300), meta=np.array(meta))
    with np.load(io.BytesIO(data)) as good:
        values, good_meta = np.array(good["values"]), json.loads(str(good["meta"]))
    edited = io.BytesIO()  # an extra of another model: the manifest blamed the material file for it
    np.savez(edited, values=values, meta=np.array(json.dumps({**good_meta, "extra": {"representation": "x"}})))
    repeated = io.BytesIO()  # five slices for a one-slice lambert were baked into the atlas as they were
    np.savez(repeated, values=np.repeat(values, 5, axis=0), meta=np.array(json.dumps(good_meta)))
    return {
        **_forged(values, good_meta),
        "another extra": edited.getvalue(),
        "more slices": repeated.getvalue(),
        "truncated": data[: len(data) // 2],
        "empty": b"",
        "garbage": b"PK\x03\x04" + b"\xff" * 100,
        "npy": npy.getvalue(),
        "wrong shape": wrong_shape.getvalue(),
        "beyond float32": beyond_float32.getvalue(),
        "too many slices": _too_many_slices(key),
    }


@pytest.mark.parametrize(("field", "value"), [("parametrization", "bogus"), ("target", ["f_cos"])])
def test_a_forged_separable_entry_naming_no_parametrization_is_baked_again(tmp_path, write_material, field, value):
    """The separable model's own check of a cache entry (Model.check_cached): a parametrization of 'bogus' given a
    digest of its own ended the bake in an internal KeyError, where the rebuild looked it up."""
    import io

    from atlasgen.bake.cache import _entry_digest

    write_material("g", 'type = "separable"\nsource = "ggx"\nalpha = 0.3\n')
    materials = read_materials([tmp_path / "materials"])
    cache = tmp_path / "cache"
    reference = bake_atlas(materials, cache_dir=cache)
    entry = cache_path(cache, materials[0])
    with np.load(entry) as data:
        values, meta = np.array(data["values"]), json.loads(str(data["meta"]))
    assert meta["extra"][field] != value
    meta["extra"][field] = value
    meta["digest"] = _entry_digest(values, meta)
    buffer = io.BytesIO()
    np.savez(buffer, values=values, meta=np.array(json.dumps(meta)))
    entry.write_bytes(buffer.getvalue())
    result = bake_atlas(materials, cache_dir=cache)
    assert result.timings["cache"]["baked"] == ["g"]
    assert any(w.startswith(f"{entry.as_posix()}: unreadable cache entry (a {field} of ") for w in result.warnings)
    assert all(np.array_equal(x, y) for x, y in zip(result.levels, reference.levels))


def _too_many_slices(key: str, slices: int = 4000) -> bytes:
    """A small compressed entry whose values inflate to 4000 slices, 524 MB, where an atlas holds 256."""
    import io

    buffer = io.BytesIO()
    meta = json.dumps({"key": key, "extra": {}, "timings": {}})
    np.savez_compressed(buffer, values=np.zeros((slices, 32, 64, 4)), meta=np.array(meta))
    return buffer.getvalue()


def test_a_cache_entry_of_more_slices_than_an_atlas_holds_is_refused_before_it_is_inflated(tmp_path, write_material):
    """A 2.5 MB entry declaring 40000 slices took 2.6 GB of memory to load; the header says so first."""
    import tracemalloc

    write_material("a", 'type = "lambert"\n')
    material = read_materials([tmp_path / "materials"])[0]
    entry = cache_path(tmp_path / "cache", material)
    entry.parent.mkdir()
    entry.write_bytes(_too_many_slices(cache_key(material)))
    warnings = []
    tracemalloc.start()
    try:
        assert load_cached(tmp_path / "cache", material, warnings) is None
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 5_000_000 and warnings[0].endswith("(slices of shape (4000, 32, 64, 4) float64); "
                                                    "baking material 'a' again")  # fmt: skip


@pytest.mark.slow
def test_a_damaged_cache_entry_is_baked_again_with_a_warning(tmp_path, write_material):
    write_material("a", 'type = "lambert"\ncolour = [0.2, 0.4, 0.6]\n')
    materials = read_materials([tmp_path / "materials"])
    cache = tmp_path / "cache"
    reference = bake_atlas(materials, cache_dir=cache)
    entry = cache_path(cache, materials[0])
    good = entry.read_bytes()
    for name, data in _damaged(good, cache_key(materials[0])).items():
        entry.write_bytes(data)
        warnings = []
        assert load_cached(cache, materials[0], warnings) is None, name
        assert len(warnings) == 1 and warnings[0].startswith(f"{entry.as_posix()}: unreadable cache entry"), name
        result = bake_atlas(materials, cache_dir=cache)
        assert result.timings["cache"]["baked"] == ["a"], name
        assert any("unreadable cache entry" in w for w in result.warnings), name
        assert all(np.array_equal(x, y) for x, y in zip(result.levels, reference.levels)), name
        # The entry was replaced by a good one: the next bake loads it, silently.
        assert load_cached(cache, materials[0], warnings) is not None and len(warnings) == 1, name
    entry.write_bytes(good[:100])
    filled = fill_cache(cache, materials)
    assert filled["baked"] == ["a"] and len(filled["warnings"]) == 1
    with zipfile.ZipFile(entry) as archive:  # a whole .npz again
        assert sorted(archive.namelist()) == ["meta.npy", "values.npy"]


def _nested_twosided(levels: int) -> str:
    table = '{ type = "diffuse" }'
    for _ in range(levels):
        table = f'{{ type = "twosided", bsdf = {table} }}'
    return f'type = "bsdf"\nbsdf = {table}\n'


@pytest.mark.parametrize("levels,field", [(60, "bsdf" + ".bsdf" * 9), (9, "bsdf" + ".bsdf" * 9)])
def test_a_deeply_nested_bsdf_table_is_refused_naming_the_field(tmp_path, levels, field):
    """Issue 24: 60 nested ``twosided`` plugins (2 KB) grew to 3.9 GB in Mitsuba; the table's
    depth is refused when the file is read, before Mitsuba sees it."""
    from atlasgen.errors import MaterialError

    path = tmp_path / "deep.toml"
    path.write_text(_nested_twosided(levels))
    assert path.stat().st_size < 2100
    with pytest.raises(MaterialError) as refused:
        read_materials([path])
    assert str(refused.value) == f"{path.as_posix()}: field '{field}': expected tables nested at most 8 deep under 'bsdf'"


def test_a_bsdf_table_at_the_depth_bound_is_read(tmp_path):
    from atlasgen.io.fields import check_table_bounds

    table = {"type": "diffuse"}
    for _ in range(8):
        table = {"type": "twosided", "bsdf": table}
    check_table_bounds(table, tmp_path / "m.toml", "bsdf")  # eight nested tables: at the bound


def test_a_huge_bsdf_table_is_refused_naming_the_field(tmp_path):
    from atlasgen.errors import MaterialError

    path = tmp_path / "wide.toml"
    path.write_text('type = "bsdf"\nbsdf = { type = "diffuse", reflectance = [' + ", ".join(["0.5"] * 300) + "] }\n")
    with pytest.raises(MaterialError, match=r"field 'bsdf\.reflectance\[254\]': expected a table of at most 256 keys"):
        read_materials([path])
