"""Make dependency files: what make reads back from them, checked with make itself."""

import os
import shutil
import subprocess

import pytest
from hypothesis import given
from hypothesis import strategies as st

from atlasgen.errors import InputError, OutputNameError
from atlasgen.io.depfile import format_depfile, write_depfile

names = st.text(alphabet="abcXYZ019_-.# $:", min_size=1, max_size=12).filter(lambda s: s.strip(" .") and not s.startswith("-"))


@given(st.lists(names, min_size=1, max_size=5, unique=True))
def test_every_prerequisite_gets_an_empty_rule(prerequisites):
    text = format_depfile("out/a b.dds", prerequisites)
    assert text.startswith("out/a\\ b.dds:")
    assert text.count("\n\n") == 1 and len(text.split("\n\n")[1].splitlines()) == len(prerequisites)


@pytest.mark.skipif(shutil.which("make") is None, reason="GNU make is not installed")
def test_make_rebuilds_on_a_newer_prerequisite_and_survives_a_deleted_one(tmp_path):
    # The last name is no UTF-8 (an output folder named so wrote no depfile: an internal error).
    inputs = [tmp_path / "in one.toml", tmp_path / "in#2.toml", tmp_path / "cost$.npz", tmp_path / "c:d.mtlx",
              tmp_path / os.fsdecode(b"x\xff.npz")]  # fmt: skip
    for i, path in enumerate(inputs):
        path.write_text(str(i))
        os.utime(path, (1_000, 1_000))
    out = tmp_path / "out.dds"
    out.write_text("built")
    os.utime(out, (2_000, 2_000))
    write_depfile(tmp_path / "out.d", "out.dds", [p.name for p in inputs])
    (tmp_path / "Makefile").write_text("out.dds:\n\t@echo rebuilt\n-include out.d\n")

    def make():
        # Not the outer make's flags: under `make bench-workflow` (a make running make) they carry
        # -w, and make would print "Entering directory" around the recipe's output.
        env = {**os.environ, "MAKEFLAGS": "", "MAKELEVEL": ""}
        return subprocess.run(["make", "-s", "out.dds"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=30)

    assert make().stdout == ""  # up to date
    os.utime(inputs[1], (3_000, 3_000))
    assert make().stdout == "rebuilt\n"  # the escaped '#' name is a real prerequisite
    os.utime(inputs[1], (1_000, 1_000))
    os.utime(inputs[3], (3_000, 3_000))
    assert make().stdout == "rebuilt\n"  # and the escaped ':' one
    os.utime(inputs[3], (1_000, 1_000))
    os.utime(inputs[4], (3_000, 3_000))
    assert make().stdout == "rebuilt\n"  # and the one whose name is no UTF-8
    os.utime(inputs[4], (1_000, 1_000))
    inputs[0].unlink()
    result = make()
    assert result.returncode == 0 and result.stdout == "rebuilt\n", result.stderr


def test_a_path_with_a_line_break_is_refused_on_one_line():
    """Make ends a rule at a line break, and no escape exists for one."""
    with pytest.raises(InputError) as info:
        format_depfile("out.dds", ["ok.toml", "a\nb.toml"])
    assert str(info.value) == ("--depfile: cannot write 'a\\nb.toml' as a make prerequisite: make reads '\\n' in it as the "
                               "end of the rule; expected a path without ; | % = * ? [ ] ( ) \\, tabs or line breaks")  # fmt: skip


@pytest.mark.parametrize("char", list(";|%=*?[]()\\\t\r"))
def test_a_name_make_reads_as_syntax_is_refused_as_a_prerequisite_or_a_target(char):
    """A mesh named a;b.obj wrote a depfile make stopped on ("missing separator": every goal of the project's
    Makefile, clean included); a|b waited on a file 'a', 50%.obj became a pattern rule, a=b.obj an assignment."""
    with pytest.raises(InputError) as info:
        format_depfile("out.png", ["ok.obj", f"a{char}b.obj"])
    assert f"as a make prerequisite: make reads {char!r} in it as " in str(info.value)
    with pytest.raises(OutputNameError) as info:  # the target is an option's value: exit 2
        format_depfile(f"out{char}.png", ["ok.obj"])
    assert f"as a make target: make reads {char!r}" in str(info.value) and info.value.exit_code == 2


def test_a_file_inside_the_working_folder_is_named_from_it_wherever_the_tree_lies(tmp_path, monkeypatch):
    """A hostile sweep's: a file a material names reached the depfile as an absolute path (the reader resolves it
    from the material's folder), so the same tree built in two folders gave two depfiles; one outside stays absolute."""
    from atlasgen.io.depfile import encode_depfile

    written = []
    for tree in ("one", "two"):
        folder = tmp_path / tree
        (folder / "materials").mkdir(parents=True)
        monkeypatch.chdir(folder)
        texture = folder / "materials" / "tex.png"
        written.append(encode_depfile("build/a.dds", ["materials/a.toml", str(texture), "/elsewhere/b.png"]))
    assert written[0] == written[1]
    assert written[0].decode().splitlines()[:4] == ["build/a.dds: \\", "  materials/a.toml \\", "  materials/tex.png \\",
                                                    "  /elsewhere/b.png"]  # fmt: skip
