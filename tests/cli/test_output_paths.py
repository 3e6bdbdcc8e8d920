"""Output paths are checked before anything is baked or written: an output may not be an
input, another output or a folder, must have the right extension, and an atlas is not
emptied by accident."""

from __future__ import annotations

import hashlib

import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app


@pytest.fixture
def library(write_material, tmp_path):
    write_material("clay", 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n')
    write_material("snow", 'type = "lambert"\n')
    return tmp_path / "materials"


def _tree_hash(root) -> dict:
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(root.rglob("*"))}  # fmt: skip


def _refused(tmp_path, args, expected, code=4):
    """Run ``args``; it must fail with ``code`` and one line containing ``expected``, and
    leave every file under ``tmp_path`` as it was."""
    before = _tree_hash(tmp_path)
    res = CliRunner().invoke(app, args)
    assert res.exit_code == code, res.output
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("atlasgen: error: ") and expected in lines[0], res.stderr
    assert _tree_hash(tmp_path) == before
    return lines[0]


def _bake(tmp_path, library, *extra):
    res = CliRunner().invoke(app, ["bake", str(library), "-o", str(tmp_path / "build" / "atlas.dds"), "-q", *extra])
    assert res.exit_code == 0, res.output


def test_an_output_may_not_be_an_input(tmp_path, library):
    material = library / "clay.toml"
    _refused(tmp_path, ["bake", str(material), "-o", str(material)], "must end in .dds or .ktx2, not '.toml'", code=2)
    line = _refused(tmp_path, ["bake", str(library), "-o", str(tmp_path / "a.dds"), "--depfile", str(material)],
                    "--depfile would overwrite the material file of 'clay'")  # fmt: skip
    assert material.as_posix() in line
    scene = tmp_path / "s.toml"
    scene.write_text('[camera]\nposition = [0, 0, 5]\ntarget = [0, 0, 0]\n[[objects]]\nshape = "sphere"\nmaterial = "clay"\n')
    _refused(tmp_path, ["bake", str(library), "--scene", str(scene), "-o", str(tmp_path / "a.dds"), "--depfile", str(scene)],
             "--depfile would overwrite the scene (--scene)")  # fmt: skip


def test_a_depfile_named_as_a_material_or_targeting_an_input_is_refused(tmp_path, library):
    """A hostile sweep: --depfile in the material folder as dep.toml baked, and the next bake of the folder read it as
    a material and failed, as every later one did; --depfile-target naming a material file wrote a rule making it
    depend on itself. Both are usage errors now, and an ordinary depfile and target still bake."""
    material = library / "clay.toml"
    line = _refused(tmp_path, ["bake", str(library), "-o", str(tmp_path / "a.dds"), "--depfile", str(library / "dep.toml")],
                    "--depfile must not end in .toml or .mtlx", code=2)  # fmt: skip
    assert line.startswith(f"atlasgen: error: {(library / 'dep.toml').as_posix()}: ")
    _refused(tmp_path, ["bake", str(material), "-o", str(tmp_path / "a.dds"), "--depfile", str(tmp_path / "doc.mtlx")],
             "--depfile must not end in .toml or .mtlx", code=2)  # fmt: skip
    line = _refused(tmp_path, ["bake", str(material), "-o", str(tmp_path / "a.dds"), "--depfile", str(tmp_path / "a.d"),
                               "--depfile-target", str(material)], "--depfile-target is the material file of 'clay'", code=2)  # fmt: skip
    assert line.startswith(f"atlasgen: error: {material}: ")
    _bake(tmp_path, library, "--depfile", str(tmp_path / "a.d"), "--depfile-target", str(tmp_path / "build" / "atlas.dds"))
    assert (tmp_path / "a.d").read_text().startswith(f"{(tmp_path / 'build' / 'atlas.dds').as_posix()}:")


def test_two_outputs_may_not_share_a_path(tmp_path, library):
    out = tmp_path / "build" / "atlas.dds"
    _refused(tmp_path, ["bake", str(library), "-o", str(out), "--depfile", str(out.with_suffix(".json"))],
             "both the manifest written beside the atlas and --depfile")  # fmt: skip
    _refused(tmp_path, ["bake", str(library), "-o", str(out), "--depfile", str(tmp_path / "p.png"), "--preview",
                        str(tmp_path / "p.png")], "both --preview and --depfile")  # fmt: skip
    # The cache is an output too.
    _refused(tmp_path, ["bake", str(library), "-o", str(tmp_path / "clay.dds"), "--cache", str(tmp_path),
                        "--depfile", str(tmp_path / "clay.npz")], "both --depfile and the cache entry of 'clay'")  # fmt: skip


def test_an_output_may_not_be_a_folder(tmp_path, library):
    (tmp_path / "out.dds").mkdir()
    _refused(tmp_path, ["bake", str(library), "-o", str(tmp_path / "out.dds")], "the atlas (-o) is an existing folder")
    (tmp_path / "a.wgsl").mkdir()
    _refused(
        tmp_path,
        ["bake", str(library), "-o", str(tmp_path / "a.dds")],
        "the include written beside the atlas is an existing folder",
    )


def test_the_atlas_extension_must_match(tmp_path, library):
    _refused(tmp_path, ["bake", str(library), "-o", str(tmp_path / "x.json")], "the atlas (-o) must end in .dds or .ktx2", code=2)
    _refused(tmp_path, ["bake", str(library), "-o", str(tmp_path / "x")], "not 'no extension'", code=2)
    _refused(tmp_path, ["bake", str(library), "-o", str(tmp_path / "x.dds"), "--preview", str(tmp_path / "p.jpg")],
             "--preview must end in .png", code=2)  # fmt: skip


@pytest.mark.slow
def test_an_empty_folder_does_not_empty_an_atlas_without_allow_empty(tmp_path, library):
    _bake(tmp_path, library)
    empty = tmp_path / "empty"
    empty.mkdir()
    out = tmp_path / "build" / "atlas.dds"
    _refused(tmp_path, ["bake", str(empty), "-o", str(out)], "would replace an atlas of 2 materials with an empty one")
    res = CliRunner().invoke(app, ["bake", str(empty), "-o", str(out), "--allow-empty", "-q"])
    assert res.exit_code == 0 and '"materials": []' in out.with_suffix(".json").read_text()
    # An empty atlas may be re-baked empty, and a new one made empty, without the flag.
    assert CliRunner().invoke(app, ["bake", str(empty), "-o", str(out), "-q"]).exit_code == 0
    assert CliRunner().invoke(app, ["bake", str(empty), "-o", str(tmp_path / "new.dds"), "-q"]).exit_code == 0
    # Allowed, but not without a word: a folder given by mistake baked an empty atlas with exit 0 and no line.
    res = CliRunner().invoke(app, ["bake", str(empty), "-o", str(tmp_path / "new.dds")])
    assert (
        res.exit_code == 0
        and res.stderr == f"atlasgen: warning: {empty.as_posix()}: no material files; the atlas holds no materials\n"
    )
    assert "warning" not in CliRunner().invoke(app, ["bake", str(library), "-o", str(tmp_path / "full.dds")]).stderr


def test_a_depfile_under_a_file_fails_before_the_atlas_is_replaced(tmp_path, library):
    _bake(tmp_path, library)
    (tmp_path / "blocker").write_text("a file")
    (library / "snow.toml").write_text('type = "lambert"\ncolour = [0.1, 0.1, 0.1]\n')
    _refused(tmp_path, ["bake", str(library), "-o", str(tmp_path / "build" / "atlas.dds"), "--depfile",
                        str(tmp_path / "blocker" / "atlas.d")],
             f"blocker/atlas.d: --depfile: cannot write its folder {(tmp_path / 'blocker').as_posix()}")  # fmt: skip


def test_a_depfile_that_fails_while_written_leaves_the_atlas(tmp_path, library, monkeypatch):
    from atlasgen.errors import OutputError
    from atlasgen.io import atomic

    _bake(tmp_path, library)
    (library / "snow.toml").write_text('type = "lambert"\ncolour = [0.1, 0.1, 0.1]\n')

    def full_disk(step, path):
        if path.suffix == ".d":
            raise OutputError(f"{path.as_posix()}: cannot write (No space left on device)")

    monkeypatch.setattr(atomic, "commit_hook", full_disk)
    _refused(tmp_path, ["bake", str(library), "-o", str(tmp_path / "build" / "atlas.dds"), "--depfile",
                        str(tmp_path / "build" / "atlas.d")], "No space left on device")  # fmt: skip


def test_a_render_may_not_write_over_a_folder(tmp_path, library):
    scene = tmp_path / "s.toml"
    scene.write_text('[camera]\nposition = [0, 0, 5]\ntarget = [0, 0, 0]\n[[objects]]\nshape = "sphere"\nmaterial = "clay"\n')
    (tmp_path / "r.png").mkdir()
    # Refused before the atlas (missing here) is read or anything is rendered.
    _refused(tmp_path, ["render", str(scene), "--atlas", str(tmp_path / "a.dds"), "-o", str(tmp_path / "r.exr")],
             "the PNG written beside the render is an existing folder")  # fmt: skip
    # With --aov too: its commit removes the PNG's name, and failed on the folder once the render was done.
    _refused(tmp_path, ["render", str(scene), "--atlas", str(tmp_path / "a.dds"), "-o", str(tmp_path / "r.exr"),
                        "--aov", "depth"], "the PNG beside the render (removed with --aov) is an existing folder")  # fmt: skip


def test_a_render_may_not_write_over_the_scene_s_environment_image(tmp_path):
    """Found by a hostile-input hunt: -o sky.exr replaced the image the scene lights with, exit 0."""
    (tmp_path / "sky.exr").write_bytes(b"an image")
    scene = tmp_path / "s.toml"
    scene.write_text('environment = "sky.exr"\n[camera]\nposition = [0, 0, 5]\ntarget = [0, 0, 0]\n'
                     '[[objects]]\nshape = "sphere"\nmaterial = "clay"\n')  # fmt: skip
    _refused(tmp_path, ["render", str(scene), "--atlas", str(tmp_path / "a.dds"), "-o", str(tmp_path / "sky.exr")],
             "the render (-o) would overwrite the scene's environment image")  # fmt: skip


def test_a_material_the_scene_does_not_use_is_still_an_input(tmp_path, library):
    """Found by the fuzz suite: with --scene, only the selected materials counted as inputs,
    so a depfile could overwrite another material file of the folder that was read."""
    scene = tmp_path / "s.toml"
    scene.write_text('[camera]\nposition = [0, 0, 5]\ntarget = [0, 0, 0]\n[[objects]]\nshape = "sphere"\nmaterial = "snow"\n')
    _refused(tmp_path, ["bake", str(library), "--scene", str(scene), "-o", str(tmp_path / "a.dds"), "--depfile",
                        str(library / "clay.toml")], "--depfile would overwrite the material file of 'clay'")  # fmt: skip


@pytest.mark.parametrize("command", [["validate", "--merge"], ["report", "library"], ["report", "separable", "--merge"]])
def test_a_report_folder_that_is_a_file_is_refused_before_any_work(tmp_path, command):
    blocker = tmp_path / "report"
    blocker.write_text("not a folder")
    # validate's was click's own check, exit 2 where the exit-code table says 4.
    _refused(tmp_path, [*command, "-o", str(blocker)], "the report folder (-o) is an existing file; expected a folder path")
    # The line names the option and what was expected, where it said "cannot write output folder (X is a file)".
    _refused(tmp_path, [*command, "-o", str(blocker / "sub")], f"cannot write output folder: the report folder (-o) lies "
             f"under {blocker.as_posix()}, which is a file; expected a folder path")  # fmt: skip
    # A link to nothing failed only after the work, on mkdir ("File exists"), naming no option.
    dangling = tmp_path / "dangling"
    dangling.symlink_to("nowhere")
    _refused(tmp_path, [*command, "-o", str(dangling)], f"{dangling.as_posix()}: the report folder (-o) is a symbolic "
             "link to 'nowhere', which does not exist; expected a folder path")  # fmt: skip


@pytest.mark.parametrize(("command", "output", "what"), [(["preview", "{material}"], "p.png", "the preview (-o)"),
                                                    (["render", "{scene}"], "r.exr", "the render (-o)")])  # fmt: skip
def test_an_image_output_that_is_a_folder_is_refused_as_an_output(tmp_path, library, command, output, what):
    """click's check of the kind gave exit 2, a usage error, where every other output that is a folder gives 4."""
    scene = tmp_path / "s.toml"
    scene.write_text('[camera]\nposition = [0, 0, 5]\ntarget = [0, 0, 0]\n[[objects]]\nshape = "sphere"\nmaterial = "clay"\n')
    (tmp_path / output).mkdir()
    args = [a.format(material=library / "clay.toml", scene=scene) for a in command]
    _refused(tmp_path, [*args, "-o", str(tmp_path / output)], f"{what} is an existing folder; expected a file path")


@pytest.mark.parametrize("command", [["bake"], ["report", "library"], ["validate", "--merge"]])
def test_an_output_inside_a_set_s_store_is_refused_before_any_work(tmp_path, library, command):
    """Such a path was refused only when written, after the work: a report's progress line came first, two lines."""
    _bake(tmp_path, library)
    inside = tmp_path / "build" / ".atlas.atlasgen" / "current"
    if command == ["bake"]:
        args = ["bake", str(library), "-o", str(inside / "x.dds"), "--cache", str(tmp_path / "cache")]  # filled by a bake
    else:
        args = [*command, *([str(tmp_path)] if "--merge" in command else []), "-o", str(inside)]
    _refused(tmp_path, args, f"{inside.as_posix()}{'/x.dds' if command == ['bake'] else ''}: inside .atlas.atlasgen, "
             "the generations of an output set; expected a path outside atlasgen's .*.atlasgen folders")  # fmt: skip


@pytest.mark.parametrize(("other_primary", "command"), [("report.json", ["report", "library"]),
                                                       ("index.html", ["validate", "--merge"]),
                                                       ("index.html", ["report", "separable", "--merge"])])  # fmt: skip
def test_a_report_folder_holding_another_command_s_page_is_refused_before_any_work(tmp_path, other_primary, command):
    """report library into validate's folder was refused only at its commit, after its work, and left its lock and
    two empty folders in the other command's folder."""
    from atlasgen.io.atomic import write_files_atomically

    out = tmp_path / "out"
    write_files_atomically({out / "index.html": b"<p>another command's page</p>", out / "report.json": b"{}"},
                           primary=out / other_primary, whole=True)  # fmt: skip
    args = [*command, *([str(tmp_path / "runs")] if "--merge" in command else []), "-o", str(out)]
    first = "index.html" if command == ["report", "library"] else "report.json"  # the first file it writes
    _refused(tmp_path, args, f"{(out / first).as_posix()}: already written by another command's outputs "
             f"(.{other_primary.split('.')[0]}.atlasgen beside it); expected a folder of its own")  # fmt: skip


def test_a_cache_folder_that_is_a_named_pipe_is_named_so(tmp_path, library):
    """A FIFO given as --cache was refused as "a file": true to Unix, but no help to find it."""
    import os

    pipe = tmp_path / "cache"
    os.mkfifo(pipe)
    _refused(tmp_path, ["bake", str(library), "-o", str(tmp_path / "a.dds"), "--cache", str(pipe)],
             f"cannot write its folder {pipe.as_posix()} ({pipe.as_posix()} is a named pipe)")  # fmt: skip
    report = tmp_path / "report"
    os.mkfifo(report)
    _refused(tmp_path, ["report", "library", "-o", str(report)], "(-o) is a named pipe; expected a folder path")


@pytest.mark.parametrize("through_link", [False, True], ids=["a named pipe", "a link to a named pipe"])
def test_an_output_that_is_a_named_pipe_is_refused_not_replaced(tmp_path, library, through_link):
    """Found by a hostile sweep: `render --depfile /dev/null` replaced the system's /dev/null with a link into the
    render's store, exit 0; a named pipe, a device or a link to /dev/stdout went the same way, -o's files too."""
    import os
    import stat

    scene = tmp_path / "s.toml"
    scene.write_text('[camera]\nposition = [0, 0, 5]\ntarget = [0, 0, 0]\n[[objects]]\nshape = "sphere"\nmaterial = "clay"\n')
    out = tmp_path / "out"
    cases = [
        ("a.d", ["bake", str(library), "-o", str(out / "a.dds"), "--depfile"], "--depfile"),
        ("a.png", ["bake", str(library), "-o", str(out / "a.dds"), "--preview"], "--preview"),
        ("b.dds", ["bake", str(library), "-o"], "the atlas (-o)"),
        ("r.d", ["render", str(scene), "--atlas", str(out / "a.dds"), "-o", str(out / "r.exr"), "--depfile"],
         "--depfile"),
    ]  # fmt: skip
    for name, args, role in cases:
        pipe = tmp_path / f"pipe-{name}"
        os.mkfifo(pipe)
        target = pipe
        if through_link:
            target = tmp_path / name
            target.symlink_to(pipe)
        line = _refused(tmp_path, [*args, str(target)], f"{target.as_posix()}: {role} is a named pipe; "
                                                        "expected a regular file path, which the command replaces")  # fmt: skip
        assert stat.S_ISFIFO(os.lstat(pipe).st_mode) and target.is_symlink() == through_link, line


@pytest.mark.parametrize(("option", "mark"), [("-o", "\n"), ("--depfile", "\n"), ("--preview", "\t"), ("-o", "\u0085"),
                                            ("--depfile", "\u2028"), ("--preview", "\u009b")])  # fmt: skip
def test_an_output_name_with_a_line_break_is_refused(tmp_path, library, option, mark):
    """Found by hostile sweeps: `--depfile $'od/a\\nb.d'` wrote the file, exit 0, and its "wrote" line split in two; so
    did NEL and U+2028, which Python's splitlines breaks at, and a C1 CSI reached the terminal."""
    suffix = {"-o": ".dds", "--depfile": ".d", "--preview": ".png"}[option]
    name = f"a{mark}b{suffix}"
    args = ["bake", str(library), "-o", str(tmp_path / "x.dds")]
    args = [*args[:2], "-o", str(tmp_path / name)] if option == "-o" else [*args, option, str(tmp_path / name)]
    line = _refused(tmp_path, args, "expected a path without line breaks, tabs or other control characters", code=2)
    assert "a name holding the control character" in line


def test_a_dotted_atlas_name_keeps_its_files_apart_from_the_shorter_name(tmp_path, library):
    """``hero.v2.dds`` writes ``hero.v2.json`` and its includes, never ``hero.json``: another atlas's files."""
    out = tmp_path / "build"
    _bake(tmp_path, library)  # build/atlas.dds, and its siblings
    baked = _tree_hash(out)
    res = CliRunner().invoke(app, ["bake", str(library / "clay.toml"), "-o", str(out / "atlas.v2.dds"), "-q"])
    assert res.exit_code == 0, res.output
    after = _tree_hash(out)
    assert {k: v for k, v in after.items() if k in baked} == baked
    for suffix in (".json", ".wgsl", ".glsl", ".hlsl", ".timings.json"):
        assert (out / f"atlas.v2{suffix}").is_file(), suffix
    info = CliRunner().invoke(app, ["info", str(out / "atlas.v2.dds")])
    assert info.exit_code == 0 and "clay" in info.output, info.output


def test_an_empty_path_is_refused_not_read_as_the_current_folder(tmp_path, library, monkeypatch):
    monkeypatch.chdir(library)  # where "" would have baked every material
    _refused(tmp_path, ["bake", "", "-o", str(tmp_path / "a.dds")], "Invalid value for '[PATHS]...': expected a path, "
             "got an empty string", code=2)  # fmt: skip
    _refused(tmp_path, ["bake", str(library), "-o", ""], "expected a path, got an empty string", code=2)


@pytest.mark.parametrize("option", ["--depfile", "--preview", "-o", "input"])
def test_a_dash_is_refused_not_written_as_a_file_named_dash(tmp_path, library, monkeypatch, option):
    """``--depfile -`` wrote a file named ``-`` where a user meant standard output; ``./-`` still names that file."""
    monkeypatch.chdir(tmp_path)
    out = ["-o", "a.dds"]
    args = {"--depfile": [str(library), *out, "--depfile", "-"], "--preview": [str(library), *out, "--preview", "-"],
            "-o": [str(library), "-o", "-"], "input": ["-", *out]}[option]  # fmt: skip
    _refused(tmp_path, ["bake", *args], "'-' would be a file named '-', not standard input or output", code=2)
    res = CliRunner().invoke(app, ["bake", str(library), *out, "--depfile", "./-", "-q"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "-").read_text().startswith("a.dds:")


@pytest.mark.parametrize("command", ["bake -o", "bake --preview", "bake --depfile", "render -o", "render --depfile",
                                     "preview -o"])  # fmt: skip
def test_a_file_output_ending_in_a_slash_is_refused_not_written_as_a_file(tmp_path, library, monkeypatch, command):
    """``-o newdir.png/`` names a folder: pathlib dropped the slash and a file ``newdir.png`` was written."""
    monkeypatch.chdir(tmp_path)
    name, option = command.split()
    scene = tmp_path / "s.toml"
    scene.write_text("[[objects]]\nshape = 'sphere'\nmaterial = 'clay'\n")
    base = {"bake": ["bake", str(library), "-o", "a.dds"], "render": ["render", str(scene), "-o", "r.png"],
            "preview": ["preview", str(library / "clay.toml")]}[name]  # fmt: skip
    args = [*base, option, "newdir.png/"] if option != "-o" or name == "preview" else [*base[:-1], "newdir.png/"]
    _refused(tmp_path, args, "'newdir.png/' ends in '/', a folder's path; expected a file's path", code=2)
    assert not (tmp_path / "newdir.png").exists()


@pytest.mark.parametrize(("extra", "expected"), [
    (["--preview", "a.dds/sheet.png"], "a.dds/sheet.png: --preview lies under a.dds, the atlas (-o)'s path; expected "
                                       "outputs beside each other, not one inside another"),
    (["--cache", "a.dds"], "a.dds/clay.npz: the cache entry of 'clay' lies under a.dds, the atlas (-o)'s path"),
    (["--preview", "p.png", "--depfile", "p.png/b.d"], "p.png/b.d: --depfile lies under p.png, --preview's path"),
])  # fmt: skip
def test_an_output_under_another_output_s_path_is_refused_before_the_work(tmp_path, library, monkeypatch, extra,
                                                                          expected):  # fmt: skip
    """The commit made the one path a folder, then failed on the other (\"a.dds: cannot replace (Is a directory)\"),
    after the bake, leaving the folder and its cache entries behind."""
    monkeypatch.chdir(tmp_path)
    _refused(tmp_path, ["bake", str(library), "-o", "a.dds", *extra], expected)


@pytest.mark.parametrize("args", [["bake", "MATERIALS", "-o", "dang/a.dds"],
                                  ["bake", "MATERIALS", "-o", "a.dds", "--cache", "dang/sub"],
                                  ["preview", "MATERIALS/clay.toml", "-o", "dang/c.png", "--no-cache"]])  # fmt: skip
def test_an_output_in_a_folder_that_links_to_nothing_is_refused_before_the_work(tmp_path, library, monkeypatch, args):
    """mkdir failed on the dangling link after the work: "dang: cannot write output folder (File exists)"."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "dang").symlink_to("nowhere")
    args = [a.replace("MATERIALS", str(library)) for a in args]
    _refused(tmp_path, args, "its folder dang is a symbolic link to 'nowhere', which does not exist; expected a folder "
                             "path")  # fmt: skip


def test_a_probe_folder_a_killed_run_left_is_removed_by_the_next(tmp_path, library):
    """A kill between the writability probe's mkdir and rmdir left .atlasgen-probe.<random>.atlasgen.tmp in the output
    folder for good: its name held no pid. Named by its process now, the next run's probe removes a dead one's."""
    import os
    import subprocess
    import sys

    out = tmp_path / "out"
    out.mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = out / f".atlasgen-probe.{int(dead.stdout)}.x1y2z3w4.atlasgen.tmp"
    stale.mkdir()
    live = out / f".atlasgen-probe.{os.getpid()}.a1b2c3d4.atlasgen.tmp"  # a running process's: left alone
    live.mkdir()
    res = CliRunner().invoke(app, ["bake", str(library), "-o", str(out / "a.dds"), "-q"])
    assert res.exit_code == 0, res.output
    assert not stale.exists() and live.is_dir()
    assert [p.name for p in out.iterdir() if "probe" in p.name] == [live.name]


def test_a_named_ids_from_manifest_must_exist(tmp_path, library):
    """Only the atlas's own manifest may be missing (its first bake); a missing --ids-from would renumber silently."""
    _refused(tmp_path, ["bake", str(library), "-o", str(tmp_path / "a.dds"), "--ids-from", str(tmp_path / "none.json")],
             f"{(tmp_path / 'none.json').as_posix()}: no such manifest", code=3)  # fmt: skip


@pytest.mark.parametrize("output", ["--depfile", "--preview", "-o"])
def test_a_file_a_materialx_document_includes_is_an_input_too(tmp_path, output):
    """An output where the document's xi:include points replaced the included file (exit 0): the overlap check
    knew the document, not what it includes."""
    pytest.importorskip("MaterialX")
    suffix = {"--depfile": ".d", "--preview": ".png", "-o": ".wgsl"}[output]
    included = tmp_path / f"lib{suffix}"
    included.write_text('<?xml version="1.0"?>\n<materialx version="1.39">\n'
                        '<standard_surface name="SR_red" type="surfaceshader" />\n'
                        '<surfacematerial name="red" type="material">'
                        '<input name="surfaceshader" type="surfaceshader" nodename="SR_red" /></surfacematerial>\n'
                        '</materialx>\n')  # fmt: skip
    document = tmp_path / "main.mtlx"
    document.write_text('<?xml version="1.0"?>\n<materialx version="1.39" xmlns:xi="http://www.w3.org/2001/XInclude">\n'
                        f'<xi:include href="{included.name}" />\n</materialx>\n')  # fmt: skip
    atlas = tmp_path / ("lib.dds" if output == "-o" else "a.dds")
    args = ["bake", str(document), "-o", str(atlas), "-q"] + ([] if output == "-o" else [output, str(included)])
    role = {"--depfile": "--depfile", "--preview": "--preview", "-o": "the include written beside the atlas"}[output]
    line = _refused(tmp_path, args, f"{role} would overwrite a file the material file of 'red' includes")
    assert included.as_posix() in line


@pytest.mark.parametrize("option", ["-o", "--depfile", "--preview"])
def test_a_name_the_file_system_cannot_hold_is_one_line_not_an_internal_error(tmp_path, library, option):
    """A 244-character stem: stat() of X.timings.json raised ENAMETOOLONG through the overlap check, exit 1."""
    long = "a" * 260  # NAME_MAX is 255
    path = {"-o": f"{long[:244]}.dds", "--depfile": f"{long}.d", "--preview": f"{long}.png"}[option]
    args = ["bake", str(library), "-o", str(tmp_path / ("a.dds" if option != "-o" else path)), "-q"]
    args += [option, str(tmp_path / path)] if option != "-o" else []
    # Refused by its length, before the file system is asked: a 250-byte render name passed stat() and failed at its
    # scratch file, a line naming the folder ".". A usage error: a bad option value.
    size = len(path)
    line = _refused(tmp_path, args, f": a file name of {size} bytes; expected at most 215 (the temporary files written "
                                    "beside it add to the name)", code=2)  # fmt: skip
    assert line.startswith(f"atlasgen: error: {tmp_path.as_posix()}/aaa")


def test_an_output_that_is_another_sets_link_is_refused_before_the_lock(tmp_path, library):
    """Found by the output-path fuzz test: `bake -o build/x.dds --depfile build/atlas.dds` (another bake's link)
    was refused at the commit, after the lock had made build/.x.atlasgen: a failure that left a folder behind."""
    _bake(tmp_path, library)
    out = tmp_path / "build"
    _refused(tmp_path, ["bake", str(library), "-o", str(out / "x.dds"), "--depfile", str(out / "atlas.dds")],
             "already written by another command's outputs")  # fmt: skip


def test_a_render_onto_another_sets_link_is_refused_before_it_renders(tmp_path, library, monkeypatch):
    """render -o build/x.exr, whose PNG build/x.png is a bake's --preview, rendered the whole frame before its
    commit refused it, and left build/.x.atlasgen behind."""
    import atlasgen.render

    _bake(tmp_path, library, "--preview", str(tmp_path / "build" / "x.png"))
    scene = tmp_path / "scene.toml"
    scene.write_text('[camera]\nposition = [0, 0, 5]\ntarget = [0, 0, 0]\n[[objects]]\nshape = "sphere"\nmaterial = "clay"\n')

    def no_render(*args, **kwargs):
        raise AssertionError("the atlas was read for rendering")

    monkeypatch.setattr(atlasgen.render, "read_render_atlas", no_render)
    _refused(tmp_path, ["render", str(scene), "--atlas", str(tmp_path / "build" / "atlas.dds"), "-o",
                        str(tmp_path / "build" / "x.exr")], "x.png: already written by another command's outputs")  # fmt: skip


def test_an_unreadable_input_is_left_to_the_reader_not_a_usage_error(tmp_path, library, monkeypatch):
    """click's Path refused a file os.access calls unreadable as a usage error (exit 2); the readers refuse what
    they cannot read on one line, exit 3, as for any bad input. (Root reads through chmod 000, so os.access is made
    to say no: the command then goes on to the reader, which reads the file.)"""
    import os

    monkeypatch.setattr(os, "access", lambda *args, **kwargs: False)
    res = CliRunner().invoke(app, ["bake", str(library / "clay.toml"), "-o", str(tmp_path / "a.dds"), "-q"])
    assert res.exit_code == 0, res.output


def test_a_manifest_that_is_a_symbolic_link_loop_is_refused_on_one_line(tmp_path, library):
    """--ids-from on a loop was an internal error (Python 3.11's resolve() raises RuntimeError), and info took an
    x.json that loops for no manifest at all (exit 0): each is now the reader's one-line refusal, exit 3."""
    loop = tmp_path / "loop.json"
    loop.symlink_to("loop.json")
    _refused(tmp_path, ["bake", str(library), "-o", str(tmp_path / "a.dds"), "--ids-from", str(loop)],
             f"{loop.as_posix()}: expected a regular file, got a symbolic link loop", code=3)  # fmt: skip
    out = tmp_path / "out"
    _bake(out, library)
    manifest = out / "build" / "atlas.json"
    manifest.unlink()
    manifest.symlink_to("atlas.json")
    expected = f"{manifest.as_posix()}: expected a regular file, got a symbolic link loop"
    _refused(tmp_path, ["bake", str(library), "-o", str(out / "build" / "atlas.dds")], expected, code=3)
    res = CliRunner().invoke(app, ["info", str(out / "build" / "atlas.dds")])
    assert res.exit_code == 3 and res.stderr.strip() == f"atlasgen: error: {expected}", res.output
    # A link that points nowhere (a first commit killed before its generation became current leaves its links so) is
    # no manifest to a bake: the next bake goes on and mends it. Refused, it left every later bake, and make, failing.
    manifest.unlink()
    manifest.symlink_to(".atlas.atlasgen/gen-99/atlas.json")
    # Reading such an atlas names the link, where info said "no manifest beside it" as for one never baked with one.
    res = CliRunner().invoke(app, ["info", str(out / "build" / "atlas.dds")])
    assert res.exit_code == 3 and res.stderr.strip() == (
        f"atlasgen: error: {manifest.as_posix()}: a symbolic link to '.atlas.atlasgen/gen-99/atlas.json', which does not "
        "exist; expected the atlas's manifest there; re-run atlasgen bake"), res.output  # fmt: skip
    res = CliRunner().invoke(app, ["bake", str(library), "-o", str(out / "build" / "atlas.dds"), "-q"])
    assert res.exit_code == 0, res.output
    assert CliRunner().invoke(app, ["info", str(out / "build" / "atlas.dds")]).exit_code == 0


_UNWRITABLE = "(Operation not permitted); expected a folder this user may write"


@pytest.mark.parametrize(("command", "output", "what"), [
    (["bake", "{library}"], "x.dds", "the atlas (-o)"),
    (["render", "{scene}"], "x.exr", "the render (-o)"),
    (["preview", "{material}"], "x.png", "the preview (-o)"),
    (["validate", "{material}"], "report", "the report folder (-o)"),
    (["report", "library"], "report", "the report folder (-o)"),
    (["validate", "--merge", "{tmp}"], "report", "the report folder (-o)"),
])  # fmt: skip
@pytest.mark.parametrize("below", [False, True], ids=["in it", "in a folder to be made in it"])
def test_an_output_in_a_folder_that_takes_no_new_file_is_refused_before_any_work(tmp_path, library, command, output,
                                                                                  what, below):  # fmt: skip
    """An immutable (or, for a user who is not root, read-only) output folder was found only at the commit: validate
    rendered every material, printed its progress, then failed, the work lost."""
    from tests.immutable import immutable

    scene = tmp_path / "s.toml"
    scene.write_text('[camera]\nposition = [0, 0, 5]\ntarget = [0, 0, 0]\n[[objects]]\nshape = "sphere"\nmaterial = "clay"\n')
    args = [a.format(library=library, material=library / "clay.toml", scene=scene, tmp=tmp_path) for a in command]
    if command[0] in ("render", "report"):
        _bake(tmp_path, library)
        args += ["--atlas", str(tmp_path / "build" / "atlas.dds")]
    stuck = tmp_path / "stuck"
    stuck.mkdir()
    target = stuck / "sub" / output if below else stuck / output
    with immutable(stuck):
        _refused(tmp_path, [*args, "-o", str(target)], f"{target.as_posix()}: {what}: cannot write in {stuck.as_posix()} "
                 f"{_UNWRITABLE}")  # fmt: skip


@pytest.mark.parametrize(("command", "option"), [(["validate", "{material}"], "--cache"),
                                                 (["validate", "{material}"], "--reference-cache"),
                                                 (["preview", "{material}"], "--cache"),
                                                 (["bake", "{library}"], "--cache")])  # fmt: skip
def test_a_cache_folder_that_takes_no_new_file_is_refused_before_any_work(tmp_path, library, command, option):
    """validate and preview stored their caches as the renders finished: an immutable --cache was "cannot write output
    folder", after the work, and for a folder that is no output."""
    from tests.immutable import immutable

    args = [a.format(library=library, material=library / "clay.toml") for a in command]
    out = tmp_path / ("x.dds" if command[0] == "bake" else "x.png" if command[0] == "preview" else "report")
    stuck = tmp_path / "stuck"
    stuck.mkdir()
    with immutable(stuck):
        line = _refused(tmp_path, [*args, "-o", str(out), option, str(stuck / "cache")],
                        f"cannot write in {stuck.as_posix()} {_UNWRITABLE}")  # fmt: skip
    assert option in line or command[0] == "bake", line  # bake names the entry: "the cache entry of 'clay'"


def test_a_writable_output_folder_is_left_as_it_was_by_the_check(tmp_path):
    """The check makes and removes an empty folder: nothing of it stays."""
    from atlasgen.io.output_paths import check_cache_folder, check_output_folder, check_output_paths

    folder = tmp_path / "out"
    folder.mkdir()
    check_output_paths([(folder / "x.dds", "the atlas (-o)"), (folder / "sub" / "y.d", "--depfile")])
    check_output_folder(folder / "report", "the report folder (-o)")
    check_cache_folder(folder / "cache", "--cache")
    assert list(tmp_path.rglob("*")) == [folder]


@pytest.mark.parametrize(("command", "option"), [(["validate", "{material}"], "--cache"),
                                                 (["validate", "{material}"], "--reference-cache"),
                                                 (["preview", "{material}"], "--cache")])  # fmt: skip
def test_a_cache_folder_under_a_file_is_named_a_cache_folder_before_any_work(tmp_path, library, command, option):
    """Found when the first entry was stored, after a render, as "cannot write output folder": a cache is none."""
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    args = [a.format(material=library / "clay.toml") for a in command]
    out = tmp_path / ("x.png" if command[0] == "preview" else "report")
    _refused(tmp_path, [*args, "-o", str(out), option, str(blocker / "cache")],
             f"{(blocker / 'cache').as_posix()}: cannot write cache folder: {option} lies under {blocker.as_posix()}, "
             "which is a file; expected a folder path")  # fmt: skip


@pytest.mark.parametrize(("command", "option"), [(["validate", "{material}"], "--cache"),
                                                 (["validate", "{material}"], "--reference-cache"),
                                                 (["preview", "{material}"], "--cache")])  # fmt: skip
def test_a_cache_folder_that_is_a_file_is_refused_as_the_docs_say(tmp_path, library, command, option):
    """docs/validation.md: exit 4 and atlasgen's one line; click's own path check ran first, with exit 2 and
    "Invalid value for '--cache': Directory 'afile' is a file." (a hostile sweep's)."""
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    args = [a.format(material=library / "clay.toml") for a in command]
    out = tmp_path / ("x.png" if command[0] == "preview" else "report")
    _refused(tmp_path, [*args, "-o", str(out), option, str(afile)],
             f"{afile.as_posix()}: {option} is an existing file; expected a folder path")  # fmt: skip


@pytest.mark.parametrize(("depfile", "role"), [
    ("atlas.ktx2", "the other container's name beside the atlas (removed by the bake)"),
    ("atlas.glsl", "the GLSL include's name beside the atlas"),
    ("atlas.separable.bin", "the separable side-car's name beside the atlas"),
])  # fmt: skip
def test_a_depfile_may_not_take_a_name_of_the_atlas_s_set(tmp_path, library, depfile, role):
    """--depfile X.ktx2 beside X.dds, or X.glsl where only WGSL was asked for, was written: a Make fragment under the
    name an engine loads as the atlas or its include."""
    out = tmp_path / "build" / "atlas.dds"
    _refused(tmp_path, ["bake", str(library), "-o", str(out), "--include", "wgsl", "--depfile", str(out.parent / depfile)],
             f"{(out.parent / depfile).as_posix()}: both {role} and --depfile; expected a different path for each output")  # fmt: skip


def test_one_file_read_for_many_materials_is_compared_once(tmp_path, monkeypatch):
    """A MaterialX document names one file for each of its materials: each output is compared with it once, not
    once per material (5000 materials with --cache took minutes before the slice count refused them), and a clash
    is still named under the first material's role."""
    from atlasgen.io import output_paths

    document = tmp_path / "library.mtlx"
    document.write_text("<materialx/>")
    outputs = [(tmp_path / "cache" / f"m{i}.npz", f"the cache entry of 'm{i}'") for i in range(50)]
    inputs = [(document, f"the material file of 'm{i}'") for i in range(50)]
    calls = []
    compare = output_paths._same_file
    monkeypatch.setattr(output_paths, "_same_file", lambda a, b: calls.append((a, b)) or compare(a, b))
    output_paths.check_output_paths(outputs, inputs)
    assert len(calls) == len(outputs)
    with pytest.raises(output_paths.OutputError, match=r"would overwrite the material file of 'm0' \(.*library.mtlx\)"):
        output_paths.check_output_paths([(document, "the atlas (-o)")], inputs)


def test_an_atlas_whose_manifest_would_replace_a_report_is_refused(tmp_path, library):
    """A hostile sweep: `bake -o v1/report.dds` in a validation folder read its report.json as the atlas's damaged
    manifest: exit 3, advising to delete another command's report. A report folder written before reports recorded
    themselves in their set is told by its report.json."""
    folder = tmp_path / "v1"
    folder.mkdir()
    (folder / "report.json").write_text('{"results": []}')
    _refused(tmp_path, ["bake", str(library), "-o", str(folder / "report.dds")],
             f"{(folder / 'report.json').as_posix()}: the manifest written beside the atlas would replace a validation "
             "report; expected a folder of its own for each command's outputs")  # fmt: skip


def test_a_watch_s_cache_that_is_a_file_is_its_one_line_before_it_begins(tmp_path, library):
    """A hostile sweep's: `preview --watch --cache FILE` printed "watching ..." and then the refusal."""
    afile = tmp_path / "afile"
    afile.write_text("not a folder")
    _refused(tmp_path, ["preview", "--watch", str(library / "clay.toml"), "-o", str(tmp_path / "x.png"), "--cache",
                        str(afile)], f"{afile.as_posix()}: --cache is an existing file; expected a folder path")  # fmt: skip


def test_a_file_where_the_preview_keeps_its_own_cache_is_refused_naming_the_option(tmp_path, library):
    """A hostile sweep's: a file at <cache>/preview failed the preview after its bake, "cannot write output folder
    (File exists)", naming no option."""
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "preview").write_text("not a folder")
    _refused(
        tmp_path,
        ["preview", str(library / "clay.toml"), "-o", str(tmp_path / "x.png"), "--cache", str(cache)],
        f"{(cache / 'preview').as_posix()}: --cache's preview folder is an existing file; expected a folder path",
    )
