"""Mitsuba 3 sources: vectorised BSDF.eval agrees with the analytic model; bad dicts quote Mitsuba."""

import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from atlasgen.errors import MaterialError
from atlasgen.separable.error import sample_error_pairs, sample_hemisphere_pairs
from atlasgen.separable.mitsuba_source import evaluate_mitsuba_f_cos, load_mitsuba_bsdf
from atlasgen.separable.source import make_source
from tests.separable.separable_helpers import analytic


@pytest.mark.parametrize("distribution", ["ggx", "beckmann"])
@pytest.mark.parametrize("alpha", [0.1, 0.4])
@pytest.mark.slow
def test_roughdielectric_reflection_is_the_analytic_microfacet_brdf(mitsuba_llvm, distribution, alpha):
    """Mitsuba's rough dielectric reflects D F G / (4 cos_i cos_o) with exact Fresnel: our model, computed independently."""
    bsdf = load_mitsuba_bsdf(
        {
            "type": "roughdielectric",
            "distribution": distribution,
            "alpha": alpha,
            "int_ior": 1.5,
            "ext_ior": 1.0,
            "sample_visible": False,
        },
        "t.toml",
    )
    l, v = sample_hemisphere_pairs(20_000, seed=3)
    ours = analytic(distribution, alpha=alpha, fresnel="exact", ior=1.5).f_cos(l, v)
    theirs = evaluate_mitsuba_f_cos(bsdf, l, v)
    assert theirs.shape == (20_000, 3)
    # Mitsuba works in float32; compare where the value is not vanishingly small.
    big = ours > 1e-4 * ours.max()
    np.testing.assert_allclose(theirs[big], ours[big], rtol=2e-3)


def test_diffuse_is_lambert(mitsuba_llvm):
    src = make_source(
        {"source": "mitsuba", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.2, 0.4, 0.6]}}}
    )
    l, v = sample_hemisphere_pairs(1000, seed=1)
    np.testing.assert_allclose(src.f_cos(l, v), np.array([0.2, 0.4, 0.6]) / np.pi * l[:, 2:3], rtol=1e-5)
    assert src.zero_on_horizon


RGB = '{type = "rgb", value = [r, g, b]}'


@pytest.mark.parametrize(
    "spec, field, expected",
    [
        ({"type": "no_such_bsdf"}, "bsdf.type", ["expected a Mitsuba BSDF plugin", "got 'no_such_bsdf'",
                                                 'Plugin "no_such_bsdf" not found']),
        ({"type": "roughconductr"}, "bsdf.type", ["(did you mean 'roughconductor'?)"]),
        ({"type": "roughconductor", "alhpa": 0.2}, "bsdf.alhpa",
         ["unknown property of a 'roughconductor' BSDF", "(did you mean 'alpha'?)", 'float "alhpa": 0.2']),
        ({"type": "roughconductor", "material": "Xx"}, "bsdf.material", ["Mitsuba rejected 'Xx'", "Xx.eta.spd"]),
        ({"type": "diffuse", "reflectance": [0.5, 0.2, 0.1]}, "bsdf.reflectance",
         [f"expected {RGB}, a spectrum or a number, got [0.5, 0.2, 0.1]", "got vector"]),
        ({"type": "diffuse", "reflectance": "red"}, "bsdf.reflectance", [f"expected {RGB}", "got 'red'"]),
        ({"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.2]}}, "bsdf.reflectance",
         [f"expected {RGB} (three numbers), got value = [0.5, 0.2]"]),
        ({"type": "twosided", "material": {"type": "diffuse", "reflectance": [0.5, 0.5, 0.5]}},
         "bsdf.material.reflectance", [f"expected {RGB}"]),
        ({"type": "blendbsdf", "weight": 0.5, "a": {"type": "diffuse"}, "b": {"type": "roughplastic", "alpah": 0.1}},
         "bsdf.b.alpah", ["unknown property of a 'roughplastic' BSDF", "(did you mean 'alpha'?)"]),
        ({"type": "roughplastic", "alpha": True}, "bsdf.alpha", ["expected a roughness (a number, or a texture table), got true"]),
        # A hostile sweep's: Mitsuba named the whole table, or refused 6 s into the bake.
        ({"type": "roughconductor", "alpha": [[0.2]]}, "bsdf.alpha", ["expected a roughness (a number, or a texture table), got [[0.2]]"]),
        ({"type": "diffuse", "id": 3}, "bsdf.id", ["expected a name (Mitsuba's id of the table, a string), got 3"]),
        ({"type": "diffuse", "reflectance": {"type": "spectrum", "value": [[400.0, float("nan")], [700.0, 0.5]]}},
         "bsdf.reflectance.value", ["expected a finite float32 number, got [[400.0, nan], [700.0, 0.5]]"]),
        ({"type": "roughconductor", "alpha": -0.1}, "bsdf.alpha", ["expected a roughness > 0 and <= 4, got -0.1"]),
        ({"type": "dielectric", "int_ior": "glas"}, "bsdf.int_ior", ["Mitsuba rejected 'glas'", "Valid choices are"]),
        ({"type": "roughconductor", "distribution": "phong"}, "bsdf.distribution", ["Mitsuba rejected 'phong'"]),
    ],
)  # fmt: skip
def test_bad_dicts_name_the_offending_key_and_quote_mitsuba(mitsuba_llvm, spec, field, expected):
    with pytest.raises(MaterialError) as info:
        load_mitsuba_bsdf(spec, "materials/bad.toml")
    message = str(info.value)
    assert "\n" not in message and "[parser.cpp" not in message
    assert message.startswith(f"materials/bad.toml: field '{field}': "), message
    for part in expected:
        assert part in message, message


@pytest.mark.parametrize(
    "spec",
    [
        {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.2, 0.1]}},
        {"type": "diffuse", "reflectance": 0.5},
        {"type": "diffuse", "reflectance": {"type": "spectrum", "value": [[400.0, 0.1], [700.0, 0.9]]}},
        {"type": "twosided", "material": {"type": "roughconductor", "alpha": 0.3, "material": "Cu"}},
        {"type": "blendbsdf", "weight": 0.3, "a": {"type": "diffuse"},
         "b": {"type": "roughdielectric", "int_ior": "bk7", "ext_ior": "air", "alpha": 1}},
        {"type": "roughconductor", "eta": {"type": "rgb", "value": [0.2, 0.92, 1.1]},
         "k": {"type": "rgb", "value": [3.9, 2.45, 2.14]}},
    ],
)  # fmt: skip
def test_the_documented_dict_forms_load(mitsuba_llvm, spec):
    # docs/separable.md shows each of these forms.
    load_mitsuba_bsdf(spec, "materials/good.toml")


def test_a_non_bsdf_plugin_is_rejected(mitsuba_llvm):
    with pytest.raises(MaterialError, match="expected a Mitsuba BSDF"):
        load_mitsuba_bsdf({"type": "point"}, "m.toml")


@pytest.mark.slow
def test_nan_and_inf_from_a_mitsuba_bsdf_are_masked_counted_and_reported(mitsuba_llvm, write_material, tmp_path):
    """A Python BSDF registered with Mitsuba returns NaN for some directions and inf for others: an error
    naming bsdf, unless the material tolerates that many (then one warning)."""
    import drjit as dr

    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_materials

    mi = mitsuba_llvm

    class BrokenBSDF(mi.BSDF):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.m_flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide
            self.m_components = [self.m_flags]

        def eval(self, ctx, si, wo, active=True):
            value = dr.select(wo.x > 0.9, dr.nan, 0.3 / dr.pi * dr.maximum(wo.z, 0.0))
            value = dr.select(si.wi.y > 0.95, dr.inf, value)
            return mi.Color3f(value)

        def sample(self, ctx, si, sample1, sample2, active=True):
            return dr.zeros(mi.BSDFSample3f), mi.Color3f(0.0)

        def pdf(self, ctx, si, wo, active=True):
            return mi.Float(0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), mi.Float(0.0)

        def to_string(self):
            return "BrokenBSDF[]"

    mi.register_bsdf("atlasgen_test_broken", lambda props: BrokenBSDF(props))
    body = 'type = "separable"\nsource = "mitsuba"\nbsdf = { type = "atlasgen_test_broken" }\nterms = 2\n'
    write_material("broken", body)
    reported = []
    with pytest.raises(MaterialError, match=r"broken.toml: field 'bsdf': .* non-finite samples .*nonfinite_tolerance >= "):
        bake_atlas(read_materials([tmp_path / "materials"]), progress=reported.append)
    assert reported == []  # refused as its slices arrive: never reported baked first (a second line on stderr)
    write_material("broken", body + "nonfinite_tolerance = 1000000\n")
    result = bake_atlas(read_materials([tmp_path / "materials"]))
    (warning,) = [w for w in result.material_warnings if w.cause == "non-finite samples"]
    assert warning.material == "broken" and "nonfinite_tolerance = 1000000" in str(warning)
    entry = result.manifest.materials[0].factors
    from atlasgen.separable.parametrization import get_parametrization

    l, v = (d.astype(np.float32) for d in get_parametrization("half_diff").grid_directions(entry.sampling_grid, lift=True))
    bad = (l[..., 0] > 0.9) | (v[..., 1] > 0.95)
    assert entry.nonfinite_samples == 3 * int(bad.sum()) > 0
    # The manifest names the report sample exactly: its size, seed and lobe width.
    sample = sample_error_pairs(entry.errors.pairs, entry.errors.seed, entry.errors.lobe_alpha)
    pl, pv = (d.astype(np.float32) for d in sample.pairs)
    assert entry.nonfinite_reference == 3 * int(((pl[:, 0] > 0.9) | (pv[:, 1] > 0.95)).sum()) > 0
    assert all(np.all(np.isfinite(level)) for level in result.levels)
    assert np.isfinite(entry.errors.float_error.relative_rms) and np.isfinite(entry.errors_8bit.relative_rms)


def test_every_bsdf_example_in_the_docs_loads(mitsuba_llvm):
    text = (Path(__file__).resolve().parents[2] / "docs" / "separable.md").read_text(encoding="utf-8")
    section = text[text.index("### The `bsdf` table") : text.index("What is refused")]
    blocks = re.findall(r"```toml\n(.*?)```", section, re.S)
    examples = [tomllib.loads(line)["bsdf"] for line in blocks[0].splitlines() if line.startswith("bsdf =")]
    examples += [tomllib.loads(block)["bsdf"] for block in blocks[1:]]
    assert len(examples) >= 7
    for spec in examples:
        load_mitsuba_bsdf(spec, "docs/separable.md")


@pytest.mark.parametrize("plugin", ["roughdielectric", "dielectric", "thindielectric"])
def test_a_transmissive_bsdf_is_refused_naming_bsdf_type(mitsuba_llvm, expect_rejected, plugin):
    message = expect_rejected("separable", f'source = "mitsuba"\nbsdf = {{ type = "{plugin}" }}\nterms = 1',
                              "bsdf.type", f"a '{plugin}' BSDF transmits light")  # fmt: skip
    assert "reflection_only = true" in message


@pytest.mark.parametrize(("model", "bsdf", "field"), [
    ("bsdf", '{ type = "diffuse", reflectance = { type = "blackbody", temperature = 5000 } }', "bsdf.reflectance"),
    ("bsdf", '{ type = "roughconductor", alpha = 0.2, k = { type = "blackbody", temperature = 3000 } }', "bsdf.k"),
    ("separable", '{ type = "diffuse", reflectance = { type = "blackbody", temperature = 5000 } }\nsource = "mitsuba"',
     "bsdf.reflectance"),
])  # fmt: skip
def test_a_blackbody_spectrum_is_refused_naming_it(mitsuba_llvm, expect_rejected, model, bsdf, field):
    """It loads, and Mitsuba's RGB variant raised "Not implemented for non-spectral modes" mid-bake: an internal error."""
    expect_rejected(model, f"bsdf = {bsdf}", field, "expected a spectrum Mitsuba's RGB variant evaluates, got a blackbody")


def test_reflection_only_is_only_for_mitsuba(expect_rejected):
    expect_rejected("separable", 'source = "ggx"\nreflection_only = true', "reflection_only", "only used with source = 'mitsuba'")


@pytest.mark.slow
def test_reflection_only_bakes_the_reflection_and_records_the_dropped_fraction(mitsuba_llvm, write_material, tmp_path):
    from atlasgen.bake.pipeline import bake_atlas
    from atlasgen.materials.material import read_materials

    write_material("glass", 'type = "separable"\nsource = "mitsuba"\nreflection_only = true\nterms = 2\n'
                            'bsdf = { type = "roughdielectric", alpha = 0.2, int_ior = 1.5, ext_ior = 1.0 }\n')  # fmt: skip
    entry = bake_atlas(read_materials([tmp_path / "materials"])).manifest.materials[0].factors
    fractions = {row["view_deg"]: row["fraction"] for row in entry.transmitted_fraction}
    assert sorted(fractions) == [0.0, 30.0, 60.0, 80.0]
    # At normal view: R = F(0) = 0.04, T = (1 - F) / n^2 in radiance units (Mitsuba's
    # roughdielectric scales transmitted radiance by 1/eta^2), so T / (R + T) = 0.9142; the
    # rough surface moves it a little. Grazing views reflect more, so the fraction falls.
    t = 0.96 / 1.5**2
    assert fractions[0.0] == pytest.approx(t / (t + 0.04), abs=0.01)
    assert fractions[0.0] > fractions[60.0] > fractions[80.0] > 0.2
    assert np.isfinite(entry.errors_8bit.relative_rms)


@pytest.mark.slow
def test_an_opaque_bsdf_records_no_dropped_fraction(mitsuba_llvm):
    from atlasgen.separable.mitsuba_source import transmitted_fractions

    rows = transmitted_fractions({"type": "roughconductor", "alpha": 0.1, "material": "Cu"})
    assert [r["fraction"] for r in rows] == [0.0] * 4


def test_an_unavailable_variant_is_one_backend_error_line(mitsuba_llvm, monkeypatch):
    from atlasgen.errors import BackendError
    from atlasgen.separable import mitsuba_source

    def refuse(variant):
        raise RuntimeError("[jit_init] cannot load LLVM\n  [llvm.cpp:42] - libLLVM.so not found")

    monkeypatch.setattr(mitsuba_llvm, "variant", lambda: "scalar_rgb")
    monkeypatch.setattr(mitsuba_llvm, "set_variant", refuse)
    with pytest.raises(BackendError) as info:
        mitsuba_source.load_mitsuba_bsdf({"type": "diffuse"}, "m.toml")
    message = str(info.value)
    assert "\n" not in message and "[llvm.cpp:42]" not in message
    assert message == "Mitsuba variant 'llvm_ad_rgb' is unavailable: cannot load LLVM; libLLVM.so not found"


@pytest.mark.parametrize("reflectance", [0.0, 0.5])
def test_delta_fractions_is_the_smooth_coat_share_of_the_albedo(mitsuba_llvm, reflectance):
    """A smooth plastic's coat reflects F(theta_v) (exact Fresnel, n = 1.5: 0.04 at normal view), the
    part BSDF.eval omits; the rest is its diffuse albedo, integrated here from BSDF.eval by a midpoint
    rule over the hemisphere, independent of BSDF.sample. D / (D + S) must match; with a black base S = 0."""
    from atlasgen.separable.mitsuba_source import delta_fractions

    spec = {"type": "plastic", "int_ior": 1.5, "ext_ior": 1.0, "diffuse_reflectance": reflectance, "nonlinear": False}
    rows = delta_fractions(spec, views=(0.0,))
    n = 256
    mu = (np.arange(n) + 0.5) / n  # cos theta_l, uniform: d omega = d mu d phi
    phi = 2.0 * np.pi * (np.arange(n) + 0.5) / n
    m, p = np.meshgrid(mu, phi, indexing="ij")
    s = np.sqrt(1.0 - m * m)
    l = np.stack([s * np.cos(p), s * np.sin(p), m], -1).reshape(-1, 3)
    v = np.tile([0.0, 0.0, 1.0], (l.shape[0], 1))
    albedo = float(evaluate_mitsuba_f_cos(load_mitsuba_bsdf(spec, "t"), l, v).mean(axis=1).sum() * (2.0 * np.pi / (n * n)))
    coat = 0.04
    assert rows[0]["view_deg"] == 0.0
    assert rows[0]["fraction"] == pytest.approx(coat / (coat + albedo), abs=5e-3)
    assert (rows[0]["fraction"] == pytest.approx(1.0)) == (reflectance == 0.0)


def test_a_rough_bsdf_has_no_delta_fraction(mitsuba_llvm):
    from atlasgen.separable.mitsuba_source import delta_fractions

    assert [r["fraction"] for r in delta_fractions({"type": "roughplastic", "alpha": 0.2})] == [0.0] * 4


def test_a_bitmap_texture_larger_than_the_limit_is_refused_from_its_header(tmp_path, monkeypatch):
    """An 875 KB PNG declaring 30000 x 30000 texels crashed the bake (SIGSEGV, no line): Mitsuba allocates what the
    header says. The limit is lowered here so that an 8 x 8 image stands for one over it."""
    import numpy as np

    import atlasgen.separable.mitsuba_source as source
    from atlasgen.errors import MaterialError
    from atlasgen.io.images import write_png

    texture = tmp_path / "tex.png"
    write_png(texture, np.full((8, 8, 3), 128, np.uint8))
    monkeypatch.setattr(source, "MAX_BITMAP_TEXELS", 63)
    spec = {"type": "diffuse", "reflectance": {"type": "bitmap", "filename": str(texture)}}
    with pytest.raises(MaterialError) as info:
        source.load_mitsuba_bsdf(spec, "materials/bad.toml")
    assert str(info.value) == ("materials/bad.toml: field 'bsdf.reflectance.filename': expected a texture of at most 63 "
                               f"texels, got 8 x 8 in {texture}")  # fmt: skip


def test_doctests():
    import doctest

    from atlasgen.separable import mitsuba_source

    result = doctest.testmod(mitsuba_source)
    assert result.attempted > 0 and result.failed == 0


@pytest.mark.parametrize(("reflectance", "field", "expected"), [
    ({"type": "volume"}, "bsdf.reflectance.volume", "expected the volume a volume texture reads (a table, e.g. "
     '{type = "constvolume", value = 0.5}), got None'),
    ({"type": "rgb", "value": [True, False, True]}, "bsdf.reflectance", '(three numbers), got value = [true, false, true]'),
    ({"type": "rgb", "value": ["0.5", "0.5", "0.5"]}, "bsdf.reflectance", "(three numbers), got value = "),
    ({"type": "spectrum", "value": [[400, True], [700, False]]}, "bsdf.reflectance.value",
     "expected a number or [[wavelength, value], ...], pairs of numbers, got "),
    ({"type": "spectrum", "filename": "{unsorted}"}, "bsdf.reflectance.filename",
     "wavelength 400 after 700; expected the wavelengths increasing"),
    ({"type": "spectrum", "filename": "{one}"}, "bsdf.reflectance.filename",
     "1 wavelength-value pairs; expected at least 2"),
    ({"type": "spectrum", "filename": "{negative}"}, "bsdf.reflectance", "expected a reflectance >= 0 in every channel"),
    ({"type": "uniform", "value": -1.0}, "bsdf.reflectance", "expected a reflectance >= 0 in every channel"),
])  # fmt: skip
def test_a_colour_table_mitsuba_would_take_wrongly_is_refused_on_one_line(tmp_path, capfd, reflectance, field, expected):
    """A hostile sweep's: a volume texture without its volume crashed the bake (SIGSEGV, no line); booleans read as
    numbers; strings failed with nanobind's line before the refusal; a spectrum file unsorted or of one line baked
    black, and a negative one (as a negative uniform spectrum) passed the check of a negative reflectance."""
    files = {"unsorted": "700 0.1\n400 0.5\n", "one": "400 0.1\n", "negative": "# measured\n400 -0.5\n700 -0.5\n"}
    for name, text in files.items():
        (tmp_path / f"{name}.spd").write_text(text)
    if "filename" in reflectance:
        reflectance = {**reflectance, "filename": str(tmp_path / f"{reflectance['filename'][1:-1]}.spd")}
    with pytest.raises(MaterialError) as info:
        load_mitsuba_bsdf({"type": "diffuse", "reflectance": reflectance}, "m.toml")
    assert str(info.value).startswith(f"m.toml: field '{field}': ") and expected in str(info.value), str(info.value)
    assert capfd.readouterr().err == ""


def test_a_spectrum_file_mitsuba_reads_is_taken_with_its_comments(tmp_path, mitsuba_llvm):
    from atlasgen.separable.mitsuba_source import read_spectrum_file

    path = tmp_path / "s.spd"
    path.write_text("# wavelength value\n400 0.5\n\n700 0.25  # red\n")
    assert read_spectrum_file(path) == [[400.0, 0.5], [700.0, 0.25]]
    load_mitsuba_bsdf({"type": "diffuse", "reflectance": {"type": "spectrum", "filename": str(path)}}, "m.toml")


@pytest.mark.parametrize("texture", [b"\x89PNG\r\n\x1a\n" + bytes(100), b"\xff\xd8\xff\xe0\x00\x10JFIF\x00"])
def test_a_texture_no_library_reads_is_one_line_without_the_library_s_own(tmp_path, capfd, mitsuba_llvm, texture):
    """A hostile sweep's: libpng's "libpng error: ... bad header" (or libjpeg's warning) came before the refusal."""
    path = tmp_path / ("t.png" if texture.startswith(b"\x89") else "t.jpg")
    path.write_bytes(texture)
    with pytest.raises(MaterialError, match=r"^m\.toml: field 'bsdf\.reflectance': Mitsuba rejected the BSDF 'bitmap'"):
        load_mitsuba_bsdf({"type": "diffuse", "reflectance": {"type": "bitmap", "filename": str(path)}}, "m.toml")
    assert capfd.readouterr().err == ""
