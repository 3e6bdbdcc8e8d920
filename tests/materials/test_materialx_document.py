"""Reading MaterialX documents: every surfacematerial of the four surface models, and one-line refusals."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("MaterialX")

pytestmark = pytest.mark.slow  # loading MaterialX's libraries costs about a second of CPU

from atlasgen.errors import InputError, MaterialError  # noqa: E402
from atlasgen.materials.material import find_material_files, read_material_file, read_materials  # noqa: E402


def _document(tmp_path, body: str, name: str = "lib.mtlx"):
    path = tmp_path / name
    path.write_text(f'<?xml version="1.0"?>\n<materialx version="1.39">\n{body}\n</materialx>\n')
    return path


def _material(name, category, inputs: str):
    return (f'<{category} name="SR_{name}" type="surfaceshader">{inputs}</{category}>\n'
            f'<surfacematerial name="{name}" type="material">'
            f'<input name="surfaceshader" type="surfaceshader" nodename="SR_{name}" /></surfacematerial>')  # fmt: skip


FOUR = "\n".join([
    _material("Std", "standard_surface", '<input name="base_color" type="color3" value="0.8, 0.1, 0.1" />'),
    _material("Open", "open_pbr_surface", '<input name="coat_weight" type="float" value="1" />'
              '<input name="coat_roughness" type="float" value="0.2" />'),
    _material("Gltf", "gltf_pbr", '<input name="metallic" type="float" value="1" />'),
    _material("Usd", "UsdPreviewSurface", '<input name="roughness" type="float" value="0.3" />'),
])  # fmt: skip


def test_every_surface_model_reads_with_the_document_names(tmp_path):
    path = _document(tmp_path, FOUR)
    materials = read_material_file(path)
    assert [m.name for m in materials] == ["Std", "Open", "Gltf", "Usd"]
    for m in materials:
        spec = m.params["materialx"]
        assert m.type == "separable" and m.params["source"] == "materialx" and m.source == path.as_posix()
        assert spec["document"] == path.name and spec["material"] == m.name
    assert materials[0].params["materialx"]["inputs"] == {"base_color": pytest.approx([0.8, 0.1, 0.1])}
    assert materials[1].params["materialx"]["category"] == "open_pbr_surface"
    assert len({m.content_hash for m in materials}) == 4  # one cache entry each


def test_a_folder_lists_documents_beside_toml_files(tmp_path):
    _document(tmp_path, FOUR)
    (tmp_path / "a.toml").write_text('type = "lambert"\n')
    assert [p.name for p in find_material_files([tmp_path])] == ["a.toml", "lib.mtlx"]
    assert [m.name for m in read_materials([tmp_path])] == ["a", "Std", "Open", "Gltf", "Usd"]


@pytest.mark.parametrize("name", ["b.MTLX", "b.Toml"])
def test_a_folder_s_material_file_with_an_upper_case_extension_is_refused_not_skipped(tmp_path, name):
    """It was left out without a word (exit 0, the rest baked), though named on its own it bakes."""
    (tmp_path / "a.toml").write_text('type = "lambert"\n')
    (tmp_path / name).write_text('type = "lambert"\n')
    with pytest.raises(InputError) as info:
        find_material_files([tmp_path])
    assert str(info.value) == (f"{(tmp_path / name).as_posix()}: expected a material file's extension in lower case "
                               f"({name[1:].lower()}), as a folder's material files are found; rename it")  # fmt: skip
    (tmp_path / name).rename(tmp_path / name.lower())
    assert [p.name for p in find_material_files([tmp_path])] == ["a.toml", name.lower()]


TEXTURED = '<image name="tex" type="color3"><input name="file" type="filename" value="a.png" /></image>\n' + _material(
    "Tex", "standard_surface", '<input name="base_color" type="color3" nodename="tex" />'
)


def test_a_driven_input_is_refused_naming_it(tmp_path):
    path = _document(tmp_path, TEXTURED)
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{path.as_posix()}: field 'Tex.base_color': driven by node 'tex'")


def test_flattening_records_what_was_flattened(tmp_path):
    path = _document(tmp_path, TEXTURED)
    spec = read_material_file(path, "default")[0].params["materialx"]
    assert spec["flattened"] == {"base_color": {"driven_by": "node 'tex'", "value": pytest.approx([0.8, 0.8, 0.8])}}
    spec = read_material_file(path, {"base_color": [0.1, 0.2, 0.3]})[0].params["materialx"]
    assert spec["inputs"]["base_color"] == [0.1, 0.2, 0.3]


_LOOKS = """<variantset name="finish"><variant name="shiny"><input name="specular_roughness" type="float" value="0.05" />
</variant></variantset>
<look name="hero"><materialassign name="body" material="Paint" geom="/car/body">
<variantassign name="pick" variantset="finish" variant="shiny" /></materialassign></look>
<look name="plain"><materialassign name="trim" material="Paint" geom="/car/trim" /></look>"""


def test_a_variant_a_look_assigns_is_named_not_applied_silently(tmp_path):
    """The look switches the material's roughness to 0.05; the bake keeps its own 0.4 (as MaterialX's generator
    shades it), and said nothing. A look that only binds geometry changes no slice and is not named."""
    body = _material("Paint", "standard_surface", '<input name="specular_roughness" type="float" value="0.4" />')
    spec = read_material_file(_document(tmp_path, body + "\n" + _LOOKS))[0].params["materialx"]
    assert spec["inputs"]["specular_roughness"] == pytest.approx(0.4)
    assert spec["not_in_table"] == ["variant 'shiny' of variantset 'finish' (look 'hero', materialassign 'body'): looks "
                                    "are not applied, the material's own inputs are baked"]  # fmt: skip
    other = _material("Other", "standard_surface", "")
    spec = read_material_file(_document(tmp_path, other + "\n" + body + "\n" + _LOOKS, "two.mtlx"))[0].params["materialx"]
    assert spec["not_in_table"] == []  # 'Other' is in no look


def test_inputs_the_table_cannot_hold_are_named_and_left_out_of_the_oracle(tmp_path):
    body = _material("Glow", "standard_surface", '<input name="emission" type="float" value="2" />'
                     '<input name="transmission" type="float" value="0.5" />'
                     '<input name="opacity" type="color3" value="0.5, 0.5, 0.5" />')  # fmt: skip
    spec = read_material_file(_document(tmp_path, body))[0].params["materialx"]
    assert [line.split(" =")[0] for line in spec["not_in_table"]] == ["emission", "opacity", "transmission"]
    assert spec["oracle_inputs"]["emission"] == 0.0 and spec["oracle_inputs"]["opacity"] == [1.0, 1.0, 1.0]
    assert spec["oracle_inputs"]["transmission"] == 0.5  # the reflection that remains is what the oracle shades


@pytest.mark.parametrize(
    ("category", "inputs", "named"),
    [
        ("standard_surface", '<input name="thin_walled" type="boolean" value="true" />'
                             '<input name="subsurface" type="float" value="1" />', ["subsurface"]),
        ("open_pbr_surface", '<input name="geometry_thin_walled" type="boolean" value="true" />'
                             '<input name="subsurface_weight" type="float" value="0.5" />', ["subsurface_weight"]),
        ("standard_surface", '<input name="subsurface" type="float" value="1" />', []),  # a solid's: reflected
        ("standard_surface", '<input name="thin_walled" type="boolean" value="true" />', []),  # no subsurface
    ],
    ids=["ss-thin-subsurface", "openpbr-thin-subsurface", "ss-solid-subsurface", "ss-thin-without-subsurface"],
)  # fmt: skip
def test_a_thin_walled_subsurface_is_named_as_light_through_the_wall(tmp_path, category, inputs, named):
    """A thin wall's subsurface is a translucent BSDF in MaterialX's graphs, light through the sheet, which a
    slice cannot hold: a white sheet baked as a black ball without a word (found by a hostile sweep)."""
    spec = read_material_file(_document(tmp_path, _material("M", category, inputs)))[0].params["materialx"]
    assert [line.split(" =")[0] for line in spec["not_in_table"]] == named
    assert all("light through the thin wall" in line for line in spec["not_in_table"])


@pytest.mark.parametrize(
    ("category", "inputs", "named"),
    [
        ("UsdPreviewSurface", '<input name="displacement" type="float" value="5" />'
                              '<input name="occlusion" type="float" value="0.5" />', ["displacement", "occlusion"]),
        ("gltf_pbr", '<input name="occlusion" type="float" value="0.25" />', ["occlusion"]),
        ("UsdPreviewSurface", '<input name="occlusion" type="float" value="1" />', []),  # its default: nothing lost
    ],
    ids=["usd-displacement-and-occlusion", "gltf-occlusion", "usd-occlusion-at-its-default"],
)  # fmt: skip
def test_inputs_the_shader_graph_leaves_unused_are_named_not_dropped(tmp_path, category, inputs, named):
    """MaterialX's glTF and USD graphs never read ``occlusion`` (nor USD's ``displacement``): a value given was baked
    away without a word (found by a hostile sweep). Each is now named, unless it is the nodedef's default."""
    spec = read_material_file(_document(tmp_path, _material("M", category, inputs)))[0].params["materialx"]
    assert [line.split(" =")[0] for line in spec["not_in_table"]] == named


@pytest.mark.parametrize(
    ("body", "field", "expected"),
    [
        (_material("Ph", "standard_surface", "").replace("standard_surface", "surface_unlit"), "Ph.surfaceshader",
         "surface shader 'surface_unlit' is not supported"),
        ('<surfacematerial name="Lone" type="material" />', "Lone.surfaceshader", "expected a connected surface shader"),
        ("", None, "expected at least one surfacematerial"),
        ("<notclosed", None, "malformed MaterialX document"),
    ],
)  # fmt: skip
def test_bad_documents_are_refused_on_one_line(tmp_path, body, field, expected):
    path = _document(tmp_path, body)
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    message = str(info.value)
    where = f"{path.as_posix()}: field '{field}'" if field else path.as_posix()
    assert "\n" not in message and message.startswith(f"{where}: {expected}"), message


def _open(inputs: str) -> str:
    return _material("M", "open_pbr_surface", inputs)


@pytest.mark.parametrize(
    ("inputs", "field", "expected"),
    [
        ('<input name="base_color" type="color3" value="abc" />', "M.base_color", "expected 3 finite numbers, got 'abc'"),
        ('<input name="base_color" type="color3" value="0.5, 0.5" />', "M.base_color",
         "expected 3 finite numbers, got '0.5, 0.5'"),
        ('<input name="specular_roughness" type="float" value="nan" />', "M.specular_roughness",
         "expected a finite number, got 'nan'"),
        ('<input name="specular_roughness" type="float" value="-3" />', "M.specular_roughness",
         "expected float within 0 .. 1 (the nodedef's uimin .. uimax), got -3"),
        # Shown to %g, this value read "got 1", inside the range it was refused for.
        ('<input name="specular_roughness" type="float" value="1.0000001" />', "M.specular_roughness",
         "expected float within 0 .. 1 (the nodedef's uimin .. uimax), got 1.0000001"),
        # Digits of another script: "0.4" and an Arabic-Indic five was baked as 0.4.
        ('<input name="specular_roughness" type="float" value="0.4\u0665" />', "M.specular_roughness",
         "expected a finite number, got '0.4\u0665'"),
        ('<input name="base_color" type="color3" value="0.2, 1.5, 0.2" />', "M.base_color",
         "expected color3 within 0, 0, 0 .. 1, 1, 1 (the nodedef's uimin .. uimax), got 0.2, 1.5, 0.2"),
        ('<input name="thin_film_thickness" type="float" value="-1" />', "M.thin_film_thickness",
         "expected float at least 0 (the nodedef's uimin), got -1"),
        ('<input name="base_color" type="float" value="0.5" />', "M.base_color",
         "expected type color3 (the nodedef's), got 'float'"),
        # MaterialX's parser reads a leading number and drops the rest: these baked 1, 0, 0.5 and a colour.
        ('<input name="base_weight" type="float" value="1,2,3" />', "M.base_weight", "expected a finite number, got '1,2,3'"),
        ('<input name="base_weight" type="float" value="0x1" />', "M.base_weight", "expected a finite number, got '0x1'"),
        ('<input name="base_weight" type="float" value="0.5abc" />', "M.base_weight",
         "expected a finite number, got '0.5abc'"),
        ('<input name="base_color" type="color3" value="0.5, 0.5, 0.5," />', "M.base_color",
         "expected 3 finite numbers, got '0.5, 0.5, 0.5,'"),
        # Finite, but no float32: MaterialX's parser gives up on it, and "expected a finite number" misled.
        ('<input name="specular_ior" type="float" value="1e300" />', "M.specular_ior",
         "expected a finite number within float32's range (at most 3.40282e+38 in magnitude), got '1e300'"),
        ('<input name="base_color" type="color3" value="0.5, -1e40, 0.5" />', "M.base_color",
         "expected 3 finite numbers within float32's range (at most 3.40282e+38 in magnitude), got '0.5, -1e40, 0.5'"),
        # The oracle is handed values as written, where MaterialX's generator converts them.
        ('<input name="base_color" type="color3" value="0.5, 0.5, 0.5" colorspace="srgb_texture" />', "M.base_color",
         "expected a linear colour (colorspace lin_rec709), got colorspace 'srgb_texture'; atlasgen bakes values as "
         "written, with no colour transform"),
        ('<input name="thin_film_thickness" type="float" value="450" unit="nanometer" unittype="distance" />',
         "M.thin_film_thickness", "expected no unit (the nodedef's), got unit 'nanometer'; atlasgen bakes values as "
         "written, with no unit conversion"),
    ],
)  # fmt: skip
def test_a_constant_input_must_parse_be_finite_and_lie_within_the_nodedef_s_limits(tmp_path, inputs, field, expected):
    path = _document(tmp_path, _open(inputs))
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value) == f"{path.as_posix()}: field '{field}': {expected}"


def test_an_integer_input_must_be_a_whole_integer_and_linear_colours_read(tmp_path):
    path = _document(tmp_path, _material("U", "UsdPreviewSurface", '<input name="useSpecularWorkflow" type="integer" '
                                         'value="1.5" />'))  # fmt: skip
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value) == f"{path.as_posix()}: field 'U.useSpecularWorkflow': expected an integer, got '1.5'"
    linear = _document(tmp_path, _open('<input name="base_color" type="color3" value="0.5, 0.25, 0.5" '
                                       'colorspace="lin_rec709" />'), "linear.mtlx")  # fmt: skip
    assert read_material_file(linear)[0].params["materialx"]["inputs"] == {"base_color": [0.5, 0.25, 0.5]}


@pytest.mark.parametrize(("root", "shader", "field", "expected"), [
    # MaterialX's generator picks the nodedef from these; the oracle shades the current one.
    ('version="1.39"', 'nodedef="ND_open_pbr_surface_surfaceshader"', "M.surfaceshader",
     "expected the nodedef the oracle shades, ND_standard_surface_surfaceshader, got 'ND_open_pbr_surface_surfaceshader' "
     "(from the node's nodedef, version or type)"),
    ('version="1.39"', 'version="1.0.0"', "M.surfaceshader", "got 'ND_standard_surface_surfaceshader_100'"),
    ('version="1.39"', 'version="9.9"', "M.surfaceshader", "got none MaterialX can find"),
    ('version="1.39" colorspace="srgb_texture"', "", "M.base_color", "got colorspace 'srgb_texture'"),
])  # fmt: skip
def test_a_shader_the_oracle_would_not_shade_as_written_is_refused(tmp_path, root, shader, field, expected):
    path = tmp_path / "m.mtlx"
    body = _material("M", "standard_surface", '<input name="base_color" type="color3" value="0.5, 0.5, 0.5" />')
    body = body.replace('type="surfaceshader">', f'type="surfaceshader" {shader}>', 1)
    path.write_text(f'<?xml version="1.0"?>\n<materialx {root}>\n{body}\n</materialx>\n')
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value).startswith(f"{path.as_posix()}: field '{field}': ") and expected in str(info.value), str(info.value)


@pytest.mark.parametrize(("body", "expected"), [
    # MaterialX invented the name surfacematerial1, and dropped a material inside a node graph from its list.
    (_material("M", "standard_surface", "").replace('name="M"', 'name=""'),
     "field '<surfacematerial>': expected a name, got an empty one"),
    ('<nodegraph name="NG">' + _material("M", "standard_surface", "") + "</nodegraph>\n" + _material("N", "standard_surface", ""),
     "field 'M': expected a surfacematerial at the top of the document, found one inside <nodegraph name='NG'>"),
    # What MaterialX's validation finds and no check above names: a connection to an output the node lacks.
    (_material("M", "standard_surface", "").replace('nodename="SR_M"', 'nodename="SR_M" output="nope"'),
     "expected a document MaterialX validates, got: No output found for port connection"),
    # Named by its tag and name: the element's XML was cut to '<input name="bas... (110 characters)'.
    (_material("M", "standard_surface", '<input name="base_color" type="color3" interfacename="bc" />'),
     "expected a document MaterialX validates, got: Interface name not found in referenced declaration: "
     "input 'base_color'"),
    # --flatten default took an unknown driven input for one it flattened.
    (_material("M", "standard_surface", '<input name="bogus" type="float" nodename="T" />')
     + '\n<constant name="T" type="float"><input name="value" type="float" value="1" /></constant>',
     "field 'M.bogus': unknown input of standard_surface"),
])  # fmt: skip
def test_what_materialx_would_drop_rename_or_find_invalid_is_refused(tmp_path, body, expected):
    path = _document(tmp_path, body)
    with pytest.raises(MaterialError) as info:
        read_material_file(path, "default")
    assert str(info.value).startswith(f"{path.as_posix()}: {expected}"), str(info.value)


def test_limits_are_the_nodedef_s_own_and_inclusive(tmp_path):
    """At the limits (0 and 1, and glTF's ior of 1) and far above a one-sided one, inputs read as given."""
    body = "\n".join([
        _open('<input name="coat_roughness" type="float" value="0" /><input name="base_metalness" type="float" '
              'value="1" /><input name="thin_film_thickness" type="float" value="40" />'),
        _material("G", "gltf_pbr", '<input name="ior" type="float" value="1" />'),
    ])  # fmt: skip
    m, g = read_material_file(_document(tmp_path, body))
    assert m.params["materialx"]["inputs"] == {"coat_roughness": 0.0, "base_metalness": 1.0, "thin_film_thickness": 40.0}
    assert g.params["materialx"]["inputs"] == {"ior": 1.0}


def test_an_input_without_a_value_takes_the_nodedef_s_default(tmp_path):
    spec = read_material_file(_document(tmp_path, _open('<input name="base_color" type="color3" />')))[0].params["materialx"]
    assert spec["inputs"] == {} and spec["oracle_inputs"] == {}


def test_a_flattened_value_meets_the_same_limits(tmp_path):
    path = _document(tmp_path, TEXTURED)
    with pytest.raises(MaterialError) as info:
        read_material_file(path, {"base_color": [0.1, 2.0, 0.3]})
    assert str(info.value).startswith(f"{path.as_posix()}: field 'Tex.base_color': expected color3 within 0, 0, 0 .. 1, 1, 1")
    with pytest.raises(MaterialError) as info:
        read_material_file(path, {"base_color": [float("nan"), 0.2, 0.3]})
    assert str(info.value) == f"{path.as_posix()}: field 'Tex.base_color': expected 3 finite numbers, got nan, 0.2, 0.3"


def test_two_elements_of_one_name_are_refused_not_dropped(tmp_path):
    """MaterialX's reader keeps the first of two same-named elements and drops the second silently."""
    body = _open('<input name="base_color" type="color3" value="0.1, 0.2, 0.3" />')
    path = _document(tmp_path, body + "\n" + body.replace("0.1, 0.2, 0.3", "0.3, 0.2, 0.1"))
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value) == (f"{path.as_posix()}: field 'SR_M': expected unique names among the children of "
                               "<materialx>, found <open_pbr_surface> and <open_pbr_surface> both named 'SR_M'")  # fmt: skip


def _including(tmp_path, href: str, body: str = "", name: str = "main.mtlx"):
    path = tmp_path / name
    path.write_text('<?xml version="1.0"?>\n<materialx version="1.39" xmlns:xi="http://www.w3.org/2001/XInclude">\n'
                    f'<xi:include href="{href}" />\n{body}\n</materialx>\n')  # fmt: skip
    return path


def test_an_included_file_s_materials_join_and_their_values_key_the_cache(tmp_path):
    """A document's includes are read with it: their materials bake, each is listed for the depfile,
    and a change to an included material's value changes that material's content hash (the cache's
    key) and no other's; an edit that changes no value (a doc string) changes none."""
    (tmp_path / "lib").mkdir()
    leaf = _document(tmp_path / "lib", _material("Red", "standard_surface", ""), "red.mtlx")
    _including(tmp_path / "lib", "red.mtlx", name="mid.mtlx")  # nested: found beside the file that includes it
    path = _including(tmp_path, "lib/mid.mtlx", _material("Blue", "standard_surface", ""))
    before = read_material_file(path)
    assert [m.name for m in before] == ["Red", "Blue"]
    assert before[0].includes == ((tmp_path / "lib" / "mid.mtlx").as_posix(), leaf.as_posix())
    leaf.write_text(leaf.read_text().replace('type="material"', 'type="material" doc="changed"'))
    assert [m.content_hash for m in read_material_file(path)] == [m.content_hash for m in before]
    leaf.write_text(
        leaf.read_text().replace("></standard_surface>", '><input name="base" type="float" value="0.5" /></standard_surface>')
    )
    after = read_material_file(path)
    assert after[0].params["materialx"]["inputs"] == {"base": 0.5}
    assert after[0].content_hash != before[0].content_hash and after[1].content_hash == before[1].content_hash


def test_a_name_taken_by_an_included_file_is_refused_not_dropped(tmp_path):
    """MaterialX keeps the included element and drops the document's own of the same name silently."""
    red = _document(tmp_path, _material("M", "standard_surface", '<input name="base_color" type="color3" value="1, 0, 0" />'),
                    "red.mtlx")  # fmt: skip
    path = _including(tmp_path, "red.mtlx", _material("M", "standard_surface", ""))
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value) == (f"{path.as_posix()}: field 'SR_M': expected unique names in a document and the files it "
                               f"includes, found 'SR_M' in both {path.as_posix()} and {red.as_posix()}")  # fmt: skip


def test_an_include_found_only_where_materialx_would_look_further_is_refused(tmp_path, monkeypatch):
    """MaterialX's own reader looks for an href in the working folder too: run from there, a document baked
    a material of a file no check, cache key or depfile saw, and a named pipe there hung the bake."""
    import os

    work = tmp_path / "work"
    work.mkdir()
    _document(work, _material("M", "standard_surface", '<input name="base_color" type="color3" value="0, 1, 0" />'),
              "lib.mtlx")  # fmt: skip
    os.mkfifo(work / "pipe.mtlx")
    (tmp_path / "docs").mkdir()
    monkeypatch.chdir(work)
    for href in ("lib.mtlx", "pipe.mtlx"):
        path = _including(tmp_path / "docs", href, _material("N", "standard_surface", ""))
        with pytest.raises(MaterialError) as info:
            read_material_file(path)
        assert str(info.value) == (f"{path.as_posix()}: field 'xi:include': expected a file beside it or beside the "
                                   f"document, found none for href {href!r}")  # fmt: skip


@pytest.mark.parametrize("head", [
    # MaterialX reads the literal tag xi:include whatever xi is bound to, ElementTree by the namespace.
    '<materialx version="1.39" xmlns:xi="urn:not-xinclude">\n<xi:include href="red.mtlx" />',
    '<materialx version="1.39" xmlns:inc="http://www.w3.org/2001/XInclude">\n<inc:include href="red.mtlx" />',
    '<materialx version="1.39">\n<include xmlns="http://www.w3.org/2001/XInclude" href="red.mtlx" />',
])  # fmt: skip
def test_an_include_materialx_and_the_checks_would_read_differently_is_refused(tmp_path, head):
    _document(tmp_path, _material("R", "standard_surface", ""), "red.mtlx")
    path = tmp_path / "main.mtlx"
    path.write_text(f'<?xml version="1.0"?>\n{head}\n{_material("M", "standard_surface", "")}\n</materialx>\n')
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value) == (f"{path.as_posix()}: field 'xi:include': expected each include written <xi:include "
                               'href=...> with xmlns:xi="http://www.w3.org/2001/XInclude", as MaterialX reads them')  # fmt: skip
    commented = '<!-- <xi:include href="red.mtlx" /> -->'  # an include commented out is no include
    path.write_text(f'<?xml version="1.0"?>\n<materialx version="1.39">\n{commented}\n'
                    f'{_material("M", "standard_surface", "")}\n</materialx>\n')  # fmt: skip
    assert [m.name for m in read_material_file(path)] == ["M"]


def test_a_document_or_include_over_the_size_limit_is_refused_unread(tmp_path, monkeypatch):
    """A 6 GB document was read whole into memory (MemoryError, exit 1); the limit is lowered here to stand for it."""
    import atlasgen.materials.materialx_document as reader

    red = _document(tmp_path, _material("R", "standard_surface", "<!-- " + "x" * 1000 + " -->"), "red.mtlx")
    path = _including(tmp_path, "red.mtlx", _material("M", "standard_surface", ""))
    monkeypatch.setattr(reader, "_DOCUMENT_LIMIT", (path.stat().st_size, "a MaterialX document"))
    size, limit = red.stat().st_size, path.stat().st_size
    with pytest.raises(InputError) as info:
        read_material_file(path)
    assert str(info.value) == (f"{red.as_posix()}: {size} bytes; expected a MaterialX document, at most {limit} bytes "
                               f"(included by {path.as_posix()})")  # fmt: skip
    monkeypatch.setattr(reader, "_DOCUMENT_LIMIT", (10, "a MaterialX document"))
    with pytest.raises(InputError, match=r"main.mtlx: \d+ bytes; expected a MaterialX document, at most 10 bytes$"):
        read_material_file(path)


def test_an_include_cycle_back_to_the_document_is_refused(tmp_path):
    path = _including(tmp_path, "main.mtlx", _material("M", "standard_surface", ""))
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value) == (f"{path.as_posix()}: field 'xi:include': expected no include cycle, got href "
                               "'main.mtlx' leading back to the document")  # fmt: skip


def test_an_include_cycle_through_another_file_names_the_href(tmp_path):
    """main includes a, a includes b, b includes a: MaterialX's "XInclude cycle detected." named no field or file."""
    inc = tmp_path / "inc"
    inc.mkdir()
    head = '<?xml version="1.0"?>\n<materialx version="1.39" xmlns:xi="http://www.w3.org/2001/XInclude">\n'
    (inc / "a.mtlx").write_text(f'{head}<xi:include href="b.mtlx" />\n</materialx>\n')
    (inc / "b.mtlx").write_text(f'{head}<xi:include href="a.mtlx" />\n</materialx>\n')
    path = _including(tmp_path, "inc/a.mtlx", _material("M", "standard_surface", ""))
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value) == (f"{(inc / 'b.mtlx').as_posix()}: field 'xi:include': expected no include cycle, got href "
                               f"'a.mtlx' leading back to {(inc / 'a.mtlx').as_posix()!r}")  # fmt: skip


def test_an_included_file_that_is_no_xml_names_the_document_that_includes_it(tmp_path):
    (tmp_path / "bin.mtlx").write_bytes(bytes(range(256)) * 8)
    path = _including(tmp_path, "bin.mtlx", _material("M", "standard_surface", ""))
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert (
        str(info.value) == f"{(tmp_path / 'bin.mtlx').as_posix()}: expected UTF-8 MaterialX XML (included by {path.as_posix()})"
    )


@pytest.mark.parametrize(("tag", "field", "expected"), [
    # MaterialX's getMaterialNodes took any node of type material: each baked as a material (exit 0), without the
    # nodedef MaterialX would need to shade it.
    ('<SurfaceMaterial name="M" type="material">', "M", "expected a surfacematerial node, got <SurfaceMaterial> of "
     "type material, which atlasgen does not bake"),
    ('<not_a_node name="M" type="material">', "M", "expected a surfacematerial node, got <not_a_node>"),
    # The only surfacematerial, of another type, was refused as "expected at least one surfacematerial node, found none".
    ('<surfacematerial name="M" type="surfaceshader">', "M.type", "expected 'material', got 'surfaceshader'"),
])  # fmt: skip
def test_a_material_node_is_a_surfacematerial_of_type_material(tmp_path, tag, field, expected):
    close = f"</{tag[1:].split()[0]}>"
    body = _material("M", "standard_surface", "").replace('<surfacematerial name="M" type="material">', tag)
    path = _document(tmp_path, body.replace("</surfacematerial>", close))
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value).startswith(f"{path.as_posix()}: field '{field}': {expected}"), str(info.value)


@pytest.mark.parametrize("element", [
    '<nodegraph name="NG_mine" nodedef="ND_standard_surface_surfaceshader"><surface_unlit name="u" type="surfaceshader" />'
    '<output name="out" type="surfaceshader" nodename="u" /></nodegraph>',
    '<implementation name="IM_mine" nodedef="ND_standard_surface_surfaceshader" target="genglsl" file="mine.glsl" '
    'function="mine" />',
])  # fmt: skip
def test_a_document_s_own_implementation_of_a_library_node_is_refused(tmp_path, element):
    """MaterialX's generator shaded the document's graph (an unlit surface) for standard_surface, and the oracle the
    library's: the bake was not MaterialX's shader of the document, and nothing said so."""
    path = _document(tmp_path, _material("M", "standard_surface", "") + "\n" + element)
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    name = "NG_mine" if "nodegraph" in element else "IM_mine"
    assert str(info.value).startswith(f"{path.as_posix()}: field '{name}.nodedef': expected no implementation of the "
                                      "standard libraries' ND_standard_surface_surfaceshader")  # fmt: skip


@pytest.mark.parametrize("kind", ["a named pipe", "a directory"])
def test_an_included_pipe_or_folder_is_refused_not_waited_on(tmp_path, kind):
    import os

    target = tmp_path / "inc.mtlx"
    if kind == "a named pipe":
        os.mkfifo(target)
    else:
        target.mkdir()
    path = _including(tmp_path, "inc.mtlx", _material("M", "standard_surface", ""))
    with pytest.raises(InputError) as info:
        read_material_file(path)
    expected = f"expected a regular file, got {'a named pipe' if kind == 'a named pipe' else 'a folder'}"
    assert str(info.value) == f"{target.as_posix()}: {expected} (included by {path.as_posix()})"


def test_a_material_s_back_surface_and_displacement_are_named_not_dropped(tmp_path):
    body = (_open('<input name="base_color" type="color3" value="0.5, 0.5, 0.5" />')
            .replace('nodename="SR_M" />', 'nodename="SR_M" /><input name="backsurfaceshader" type="surfaceshader" '
                     'nodename="SR_M" /><input name="displacementshader" type="displacementshader" nodename="D" />')
            + '\n<displacement name="D" type="displacementshader"><input name="displacement" type="float" value="0.3" />'
            "</displacement>")  # fmt: skip
    spec = read_material_file(_document(tmp_path, body))[0].params["materialx"]
    assert spec["not_in_table"] == [
        "backsurfaceshader = node 'SR_M': a back face is shaded with the front surface's slice (the renderer flips its normal)",
        "displacementshader = node 'D': displacement moves geometry, which an atlas slice does not hold",
    ]


@pytest.mark.parametrize(
    ("body", "field", "expected"),
    [
        (_open('<input name="specular_roughness_anisotropy" type="float" value="0.8" />'), "M.specular_roughness_anisotropy",
         "expected 0 where specular_weight > 0, got 0.8: an anisotropic lobe varies with the azimuth"),
        (_material("M", "gltf_pbr", '<input name="anisotropy_strength" type="float" value="0.5" />'), "M.anisotropy_strength",
         "expected 0, got 0.5: an anisotropic lobe"),
        (_open('<input name="specular_roughness" type="float" value="0" />'), "M.specular_roughness",
         "expected above 0 where specular_weight > 0, got 0: a mirror (a delta lobe), which no slice holds; give it a "
         "roughness, at least 0.045 for the renderer's sharpest lobe (alpha 0.002)"),
        # OpenPBR's coat is a mirror unless its roughness is given.
        (_open('<input name="coat_weight" type="float" value="1" />'), "M.coat_roughness",
         "expected above 0 where coat_weight > 0, got 0 (the nodedef's default): a mirror"),
    ],
)  # fmt: skip
def test_a_lobe_no_slice_holds_is_refused_naming_its_input(tmp_path, body, field, expected):
    path = _document(tmp_path, body)
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value).startswith(f"{path.as_posix()}: field '{field}': {expected}"), str(info.value)


def test_a_lobe_of_no_weight_or_at_the_least_roughness_reads(tmp_path):
    """A mirror or anisotropic lobe of weight 0 adds nothing; at 0.045 a lobe is as sharp as the renderer's."""
    body = "\n".join([
        _open('<input name="coat_weight" type="float" value="0" /><input name="coat_roughness" type="float" value="0" />'
              '<input name="specular_roughness" type="float" value="0.045" />'),
        _material("N", "open_pbr_surface", '<input name="specular_weight" type="float" value="0" />'
                  '<input name="specular_roughness_anisotropy" type="float" value="0.9" />'),
    ])  # fmt: skip
    materials = read_material_file(_document(tmp_path, body))
    assert [m.name for m in materials] == ["M", "N"]
    assert [m.params["materialx"]["sharp_lobes"] for m in materials] == [[], []]


def test_a_lobe_sharper_than_the_renderer_s_bakes_named_as_the_cause_of_its_error(tmp_path):
    """MaterialX's own OpenPBR car paint has a coat of roughness 0.02; USD's clear coat is 0.01 by default."""
    from atlasgen.bake.quality import assess_material

    body = "\n".join([
        _open('<input name="coat_weight" type="float" value="1" /><input name="coat_roughness" type="float" value="0.02" />'),
        _material("U", "UsdPreviewSurface", '<input name="clearcoat" type="float" value="0.5" />'),
    ])  # fmt: skip
    paint, usd = read_material_file(_document(tmp_path, body))
    clause = ": a lobe sharper than the renderer's sharpest (roughness 0.045, alpha 0.002), whose highlight falls between"
    assert paint.params["materialx"]["sharp_lobes"][0].startswith("coat_roughness = 0.02" + clause)
    assert usd.params["materialx"]["sharp_lobes"][0].startswith("clearcoatRoughness = 0.01 (the nodedef's default)" + clause)
    assert paint.params["materialx"]["not_in_table"] == paint.params["materialx"]["sharp_lobes"]
    (warning,) = assess_material(paint, {"errors_8bit": {"relative_rms": 1.3}})
    assert warning.cause == "unreachable fit" and warning.detail.startswith(
        "relative RMS error 130.0% of its stored factors > 20%: coat_roughness = 0.02: a lobe sharper"
    )


RESOURCES = Path(__file__).resolve().parents[1] / "resources" / "materialx"


@pytest.mark.parametrize("path", sorted(RESOURCES.glob("*.mtlx")), ids=lambda p: p.name)
def test_every_copy_of_materialx_s_examples_reads_or_is_refused_on_one_line(path):
    """Issue 23's library: our copies of the distribution's example materials (bench/materialx.py bakes them).
    A document reads whole, or its first material the atlas cannot take is refused on one line naming it."""
    try:
        materials = read_material_file(path)
    except MaterialError as exc:
        message = str(exc)
        assert "\n" not in message and message.startswith(f"{path.as_posix()}: field '"), message
        assert not path.name.startswith("examples"), message  # the baked library reads whole
    else:
        assert not path.name.startswith("refused") and materials


def test_the_baked_library_covers_all_four_surface_models():
    categories = {m.params["materialx"]["category"] for m in read_material_file(RESOURCES / "examples.mtlx")}
    assert categories == {"standard_surface", "open_pbr_surface", "gltf_pbr", "UsdPreviewSurface"}


@pytest.mark.parametrize(
    ("inputs", "field", "expected"),
    [
        ('<input name="specular" type="float" value="0" /><input name="metalness" type="float" value="1" />'
         '<input name="specular_anisotropy" type="float" value="0.65" />', "M.specular_anisotropy",
         "expected 0 where metalness > 0, got 0.65"),
        ('<input name="specular" type="float" value="0" /><input name="transmission" type="float" value="1" />'
         '<input name="specular_roughness" type="float" value="0" />', "M.specular_roughness",
         "expected above 0 where transmission > 0, got 0"),
    ],
)  # fmt: skip
def test_standard_surface_s_metal_and_transmission_share_the_specular_roughness(tmp_path, inputs, field, expected):
    """MaterialX's standard_surface shapes its metal and transmission lobes with specular_roughness and
    specular_anisotropy too: a lobe is weighted by metalness or transmission even where specular is 0."""
    path = _document(tmp_path, _material("M", "standard_surface", inputs))
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value).startswith(f"{path.as_posix()}: field '{field}': {expected}")


def test_an_input_declared_without_a_default_is_named_not_used(tmp_path):
    """glTF's normal, clearcoat_normal and attenuation_distance have no default value: the oracle never sets them."""
    body = _material("G", "gltf_pbr", '<input name="normal" type="vector3" value="0, 0, 1" />'
                     '<input name="attenuation_distance" type="float" value="100000" />')  # fmt: skip
    spec = read_material_file(_document(tmp_path, body))[0].params["materialx"]
    assert [line.split(":")[0] for line in spec["not_in_table"]] == ["normal = 0, 0, 1", "attenuation_distance = 100000"]
    assert spec["inputs"] == {} and spec["oracle_inputs"] == {}
    # Declared inputs keep their nodedef type and limits; an undeclared one is still unknown.
    with pytest.raises(MaterialError, match="field 'G.attenuation_distance': expected float at least 0"):
        read_material_file(_document(tmp_path, body.replace("100000", "-1")))
    with pytest.raises(MaterialError, match="field 'G.normal_map': unknown input of gltf_pbr"):
        read_material_file(_document(tmp_path, body.replace('"normal"', '"normal_map"')))


def test_the_module_s_doctests_pass():
    import doctest

    import atlasgen.materials.materialx_document as reader

    result = doctest.testmod(reader)
    assert result.attempted > 0 and result.failed == 0


_SHADOW = ('<nodedef name="ND_standard_surface_surfaceshader" node="standard_surface">'
           '<input name="base_color" type="color3" value="1, 0, 0" /><output name="out" type="surfaceshader" /></nodedef>')  # fmt: skip


@pytest.mark.parametrize("included", [False, True])
def test_an_element_named_as_a_standard_library_s_is_refused(tmp_path, included):
    """Importing the libraries keeps the document's own ND_standard_surface_surfaceshader: MaterialX then gives the
    node a red base_color by default, while the oracle shades the library's grey, and the bake was grey, exit 0."""
    body = _material("P", "standard_surface", "")
    if included:
        shadow = _document(tmp_path, _SHADOW, "defs.mtlx")
        path = _including(tmp_path, "defs.mtlx", body)
    else:
        shadow = path = _document(tmp_path, _SHADOW + "\n" + body)
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    message = str(info.value)
    assert message.endswith(": field 'ND_standard_surface_surfaceshader': expected no element named as one of "
                            "MaterialX's standard libraries' (they are loaded already, and the oracle shades theirs), got <nodedef> "
                            "'ND_standard_surface_surfaceshader'" + (f" (included by {path.as_posix()})" if included
                                                                      else "")), message  # fmt: skip
    assert shadow.name in message.split(": field")[0]


@pytest.mark.parametrize("included", [False, True])
def test_a_document_with_a_namespace_is_refused_naming_it(tmp_path, included):
    """MaterialX qualifies a namespaced document's names ('acme:red'); its validation failed on the standard
    library's own node graphs, and the line named an input 'in1' the document never had."""
    body = _material("red", "standard_surface", '<input name="base_color" type="color3" value="0.8, 0.1, 0.1" />')
    spaced = _document(tmp_path, body, "spaced.mtlx")
    spaced.write_text(spaced.read_text().replace('<materialx version="1.39">', '<materialx version="1.39" namespace="acme">'))
    path = _including(tmp_path, "spaced.mtlx") if included else spaced
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    # The file that has it is named; an included one with the file that included it, as docs/materialx.md says.
    assert str(info.value) == (f"{spaced.as_posix()}: field 'namespace': a document with a namespace ('acme') is not read: "
                               "MaterialX qualifies its materials' names as 'namespace:NAME', which an atlas name "
                               "cannot hold; expected the document without its namespace attribute"
                               + (f" (included by {path.as_posix()})" if included else ""))  # fmt: skip


def _chain(tmp_path, files: int):
    """main.mtlx including c1.mtlx, including c2.mtlx, ...: ``files`` files, ``files - 1`` nested includes."""
    for i in range(1, files):
        include = f'<xi:include href="c{i + 1}.mtlx" />' if i + 1 < files else ""
        (tmp_path / f"c{i}.mtlx").write_text('<?xml version="1.0"?>\n<materialx version="1.39" xmlns:xi="http://www.w3.org/'
                                             f'2001/XInclude">{include}<standard_surface name="S{i}" type="surfaceshader"/>'
                                             "</materialx>\n")  # fmt: skip
    return _including(tmp_path, "c1.mtlx", _material("M", "standard_surface", ""))


def test_includes_nested_as_deep_as_materialx_reads_and_no_deeper(tmp_path):
    """A chain of 1000 files was an internal error (RecursionError in the walk over the includes); MaterialX
    reads 256 nested includes and refuses 257 ("Maximum XInclude depth exceeded")."""
    (tmp_path / "ok").mkdir()
    (tmp_path / "deep").mkdir()
    assert [m.name for m in read_material_file(_chain(tmp_path / "ok", 257))] == ["M"]
    path = _chain(tmp_path / "deep", 1000)
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value) == (f"{(tmp_path / 'deep' / 'c256.mtlx').as_posix()}: field 'xi:include': expected includes "
                               "nested at most 256 deep (as MaterialX reads them), got a deeper chain at href 'c257.mtlx'")  # fmt: skip


def _diamond(tmp_path, levels: int):
    """main.mtlx including L0a.mtlx, each Li including both L(i+1)a and L(i+1)b: 2 levels files, 2^levels - 1
    inclusions, for MaterialX reads a file again on every path to it."""
    for i in range(levels):
        for side in "ab":
            includes = "".join(f'<xi:include href="L{i + 1}{s}.mtlx" />' for s in "ab") if i + 1 < levels else ""
            (tmp_path / f"L{i}{side}.mtlx").write_text('<?xml version="1.0"?>\n<materialx version="1.39" xmlns:xi="http:'
                                                       f'//www.w3.org/2001/XInclude">{includes}</materialx>\n')  # fmt: skip
    return _including(tmp_path, "L0a.mtlx", _material("M", "standard_surface", ""))


def test_files_included_along_exponentially_many_paths_are_refused_unread(tmp_path, monkeypatch):
    """48 files of 150 bytes in such a diamond ran for hours: MaterialX reads a file once per path to it."""
    import atlasgen.materials.materialx_document as module

    path = _diamond(tmp_path, 14)
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value) == (f"{path.as_posix()}: field 'xi:include': expected at most 1024 inclusions in all "
                               "(MaterialX reads a file again on every path that includes it), got 16383")  # fmt: skip
    (tmp_path / "small").mkdir()
    small = _diamond(tmp_path / "small", 4)  # 1 + 2 + 4 + 8
    monkeypatch.setattr(module, "MAX_INCLUSIONS", 14)
    with pytest.raises(MaterialError, match=r"expected at most 14 inclusions in all .*, got 15$"):
        read_material_file(small)
    monkeypatch.setattr(module, "MAX_INCLUSIONS", 15)
    assert [m.name for m in read_material_file(small)] == ["M"]


def test_a_value_written_as_the_element_s_text_is_refused_not_defaulted(tmp_path):
    """MaterialX reads only the value attribute: a roughness of 0 written as text baked at the default 0.2,
    past the refusal of a mirror, with exit 0 (found by a hostile sweep)."""
    body = _material("M", "standard_surface", '<input name="specular_roughness" type="float">0</input>'
                     '<input name="metalness" type="float" value="1" />')  # fmt: skip
    path = _document(tmp_path, body)
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value) == (f"{path.as_posix()}: field 'SR_M.specular_roughness': expected the value in a value "
                               "attribute (value=\"0\"), got it as the element's text, which MaterialX ignores")  # fmt: skip
    spaced = _material("M", "standard_surface", '<input name="metalness" type="float" value="1">\n  </input>')
    assert read_material_file(_document(tmp_path, spaced, "ok.mtlx"))[0].params["materialx"]["inputs"] == {"metalness": 1.0}


@pytest.mark.parametrize(("mode", "alpha", "named"), [
    (None, 0.2, []),  # OPAQUE, the default: the graph shades it opaque whatever its alpha
    (0, 0.2, []),
    (1, 0.7, []),  # MASK, alpha at or above the cutoff (0.5): opaque
    (1, 0.2, ["alpha"]),  # MASK below it: invisible
    (2, 0.2, ["alpha"]),  # BLEND
])  # fmt: skip
def test_a_gltf_alpha_is_named_only_where_the_graph_shades_it(tmp_path, mode, alpha, named):
    """An OPAQUE glTF material's alpha was named as lost opacity, which --strict failed (a hostile sweep)."""
    inputs = f'<input name="alpha" type="float" value="{alpha}" />'
    if mode is not None:
        inputs += f'<input name="alpha_mode" type="integer" value="{mode}" />'
    spec = read_material_file(_document(tmp_path, _material("M", "gltf_pbr", inputs)))[0].params["materialx"]
    assert [line.split(" =")[0] for line in spec["not_in_table"]] == named


@pytest.mark.parametrize("mode", [-1, 3, 9])
def test_an_enumerated_integer_beyond_its_values_is_refused(tmp_path, mode):
    """glTF's alpha_mode enumerates 0, 1, 2 and sets no uimin or uimax: 9 baked without a word."""
    path = _document(tmp_path, _material("M", "gltf_pbr", f'<input name="alpha_mode" type="integer" value="{mode}" />'))
    with pytest.raises(MaterialError, match=rf"field 'M.alpha_mode': expected integer within 0 .. 2 .*, got {mode}$"):
        read_material_file(path)


def test_a_bad_value_in_an_included_file_names_that_file(tmp_path):
    """Found by a hostile sweep: a value out of range in an included file was refused naming the including document,
    which holds no such field."""
    lib = _document(tmp_path, _material("velvet", "standard_surface",
                                        '<input name="base_color" type="color3" value="2.25, 0.06, 0.05" />'))  # fmt: skip
    path = _including(tmp_path, "lib.mtlx")
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value).startswith(f"{lib.as_posix()}: field 'velvet.base_color': expected color3 within"), info.value


@pytest.mark.parametrize("element", [
    # A 1.37 document's forms, which MaterialX upgrades to inputs as it reads them, their text dropped.
    '<material name="M"><shaderref name="sr" node="standard_surface">'
    '<bindinput name="specular_roughness" type="float">0</bindinput></shaderref></material>',
    '<standard_surface name="SR_M" type="surfaceshader"><parameter name="specular_roughness" type="float">0</parameter>'
    '</standard_surface><surfacematerial name="M" type="material">'
    '<input name="surfaceshader" type="surfaceshader" nodename="SR_M" /></surfacematerial>',
])  # fmt: skip
def test_a_1_37_value_written_as_text_is_refused_not_defaulted(tmp_path, element):
    """A hostile sweep's: a mirror written as a <bindinput>'s or <parameter>'s text baked at the default roughness."""
    path = tmp_path / "old.mtlx"
    path.write_text(f'<?xml version="1.0"?>\n<materialx version="1.37">\n{element}\n</materialx>\n')
    with pytest.raises(
        MaterialError,
        match=r"\.specular_roughness': expected the value in a value attribute "
        r"\(value=\"0\"\), got it as the element's text, which MaterialX ignores$",
    ):
        read_material_file(path)


def test_a_child_of_the_shader_that_materialx_does_not_read_as_an_input_is_refused(tmp_path):
    """A hostile sweep's: a 1.39 document's <parameter value="0"> is no input to MaterialX, and baked the default."""
    path = _document(tmp_path, _material("M", "standard_surface", '<parameter name="specular_roughness" type="float" '
                                         'value="0" />'))  # fmt: skip
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value) == (f"{path.as_posix()}: field 'SR_M.specular_roughness': expected an <input> element, got "
                               "<parameter>, which MaterialX does not read as an input of the node")  # fmt: skip
    old = tmp_path / "old.mtlx"  # in 1.37 the same element is an input, and is baked
    old.write_text(path.read_text().replace('version="1.39"', 'version="1.37"').replace('value="0"', 'value="0.3"'))
    assert read_material_file(old)[0].params["materialx"]["inputs"] == {"specular_roughness": pytest.approx(0.3)}


def test_a_usd_tangent_space_normal_is_named_and_the_geometry_s_is_shaded(tmp_path):
    """A hostile sweep's: a tilted normal made the oracle's f cos vary with the azimuth and baked without a word."""
    path = _document(tmp_path, _material("M", "UsdPreviewSurface", '<input name="normal" type="vector3" '
                                         'value="0.2, 0, 0.98" />'))  # fmt: skip
    spec = read_material_file(path)[0].params["materialx"]
    assert spec["oracle_inputs"]["normal"] == [0.0, 0.0, 1.0]
    assert [c.split(":")[0] for c in spec["not_in_table"]] == ["normal = 0.2, 0, 0.98"]
    untilted = _document(tmp_path, _material("M", "UsdPreviewSurface", '<input name="normal" type="vector3" '
                                             'value="0, 0, 1" />'), "flat.mtlx")  # fmt: skip
    assert read_material_file(untilted)[0].params["materialx"]["not_in_table"] == []


def test_a_value_at_the_nodedef_s_limit_reads_as_within_it(tmp_path):
    """A hostile sweep's: 6.283185, glTF's uimax for anisotropy_rotation, read as a float32 above the same text read
    as a double, and was refused "within 0 .. 6.283185, got 6.283185"."""
    path = _document(tmp_path, _material("M", "gltf_pbr", '<input name="anisotropy_rotation" type="float" '
                                         'value="6.283185" />'))  # fmt: skip
    assert read_material_file(path)[0].params["materialx"]["inputs"]["anisotropy_rotation"] == pytest.approx(6.283185)


def test_a_shader_s_refusal_in_an_included_file_names_the_document_that_includes_it(tmp_path):
    """A hostile sweep's: a mirror in an included file named that file alone."""
    _document(tmp_path, _material("B", "standard_surface", '<input name="specular_roughness" type="float" value="0" />'),
              "inc.mtlx")  # fmt: skip
    path = _including(tmp_path, "inc.mtlx")
    with pytest.raises(MaterialError) as info:
        read_material_file(path)
    assert str(info.value).startswith(f"{(tmp_path / 'inc.mtlx').as_posix()}: field 'B.specular_roughness': expected ")
    assert str(info.value).endswith(f" (included by {path.as_posix()})")
