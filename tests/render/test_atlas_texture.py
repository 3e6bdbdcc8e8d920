"""Reading a baked atlas for the renderer: DDS, manifest and include must all be there."""

from __future__ import annotations

import numpy as np
import pytest

from atlasgen.bake.pipeline import bake_atlas, write_bake
from atlasgen.errors import InputError
from atlasgen.materials.material import read_materials
from atlasgen.optics.quantize import unorm_scale
from atlasgen.optics.srgb import decode_srgb
from atlasgen.render.atlas_texture import RenderAtlas, read_render_atlas


@pytest.fixture
def baked(tmp_path, write_material):
    write_material("white", 'type = "lambert"\n')
    write_material("warm", 'type = "lambert"\nid = 7\ncolour = [0.9, 0.4, 0.1]\n')

    def bake(layout="array"):
        out = tmp_path / f"atlas-{layout}.dds"
        write_bake(bake_atlas(read_materials([tmp_path / "materials"]), layout=layout), out)
        return out

    return bake


def test_reads_levels_manifest_and_include(baked):
    atlas = read_render_atlas(baked())
    assert atlas.srgb and len(atlas.levels) == 7
    assert atlas.levels[0].shape == (256, 32, 64, 4) and atlas.levels[6].shape == (256, 1, 1, 4)
    assert atlas.material_names == ["warm", "white"]
    assert "fn atlas_sample(" in atlas.include and "MATERIAL_WARM: u32 = 7u" in atlas.include
    # Slice 7 holds the warm colour's cosine ramp over its peak (the slice's scale), sRGB-encoded:
    # at N.L = 1, times the scale, it is the colour.
    scale = atlas.manifest.entry_named("warm").scale[0][0]
    assert scale == unorm_scale(0.9)
    np.testing.assert_allclose(decode_srgb(atlas.levels[0][7, -1, -1, :3] / 255) * scale, [0.9, 0.4, 0.1], atol=4e-3)


def test_missing_pieces(baked):
    path = baked()
    path.with_suffix(".wgsl").unlink()
    with pytest.raises(InputError, match="no shader include"):
        read_render_atlas(path)
    path.with_suffix(".json").unlink()
    with pytest.raises(InputError, match="no manifest"):
        read_render_atlas(path)
    with pytest.raises(InputError, match="no such atlas"):
        read_render_atlas(path.with_name("other.dds"))


def test_volume_atlas_is_refused(baked):
    with pytest.raises(InputError, match="2D-array atlas"):
        read_render_atlas(baked("volume"))


def test_levels_must_be_uint8_rgba():
    with pytest.raises(InputError, match="uint8"):
        RenderAtlas([np.zeros((1, 2, 2, 4), dtype=np.float32)], True, {}, "")


#: One separable term's factor tables: what a one-slice entry needs to be read as separable.
ONE_TERM = {"factor_scale": [[[1.0, 1.0, 1.0], [1.0, 1.0, 1.0]]], "factor_bias": [[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]]}


@pytest.mark.parametrize(("edit", "field", "expected"), [
    ({"type": "nosuchmodel"}, "materials[0].type", "expected one of the models atlasgen knows ("),
    # A LUT model's entry is one slice without bias: a bias of 1e30 saturated every pixel, two slices were shown.
    ({"bias": [[1e30, -5.0]]}, "materials[0].bias", "expected [[0.0, 0.0]] (a lambert slice has no bias), got "
                                                    "[[1e+30, -5.0]]"),
    ({"slice_count": 2, "scale": [[1.0, 1.0]] * 2, "bias": [[0.0, 0.0]] * 2}, "materials[0].slice_count",
     "expected 1 (a lambert material is one slice), got 2"),
    ({"type": "separable"}, "materials[0].factor_scale", "missing; expected a separable entry's factors"),
    # Names the rebuild looks up (a KeyError and a ValueError, exit 1, before).
    ({"type": "separable", "parametrization": "polar", **ONE_TERM}, "materials[0].parametrization",
     "expected one of half_diff, half_diff_sqrt_h, "),
    ({"type": "separable", "parametrization": "half_diff", "target": "nope", **ONE_TERM}, "materials[0].target",
     "expected one of f_cos, f_proxy, got 'nope'"),
    # A closed form below the model's own bound: its shader code divides by alpha^4, which float32 rounds to 0.
    ({"type": "separable", "representation": {"kind": "analytic", "distribution": "ggx", "alpha": 1e-20, "fresnel": "none",
      "f0": [1, 1, 1], "ior": 1.5, "specular": [1, 1, 1], "diffuse": [0, 0, 0]}},
     "materials[0].representation.alpha", "expected a finite number >= 1e-06 and <= 4, got 1e-20"),
    # Names the lighting shader's switch codes look up (a hostile sweep's KeyError, exit 1, where info passed them).
    ({"type": "separable", "representation": {"kind": "analytic", "distribution": "GGX", "alpha": 0.5, "fresnel": "none",
      "f0": [1, 1, 1], "ior": 1.5, "specular": [1, 1, 1], "diffuse": [0, 0, 0]}},
     "materials[0].representation.distribution", "expected one of ggx, beckmann, lambert, got 'GGX'"),
    ({"type": "separable", "representation": {"kind": "analytic", "distribution": "ggx", "alpha": 0.5, "fresnel": "bogus",
      "f0": [1, 1, 1], "ior": 1.5, "specular": [1, 1, 1], "diffuse": [0, 0, 0]}},
     "materials[0].representation.fresnel", "expected one of schlick, exact, none, got 'bogus'"),
    # A path's NUL ended info -v's lookup of the material file in an internal error.
    ({"source": "a\u0000b.toml"}, "materials[0].source", "expected a material file's path (no NUL character)"),
])  # fmt: skip
def test_an_entry_its_model_cannot_shade_is_refused_naming_the_field(baked, edit, field, expected):
    """The renderer generates its include from the manifest: an edited type reached get_model (KeyError, exit 1)
    or the shader compiler. The include's hash line is rewritten, as a careful hand edit would."""
    import hashlib
    import json

    from atlasgen.errors import ManifestError
    from atlasgen.io.atlas import INCLUDE_HASH_PREFIX

    path = baked()
    manifest = path.with_suffix(".json")
    data = json.loads(manifest.read_text())
    data["materials"][0].update(edit)
    text = json.dumps(data)
    manifest.unlink()  # a link into the bake's output set: replaced, not written through
    manifest.write_text(text)
    include = path.with_suffix(".wgsl")
    lines = include.read_text().split("\n")
    body = "\n".join([INCLUDE_HASH_PREFIX + hashlib.sha256(text.encode()).hexdigest(), *lines[1:]])
    include.unlink()
    include.write_text(body)
    with pytest.raises(ManifestError) as info:
        read_render_atlas(path)
    assert str(info.value).startswith(f"{manifest.as_posix()}: field '{field}': {expected}"), str(info.value)


def test_an_include_over_its_limit_is_refused_unread(baked, monkeypatch):
    """A 3 GB include was read whole and decoded: render ended in a MemoryError (exit 1) on a smaller machine."""
    from atlasgen.render import atlas_texture

    path = baked()
    monkeypatch.setattr(atlas_texture, "MAX_INCLUDE_BYTES", path.with_suffix(".wgsl").stat().st_size - 1)
    with pytest.raises(InputError, match=r"atlas-array.wgsl: expected a WGSL include \(UTF-8 text\), at most \d+ bytes, got"):
        read_render_atlas(path)


def test_an_atlas_name_too_long_for_the_system_is_refused_on_one_line(tmp_path):
    """Path.is_dir() raised ENAMETOOLONG (exit 1), where a scene path as long was refused."""
    path = tmp_path / ("a" * 300 + ".dds")
    with pytest.raises(InputError, match=r"a\.dds: cannot read \(File name too long\)"):
        read_render_atlas(path)
