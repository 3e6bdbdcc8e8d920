"""Golden files: the shipped library bakes to the committed atlas, manifest, includes and side-car.

Bytes that NumPy computes are compared byte for byte. Bytes that passed through Mitsuba's JIT (the
materials ``VERSIONS.json`` lists, found when the goldens were made by baking each material with
Mitsuba hidden) are compared within :mod:`tests.golden_compare`'s stated tolerance, and byte for
byte as well when this machine has the versions the goldens were generated with
(``VERSIONS.json``, which ``make setup``'s pins install).

A deliberate change to the bytes regenerates them with ``ATLASGEN_REGENERATE_GOLDEN=1 pytest
tests/test_golden.py`` (``make pins`` does so after moving the pins) and says why in the commit;
an accidental one fails here.
"""

from __future__ import annotations

import functools
import gzip
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app
from atlasgen.io.manifest import read_manifest
from tests import golden_compare

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = Path(__file__).parent / "resources" / "golden"
VERSIONS = GOLDEN / "VERSIONS.json"
REGENERATE = os.environ.get("ATLASGEN_REGENERATE_GOLDEN") == "1"

#: Where the golden outputs are baked, relative to a copy of materials/ (as build/ is in the repository).
GOLDEN_BUILD = "build"
#: variant -> extra bake options
VARIANTS = {"array-srgb": [], "volume-linear": ["--layout", "volume", "--linear"]}
SUFFIXES = (".dds", ".json", ".wgsl", ".glsl", ".hlsl", ".separable.bin")

#: Run in a fresh interpreter with Mitsuba and Dr.Jit hidden: prints the names of the materials
#: whose bake needs them (a fresh process, so that no module holds Mitsuba from an earlier import).
_PROBE = """
import json, sys
sys.modules["mitsuba"] = sys.modules["drjit"] = None
from pathlib import Path
from atlasgen.bake.adaptive import bake_material
from atlasgen.errors import AtlasgenError
from atlasgen.materials.material import read_material
needs = []
for path in sorted(Path(sys.argv[1]).glob("*.toml")):
    try:
        bake_material(read_material(path))
    except (AtlasgenError, ImportError):
        needs.append(path.stem)
print(json.dumps(needs))
"""


def _golden_name(variant: str, suffix: str) -> str:
    return f"{variant}{suffix}.gz" if suffix == ".dds" else f"{variant}{suffix}"


@functools.cache  # both variants regenerate VERSIONS.json: probe the library once
def jit_materials_of(folder: Path) -> list[str]:
    """The materials in ``folder`` whose slices pass through Mitsuba's JIT: they cannot bake without it."""
    result = subprocess.run([sys.executable, "-c", _PROBE, str(folder)], capture_output=True, text=True, check=True)
    return json.loads(result.stdout)


def _differences(outputs: dict[str, bytes], expected: dict[str, bytes], jit: list[str]) -> list[str]:
    manifest, golden_manifest = json.loads(outputs[".json"]), json.loads(expected[".json"])
    problems = golden_compare.check_links(outputs)
    for suffix in SUFFIXES:
        if suffix == ".dds":
            found = golden_compare.compare_dds(outputs[suffix], expected[suffix], golden_compare.jit_slices(golden_manifest, jit))
        elif suffix == ".json":
            found = golden_compare.compare_manifest(manifest, golden_manifest, jit)
        elif suffix == ".separable.bin":
            found = golden_compare.compare_sidecar(outputs[suffix], expected[suffix])
        else:
            found = golden_compare.compare_text(outputs[suffix].decode(), expected[suffix].decode())
        problems += [f"{suffix}: {p}" for p in found[:5]]
    return problems


@pytest.mark.slow
@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_the_shipped_library_bakes_to_the_golden_bytes(variant, tmp_path, monkeypatch, shipped_library_cache):
    # The manifest stores each material file relative to its own folder, so the bake mirrors
    # the repository's layout (materials/ beside build/) under tmp_path: the sources read
    # ../materials/<name>.toml wherever pytest's tmp_path is. Run from another folder with
    # absolute arguments, to show the bytes depend on neither. The slices come from the
    # session's cache of the same files (a cached bake is the bake: tests/test_cache.py).
    # The goldens hold the TOML library: a MaterialX document's texels come from its GLSL on Mesa's
    # llvmpipe, which the goldens' versions do not pin (tests/separable/test_materialx_oracle.py
    # holds the oracle to closed forms instead).
    shutil.copytree(ROOT / "materials", tmp_path / "materials", ignore=shutil.ignore_patterns("*.mtlx"))
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    out = tmp_path / GOLDEN_BUILD / f"{variant}.dds"
    args = ["bake", str(tmp_path / "materials"), "-o", str(out), "-q", "--cache", str(shipped_library_cache), *VARIANTS[variant]]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    outputs = {suffix: out.with_name(out.stem + suffix).read_bytes() for suffix in SUFFIXES}
    here = golden_compare.jit_environment()
    if REGENERATE:
        GOLDEN.mkdir(parents=True, exist_ok=True)
        for suffix, produced in outputs.items():
            golden = GOLDEN / _golden_name(variant, suffix)
            golden.write_bytes(gzip.compress(produced, mtime=0) if suffix == ".dds" else produced)
        record = {"generated_with": here, "jit_materials": jit_materials_of(ROOT / "materials")}
        VERSIONS.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
        return
    record = json.loads(VERSIONS.read_text())
    expected = {}
    for suffix in SUFFIXES:
        data = (GOLDEN / _golden_name(variant, suffix)).read_bytes()
        expected[suffix] = gzip.decompress(data) if suffix == ".dds" else data
    made_with = golden_compare.describe(record["generated_with"])
    problems = _differences(outputs, expected, record["jit_materials"])
    assert not problems, (
        f"{variant} differs from its goldens (made with {made_with}; here {golden_compare.describe(here)}):\n"
        + "\n".join(problems)
    )
    if here == record["generated_with"]:
        for suffix in SUFFIXES:
            assert outputs[suffix] == expected[suffix], (
                f"{variant}{suffix} is not byte-identical under the goldens' versions ({made_with})"
            )


def test_the_goldens_name_the_versions_and_the_jit_materials_they_were_made_with():
    record = json.loads(VERSIONS.read_text())
    assert set(record["generated_with"]) == {"packages", "libllvm", "cpu"}
    names = {e.name for e in read_manifest(GOLDEN / "array-srgb.json").materials}
    assert record["jit_materials"] and set(record["jit_materials"]) < names
    # The pins install the versions the goldens were made with.
    pins = dict(line.split("==") for line in (ROOT / "constraints.txt").read_text().splitlines() if "==" in line)
    lower = {k.lower(): v for k, v in pins.items()}
    assert all(lower.get(name) == v for name, v in record["generated_with"]["packages"].items()), (record, "constraints.txt")


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_every_entry_keeps_its_material_file_in_source(variant):
    # Format v2: a model's own fields never replace the entry's `source`; a separable
    # entry's factored BRDF is `brdf_source` (v1 let it overwrite `source`).
    manifest = read_manifest(GOLDEN / f"{variant}.json")
    for entry in manifest.materials:
        # Relative to the manifest's folder (format v3), baked as build/ beside materials/.
        assert entry.source.startswith("../materials/") and "\\" not in entry.source, entry.source
        path = Path(os.path.normpath(ROOT / GOLDEN_BUILD / entry.source))
        assert path.is_file() and path.suffix == ".toml", (entry.name, entry.source)
        assert path.parent == ROOT / "materials" and path.stem == entry.name, (entry.name, entry.source)
        assert hashlib.sha256(path.read_bytes()).hexdigest() == entry.content_hash, entry.name
        if entry.factors is not None:
            toml = tomllib.loads(path.read_text(encoding="utf-8"))
            assert entry.factors.brdf_source == toml.get("source", "ggx"), entry.name
            assert "source" not in entry.extra
    assert sum(e.factors is not None for e in manifest.materials) == 4
