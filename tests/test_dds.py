"""The DDS file, checked with an independent parser and with OpenImageIO."""

import numpy as np
import pytest

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.io.dds import read_dds
from atlasgen.materials.material import read_materials
from atlasgen.optics.quantize import unorm_scale
from tests.dds_reader import linear_to_srgb, parse, srgb_to_linear


@pytest.fixture
def baked(tmp_path, write_material):
    write_material("white", 'type = "lambert"\n')
    write_material("warm", 'type = "lambert"\nid = 7\ncolour = [0.9, 0.4, 0.1]\n')

    def bake(**options):
        out = tmp_path / f"atlas-{options.get('layout', 'array')}-{options.get('linear', False)}.dds"
        result = bake_atlas(read_materials([tmp_path / "materials"]), **options)
        write_bake(result, out)
        return out, result

    return bake


def test_array_header_fields(baked):
    path, _ = baked()
    f = parse(path.read_bytes())
    h, d = f["header"], f["dx10"]
    assert h["dwSize"] == 124
    assert h["dwFlags"] == 0x1 | 0x2 | 0x4 | 0x8 | 0x1000 | 0x20000
    assert (h["dwWidth"], h["dwHeight"], h["dwDepth"], h["dwMipMapCount"]) == (64, 32, 0, 7)
    assert h["dwPitchOrLinearSize"] == 64 * 4
    assert h["pf_dwSize"] == 32 and h["pf_dwFlags"] == 0x4 and h["pf_dwFourCC"] == b"DX10"
    assert h["dwCaps"] == 0x1000 | 0x8 | 0x400000 and h["dwCaps2"] == 0
    assert d == {"dxgiFormat": 29, "resourceDimension": 3, "miscFlag": 0, "arraySize": 256, "miscFlags2": 4}
    assert f["consumed"] == f["size"] == 148 + 2_796_544


def test_linear_flag_selects_dxgi_28(baked):
    path, _ = baked(linear=True)
    assert parse(path.read_bytes())["dx10"]["dxgiFormat"] == 28


def test_volume_header_fields(baked):
    path, result = baked(layout="volume")
    f = parse(path.read_bytes())
    h, d = f["header"], f["dx10"]
    assert h["dwFlags"] & 0x800000 and h["dwCaps2"] == 0x200000 and h["dwCaps"] & 0x8
    assert (h["dwDepth"], h["dwMipMapCount"]) == (256, 9)
    assert d["resourceDimension"] == 4 and d["arraySize"] == 1
    assert f["consumed"] == f["size"] == 148 + 2_396_764
    assert [lv.shape[0] for lv in f["levels"]] == [256 >> k for k in range(9)]
    assert len(result.manifest.volume_bleed) == 8
    # Level 1 averages slices 6 and 7: the warm material bleeds into its empty neighbour's texel.
    assert result.manifest.volume_bleed[0].max > 0.1
    assert any("volume layout" in w for w in result.warnings)


def test_data_order_is_element_major(baked):
    """Slice 7 (warm, explicit id) holds its colour at level 0 and only there in the array."""
    path, _ = baked()
    f = parse(path.read_bytes())
    lv0 = f["levels"][0]
    facing = lv0[:, 31, 63, :3]  # N.V = 1, N.L = 1
    # Stored over the slice's peak (its scale, 0.9): the colour's largest channel takes code 255.
    assert np.all(facing[7] == np.rint(linear_to_srgb(np.array([0.9, 0.4, 0.1]) / unorm_scale(0.9)) * 255))
    assert np.all(facing[0] == 255)
    used = {0, 7}
    assert not any(facing[s].any() for s in range(256) if s not in used)
    # The library reader agrees with the independent one, level by level.
    mine = read_dds(path)
    for a, b in zip(mine.levels, f["levels"]):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("linear", [False, True])
@pytest.mark.slow
def test_each_mip_is_the_linear_box_filter_of_the_level_above(baked, linear):
    path, _ = baked(linear=linear)
    levels = parse(path.read_bytes())["levels"]
    assert [lv.shape[1:3] for lv in levels] == [(32, 64), (16, 32), (8, 16), (4, 8), (2, 4), (1, 2), (1, 1)]

    def to_linear(lv):
        x = lv.astype(np.float64) / 255
        if not linear:
            x[..., :3] = srgb_to_linear(x[..., :3])
        return x

    def to_code(x):
        x = x.copy()
        if not linear:
            x[..., :3] = linear_to_srgb(x[..., :3])
        return x * 255

    for upper, lower in zip(levels, levels[1:]):
        x = to_linear(upper)
        h2, w2 = lower.shape[1:3]
        x = x.reshape(x.shape[0], h2, x.shape[1] // h2, w2, x.shape[2] // w2, 4).mean(axis=(2, 4))
        assert np.abs(to_code(x) - lower).max() <= 1.0


def test_openimageio_accepts_the_header(baked):
    oiio = pytest.importorskip("OpenImageIO")
    for options in ({}, {"layout": "volume"}):
        path, _ = baked(**options)
        inp = oiio.ImageInput.open(str(path))
        assert inp is not None, oiio.geterror()
        spec = inp.spec()
        assert (spec.width, spec.height, spec.nchannels) == (64, 32, 4)
        if options:
            assert spec.depth == 256
        inp.close()
