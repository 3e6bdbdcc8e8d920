"""A non-editable install works outside the source tree: every command, on the installed data.

The wheel is built from a copy of the source tree (setuptools writes ``build/`` beside the
sources, which is the Makefile's output folder here) without build isolation, so nothing
is downloaded. It is installed into a fresh virtual environment that sees this one's
packages only through a ``.pth`` path line: that makes the dependencies importable while
this environment's editable install of atlasgen (a ``.pth`` import hook, which a path line
does not run) stays out. Each command then runs from an empty folder.
"""

from __future__ import annotations

import os
import shutil
import site
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

# One process for the module: its wheel and environment are built once.
pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("install")]

ROOT = Path(__file__).resolve().parents[1]
#: Files the wheel must hold besides the code: what the commands read at run time.
PACKAGE_DATA = ["atlasgen/data/materials/terracotta.toml", "atlasgen/data/materials/separable-gold.toml",
                "atlasgen/data/validation/front.toml", "atlasgen/data/validation/back.toml",
                "atlasgen/shaders/lighting.wgsl", "atlasgen/data/lighting_cost.json",
                "atlasgen/data/preview/atlasgen-preview-floor.toml"]  # fmt: skip
SCENE = """
[camera]
position = [0, 0, 4]
target = [0, 0, 0]
[image]
width = 32
height = 24
[[lights]]
type = "directional"
direction = [0, 0, -1]
intensity = 3.0
[[objects]]
shape = "sphere"
material = "terracotta"
"""


def _run(args, cwd, check=True) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    result = subprocess.run([str(a) for a in args], cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
    if check:
        assert result.returncode == 0, f"{args}: exit {result.returncode}\n{result.stdout}\n{result.stderr}"
    return result


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("wheel")
    source = root / "source"
    shutil.copytree(ROOT, source, symlinks=True, ignore=shutil.ignore_patterns(
        ".git", ".venv", "build", "dist", "__pycache__", "*.egg-info", ".pytest_cache", ".hypothesis"))  # fmt: skip
    result = _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index", "-v",
                   "-w", root / "dist", source], cwd=root)  # fmt: skip
    # Setuptools' complaints about the licence fields or about data folders that are not listed as packages.
    assert "SetuptoolsDeprecationWarning" not in result.stdout + result.stderr
    assert "absent from the `packages` configuration" not in result.stdout + result.stderr
    [built] = (root / "dist").glob("atlasgen-*.whl")
    return built


@pytest.fixture(scope="module")
def installed(wheel, tmp_path_factory) -> Path:
    """The ``bin`` folder of a fresh environment with the wheel installed."""
    env = tmp_path_factory.mktemp("env") / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", env], cwd=env.parent)
    [site_packages] = env.glob("lib/python*/site-packages")
    (site_packages / "atlasgen-test-dependencies.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    _run([sys.executable, "-m", "pip", "--python", env / "bin" / "python", "install", "--no-deps", "--no-index", wheel],
         cwd=env.parent)  # fmt: skip
    return env / "bin"


@pytest.fixture(scope="module")
def workdir(tmp_path_factory) -> Path:
    """An empty folder: no materials/, no scenes/, nothing of the source tree."""
    return tmp_path_factory.mktemp("work")


@pytest.fixture(scope="module")
def baked(installed, workdir, shipped_library_cache) -> Path:
    # The installed code hashes as the source tree does, so the session's cache of the library
    # serves it: what is tested here is the installed command and data, not the fits again.
    _run(
        [installed / "atlasgen", "bake", "--library", "-o", "build/atlas.dds", "-q", "--cache", shipped_library_cache],
        cwd=workdir,
    )
    return workdir / "build" / "atlas.dds"


def test_the_wheel_holds_the_data_the_licence_and_the_entry_point(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    assert all(name in names for name in PACKAGE_DATA), sorted(set(PACKAGE_DATA) - set(names))
    shipped = sorted(p.name for pattern in ("*.toml", "*.mtlx") for p in (ROOT / "materials").glob(pattern))
    assert sorted(n.rsplit("/", 1)[1] for n in names if n.startswith("atlasgen/data/materials/")) == shipped
    info = next(n.split("/")[0] for n in names if n.endswith(".dist-info/METADATA"))
    assert f"{info}/licenses/LICENSE" in names and "atlasgen/__main__.py" in names
    metadata = zipfile.ZipFile(wheel).read(f"{info}/METADATA").decode()
    assert "License-Expression: Apache-2.0" in metadata.splitlines()


def test_the_installed_package_is_imported_not_the_source_tree(installed, workdir):
    result = _run([installed / "python", "-c", "import atlasgen.cli.main as m; print(m.__file__)"], cwd=workdir)
    assert Path(result.stdout.strip()).is_relative_to(installed.parent)
    help_text = _run([installed / "python", "-m", "atlasgen"], cwd=workdir).stdout
    assert help_text.startswith("Usage: atlasgen [OPTIONS] [COMMAND] [ARGS]...")


def test_bake_library_from_an_empty_folder(baked):
    assert [p.name for p in sorted(baked.parent.iterdir()) if not p.name.endswith(".atlasgen")] == [
        "atlas.dds",
        "atlas.glsl",
        "atlas.hlsl",
        "atlas.json",
        "atlas.separable.bin",
        "atlas.timings.json",
        "atlas.wgsl",
    ]
    assert "MATERIAL_TERRACOTTA" in baked.with_suffix(".wgsl").read_text()


def test_render(installed, workdir, baked):
    (workdir / "scene.toml").write_text(SCENE)
    result = _run([installed / "atlasgen", "render", "scene.toml", "--atlas", baked, "-o", "out.exr"], cwd=workdir, check=False)
    if result.returncode == 5:
        pytest.skip(f"no GPU adapter: {result.stderr.strip()}")
    assert result.returncode == 0, result.stderr
    assert (workdir / "out.exr").stat().st_size > 0 and (workdir / "out.png").stat().st_size > 0


def test_preview_with_the_installed_floor(installed, workdir):
    (workdir / "clay.toml").write_text('type = "lambert"\n')
    result = _run([installed / "atlasgen", "preview", "clay.toml", "--no-cache"], cwd=workdir, check=False)
    if result.returncode == 5:
        pytest.skip(f"no GPU adapter: {result.stderr.strip()}")
    assert result.returncode == 0, result.stderr
    assert (workdir / "build" / "preview" / "clay.png").read_bytes().startswith(b"\x89PNG")


def test_validate_on_the_installed_scenes(installed, workdir, baked):
    result = _run([installed / "atlasgen", "validate", "terracotta", "--scene", "front", "--resolution", "24x18",
                   "--no-physical", "--atlas", baked, "-o", "validation", "--strict"], cwd=workdir, check=False)  # fmt: skip
    if result.returncode == 5:
        pytest.skip(f"a backend is missing: {result.stderr.strip()}")
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("terracotta: storage goals met; storage 1/1 met")
    assert (workdir / "validation" / "report.json").is_file() and (workdir / "validation" / "index.html").is_file()


def test_report_library(installed, workdir, baked):
    # The physical Pareto charts measure every material against Mitsuba (minutes of CPU), which
    # tests/test_library_report.py checks from the source tree; what the installed command adds
    # is its data, so the cost table it charts with is read here from the installed package.
    result = _run([installed / "atlasgen", "report", "library", "--atlas", baked, "-o", "report", "--no-physical"], cwd=workdir)
    assert result.stdout.strip() == "report/index.html"
    assert (workdir / "report" / "index.html").stat().st_size > 0
    assert "Not measured on this page" in (workdir / "report" / "index.html").read_text()  # and says so
    code = "from atlasgen.separable.auto import read_lighting_cost as r; import atlasgen; print(atlasgen.__file__, r().device)"
    where, device = _run([installed / "python", "-c", code], cwd=workdir).stdout.split(" ", 1)
    assert Path(where).is_relative_to(installed.parent) and device.strip()
