"""The same material files bake to the same bytes from any working directory, with relative or
absolute arguments in any order: the manifest stores each material file relative to its own
folder, and no absolute path leaks in."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app
from atlasgen.io.atlas import describe_atlas, read_atlas

SUFFIXES = (".dds", ".json", ".wgsl", ".glsl", ".hlsl")
NAMES = ("zinc", "amber", "moss")


def _bake(cwd: Path, args: list[str], monkeypatch) -> None:
    monkeypatch.chdir(cwd)
    res = CliRunner().invoke(app, ["bake", *args, "-q"])
    assert res.exit_code == 0, res.output


@pytest.mark.slow
def test_the_bytes_depend_on_neither_the_working_directory_nor_the_arguments(tmp_path, monkeypatch):
    project = tmp_path / "project"
    (project / "materials").mkdir(parents=True)
    for name in NAMES:
        (project / "materials" / f"{name}.toml").write_text('type = "lambert"\ncolour = [0.3, 0.4, 0.5]\n')
    (tmp_path / "elsewhere" / "deeper").mkdir(parents=True)
    relative = [f"materials/{n}.toml" for n in NAMES]
    runs = {
        "from the project, relative": (project, [*relative, "-o", "build-a/atlas.dds"]),
        "from its parent, a folder": (tmp_path, ["project/materials", "-o", "project/build-b/atlas.dds"]),
        "from elsewhere, absolute, reversed": (tmp_path / "elsewhere" / "deeper",
                                               [*(str(project / p) for p in relative[::-1]), "-o", str(project / "build-c" / "atlas.dds")]),
        "from elsewhere, relative with ..": (tmp_path / "elsewhere", [*(f"../project/{p}" for p in relative[1:] + relative[:1]),
                                                                       "-o", "../project/build-d/atlas.dds"]),
    }  # fmt: skip
    outputs = {}
    for what, (cwd, args) in runs.items():
        _bake(cwd, args, monkeypatch)
        out = Path(os.path.normpath(cwd / args[-1]))
        outputs[what] = [out.with_suffix(s).read_bytes() for s in SUFFIXES]
    first = next(iter(outputs.values()))
    for what, files in outputs.items():
        assert files == first, what
    manifest = json.loads(first[1])
    assert [m["source"] for m in manifest["materials"]] == [f"../materials/{n}.toml" for n in sorted(NAMES)]
    assert str(tmp_path).encode() not in b"".join(first)
    # IDs follow the names, not the order given.
    assert [(m["name"], m["id"]) for m in manifest["materials"]] == [("amber", 0), ("moss", 1), ("zinc", 2)]


def test_readers_resolve_sources_against_the_manifests_folder(tmp_path, monkeypatch):
    project = tmp_path / "project"
    (project / "materials").mkdir(parents=True)
    (project / "materials" / "clay.toml").write_text('type = "lambert"\n')
    _bake(project, ["materials/clay.toml", "-o", "build/atlas.dds"], monkeypatch)
    monkeypatch.chdir(tmp_path)
    atlas = read_atlas("project/build/atlas.dds")
    entry = atlas.material("clay")
    assert entry.source == "../materials/clay.toml"
    assert atlas.source_path(entry) == Path("project/materials/clay.toml") and atlas.source_path(entry).is_file()
    assert "from project/materials/clay.toml" in describe_atlas("project/build/atlas.dds", verbose=True)
    # A material file named on the command line is matched by its content hash.
    res = CliRunner().invoke(app, ["validate", "project/materials/clay.toml", "--atlas", "project/build/atlas.dds",
                                   "--scene", "nonexistent", "-o", "out"])  # fmt: skip
    assert "changed since" not in res.output and "is not in" not in res.output, res.output
    assert res.exit_code != 0 and "nonexistent" in res.output, res.output  # it got as far as the scenes


def test_a_symlinked_output_folder_gives_the_real_folders_bytes_and_sources(tmp_path, monkeypatch):
    # The link sits deeper than its target: a ``..`` counted from the link's own path would
    # name another file, and the manifest's bytes would depend on the route to the folder.
    project = tmp_path / "project"
    (project / "materials").mkdir(parents=True)
    (project / "materials" / "clay.toml").write_text('type = "lambert"\n')
    (project / "build").mkdir()
    (tmp_path / "a" / "b" / "c").mkdir(parents=True)
    link = tmp_path / "a" / "b" / "c" / "build"
    link.symlink_to(project / "build", target_is_directory=True)
    _bake(project, ["materials/clay.toml", "-o", "build/atlas.dds"], monkeypatch)
    real = [(project / "build" / f"atlas{s}").read_bytes() for s in SUFFIXES]
    _bake(tmp_path, ["project/materials/clay.toml", "-o", str(link / "linked.dds")], monkeypatch)
    linked = [(project / "build" / f"linked{s}").read_bytes() for s in SUFFIXES]
    assert json.loads(linked[1])["materials"][0]["source"] == "../materials/clay.toml"
    assert linked[1:] == real[1:] and linked[0] == real[0]
    # Read through the link, the source is found where the manifest means it.
    atlas = read_atlas(link / "linked.dds")
    assert atlas.source_path(atlas.material("clay")).resolve() == (project / "materials" / "clay.toml").resolve()


def _linked_twin(tmp_path: Path) -> Path:
    """A project whose ``lnk`` leads to ``elsewhere/sub``, so ``lnk/../materials/clay.toml`` is elsewhere's clay (green),
    not the project's (red): the file the system opens, which a textual ``..`` would take for the project's."""
    project = tmp_path / "project"
    (project / "materials").mkdir(parents=True)
    (project / "materials" / "clay.toml").write_text('type = "lambert"\ncolour = [1, 0, 0]\n')
    (project / "elsewhere" / "sub").mkdir(parents=True)
    (project / "elsewhere" / "materials").mkdir()
    (project / "elsewhere" / "materials" / "clay.toml").write_text('type = "lambert"\ncolour = [0, 1, 0]\n')
    (project / "lnk").symlink_to(project / "elsewhere" / "sub", target_is_directory=True)
    return project


def test_a_dotdot_after_a_linked_folder_names_the_file_that_was_baked(tmp_path, monkeypatch):
    """``lnk/../materials/clay.toml`` baked elsewhere's clay, and the manifest named the project's: abspath folded the
    ``..`` as text. Both routes to elsewhere's file now give the same bytes, and its source is that file."""
    project = _linked_twin(tmp_path)
    _bake(project, ["lnk/../materials/clay.toml", "-o", "build-a/atlas.dds"], monkeypatch)
    _bake(project, ["elsewhere/materials/clay.toml", "-o", "build-b/atlas.dds"], monkeypatch)
    routes = [[(project / build / f"atlas{s}").read_bytes() for s in SUFFIXES] for build in ("build-a", "build-b")]
    assert routes[0] == routes[1]
    entry = json.loads(routes[0][1])["materials"][0]
    assert entry["source"] == "../elsewhere/materials/clay.toml" and entry["params"]["colour"] == [0.0, 1.0, 0.0]


def test_two_files_one_path_apart_by_a_link_are_two_materials_in_either_order(tmp_path, monkeypatch):
    """``lnk/../materials/clay.toml`` and ``materials/clay.toml`` were taken for one file named twice: the atlas held
    whichever came first, exit 0. They are two files of one material name, refused on one line in either order."""
    project = _linked_twin(tmp_path)
    monkeypatch.chdir(project)
    for files in (["lnk/../materials/clay.toml", "materials/clay.toml"], ["materials/clay.toml", "lnk/../materials/clay.toml"]):
        res = CliRunner().invoke(app, ["bake", *files, "-o", "build/atlas.dds", "-q"])
        assert res.exit_code != 0 and "clay" in res.output and len(res.output.strip().splitlines()) == 1, res.output
        assert not (project / "build" / "atlas.dds").exists()
