"""Golden files: the shipped library bakes to the same bytes as the committed atlas, manifest and include.

A deliberate change to the bytes regenerates them with ``ATLASGEN_REGENERATE_GOLDEN=1 pytest
tests/test_golden.py`` and says why in the commit; an accidental one fails here.
"""

from __future__ import annotations

import gzip
import hashlib
import os
import shutil
import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app
from atlasgen.io.manifest import read_manifest

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = Path(__file__).parent / "resources" / "golden"
REGENERATE = os.environ.get("ATLASGEN_REGENERATE_GOLDEN") == "1"

#: Where the golden outputs are baked, relative to a copy of materials/ (as build/ is in the repository).
GOLDEN_BUILD = "build"
#: variant -> extra bake options
VARIANTS = {"array-srgb": [], "volume-linear": ["--layout", "volume", "--linear"]}


def _golden_name(variant: str, suffix: str) -> str:
    return f"{variant}{suffix}.gz" if suffix == ".dds" else f"{variant}{suffix}"


@pytest.mark.slow
@pytest.mark.usefixtures("mitsuba_llvm")  # materials/separable-gold.toml has a Mitsuba source
@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_the_shipped_library_bakes_to_the_golden_bytes(variant, tmp_path, monkeypatch):
    # The manifest stores each material file relative to its own folder, so the bake mirrors
    # the repository's layout (materials/ beside build/) under tmp_path: the sources read
    # ../materials/<name>.toml wherever pytest's tmp_path is. Run from another folder with
    # absolute arguments, to show the bytes depend on neither.
    shutil.copytree(ROOT / "materials", tmp_path / "materials")
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    out = tmp_path / GOLDEN_BUILD / f"{variant}.dds"
    res = CliRunner().invoke(app, ["bake", str(tmp_path / "materials"), "-o", str(out), "-q", *VARIANTS[variant]])
    assert res.exit_code == 0, res.output
    for suffix in (".dds", ".json", ".wgsl", ".glsl", ".hlsl", ".separable.bin"):
        produced = out.with_name(out.stem + suffix).read_bytes()
        golden = GOLDEN / _golden_name(variant, suffix)
        if REGENERATE:
            GOLDEN.mkdir(parents=True, exist_ok=True)
            golden.write_bytes(gzip.compress(produced, mtime=0) if suffix == ".dds" else produced)
            continue
        expected = golden.read_bytes()
        if suffix == ".dds":
            expected = gzip.decompress(expected)
        assert produced == expected, f"{variant}{suffix} differs from {golden.relative_to(ROOT)}"


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
