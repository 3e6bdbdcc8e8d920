"""`atlasgen bake X.mtlx` end to end: the manifest names the document and the material, and the library page shows it."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("MaterialX")
pytest.importorskip("moderngl")

pytestmark = pytest.mark.slow  # the oracle compiles and fits for seconds

DOCUMENT = """<?xml version="1.0"?>
<materialx version="1.39">
  <standard_surface name="SR_matte" type="surfaceshader">
    <input name="base_color" type="color3" value="0.5, 0.4, 0.3" />
    <input name="specular" type="float" value="0.0" />
    <input name="emission" type="float" value="0.5" />
  </standard_surface>
  <surfacematerial name="Matte" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="SR_matte" />
  </surfacematerial>
</materialx>
"""


def test_bake_a_document_and_report_it(tmp_path, monkeypatch):
    from atlasgen.cli.main import main
    from atlasgen.reports.library import write_library_report

    monkeypatch.chdir(tmp_path)
    (tmp_path / "lib.mtlx").write_text(DOCUMENT)
    with pytest.raises(SystemExit) as done:
        main(["bake", "lib.mtlx", "-o", "out/X.dds", "-q"])
    assert done.value.code in (0, None)
    (entry,) = json.loads((tmp_path / "out" / "X.json").read_text())["materials"]
    assert entry["name"] == "Matte" and entry["source"].endswith("lib.mtlx") and entry["type"] == "separable"
    spec = entry["params"]["materialx"]
    assert spec["material"] == "Matte" and spec["category"] == "standard_surface"
    assert spec["not_in_table"] == ["emission = 0.5: emission"]
    assert entry["representation"]["kind"] == "lut"  # a Lambertian: one slice is cheapest within the budget
    page = write_library_report(tmp_path / "out" / "X.dds", tmp_path / "report", physical=False).read_text()
    section = page[page.index("Imported from MaterialX") :]
    assert "lib.mtlx" in section and "standard_surface" in section and "emission = 0.5: emission" in section
    assert "± " in section  # the error against the oracle with its standard error


def test_a_document_bakes_to_the_same_bytes_from_any_working_folder(tmp_path, monkeypatch):
    """The manifest's ``params.materialx.document`` held the path as given (``lib/lib.mtlx`` from the
    parent, ``lib.mtlx`` from the folder), so the outputs depended on where atlasgen ran; the name
    alone is kept (``source`` locates the file), and the content hash, keyed on it, is the same too:
    the second bake, from the other folder, loads from the cache."""
    from atlasgen.cli.main import main

    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "lib.mtlx").write_text(DOCUMENT)
    cache = str(tmp_path / "cache")
    for folder, document, out in ((tmp_path, "lib/lib.mtlx", "a/X.dds"), (tmp_path / "lib", "lib.mtlx", "../b/X.dds")):
        monkeypatch.chdir(folder)
        with pytest.raises(SystemExit) as done:
            main(["bake", document, "-o", out, "-q", "--cache", cache])
        assert done.value.code in (0, None)
    for suffix in (".dds", ".json", ".wgsl", ".glsl", ".hlsl"):
        assert (tmp_path / "a" / f"X{suffix}").read_bytes() == (tmp_path / "b" / f"X{suffix}").read_bytes(), suffix
    assert json.loads((tmp_path / "a" / "X.json").read_text())["materials"][0]["params"]["materialx"]["document"] == "lib.mtlx"
