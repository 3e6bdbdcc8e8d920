"""Reading user-written text inputs: a UTF-8 byte-order mark, as Windows editors write, is no statement."""

from __future__ import annotations

import doctest
import os
import subprocess
import sys

import pytest

from atlasgen.errors import InputError, MaterialError, SceneError
from atlasgen.io import text
from atlasgen.materials.material import read_material_file
from atlasgen.materials.scene import read_scene

BOM = b"\xef\xbb\xbf"
SCENE = (b'[camera]\nposition = [0, 0, 3]\ntarget = [0, 0, 0]\nfov = 30\n[image]\nwidth = 8\nheight = 8\n'
         b'[[lights]]\ntype = "directional"\ndirection = [0, 0, -1]\nintensity = 2\n'
         b'[[objects]]\nshape = "sphere"\nmaterial = "clay"\n')  # fmt: skip


def test_the_examples_in_the_docstrings_hold():
    result = doctest.testmod(text)
    assert result.attempted > 0 and result.failed == 0


def test_a_material_and_a_scene_read_the_same_with_a_byte_order_mark(tmp_path):
    plain, marked = tmp_path / "plain", tmp_path / "marked"
    for folder, head in ((plain, b""), (marked, BOM)):
        folder.mkdir()
        (folder / "clay.toml").write_bytes(head + b'type = "lambert"\ncolour = [0.6, 0.5, 0.4]\n')
        (folder / "scene.toml").write_bytes(head + SCENE)
    a, b = read_material_file(plain / "clay.toml")[0], read_material_file(marked / "clay.toml")[0]
    assert a.params == b.params and a.name == b.name == "clay"
    assert a.content_hash != b.content_hash  # the hash is of the file's bytes, as ever
    assert read_scene(plain / "scene.toml").lights == read_scene(marked / "scene.toml").lights


def test_a_mark_is_dropped_only_at_the_start(tmp_path):
    path = tmp_path / "clay.toml"
    path.write_bytes(b'type = "lambert"\n' + BOM + b"colour = [0.6, 0.5, 0.4]\n")
    with pytest.raises(MaterialError, match="malformed TOML"):
        read_material_file(path)


@pytest.mark.parametrize("nested", ["[" * 1000 + "]" * 1000, "{a = " * 2000 + "1" + "}" * 2000])
def test_a_file_nested_too_deeply_is_malformed_not_a_bug(tmp_path, nested):
    """tomllib recurses once a level: a thousand levels end in RecursionError, which is the file's fault."""
    material = tmp_path / "deep.toml"
    material.write_text(f'type = "lambert"\ncolour = {nested}\n')
    with pytest.raises(MaterialError) as info:
        read_material_file(material)
    assert str(info.value) == f"{material.as_posix()}: malformed TOML: arrays or inline tables nested too deeply to read"
    scene = tmp_path / "scene.toml"
    scene.write_text(f"[camera]\nposition = {nested}\n")
    with pytest.raises(SceneError, match="nested too deeply"):
        read_scene(scene)


def test_a_named_pipe_is_named_and_refused_before_it_is_opened(tmp_path):
    """Opening a named pipe for reading waits for a writer: every reader refuses one on one line instead.
    The commands run in a child process with a timeout, so a reader that opened the pipe fails the test."""
    fifo = tmp_path / "clay.toml"
    os.mkfifo(fifo)
    assert text.special_file_kind(fifo) == "a named pipe"
    assert text.special_file_kind(tmp_path) is None and text.special_file_kind(tmp_path / "missing") is None
    assert [text.path_kind(p) for p in (fifo, tmp_path, tmp_path / "missing", tmp_path / "a\0b")] == [
        "a named pipe",
        "a directory",
        text.MISSING,
        text.MISSING,
    ]
    (tmp_path / "plain.toml").write_text("")
    assert text.path_kind(tmp_path / "plain.toml") is None
    for command, expected in ((["bake", str(fifo), "-o", str(tmp_path / "a.dds")], "expected a material file or a folder"),
                              (["render", str(fifo), "-o", str(tmp_path / "a.exr")], "expected a regular file")):  # fmt: skip
        out = subprocess.run([sys.executable, "-m", "atlasgen", *command], capture_output=True, text=True, timeout=60)
        assert out.returncode == 3
        assert out.stderr.strip().splitlines() == [f"atlasgen: error: {fifo.as_posix()}: {expected}, got a named pipe"]
    with pytest.raises(InputError, match="expected a regular file, got a named pipe"):
        text.read_input_bytes(fifo)


def test_a_symbolic_link_loop_is_named_not_called_missing(tmp_path):
    """It was "no such mesh file": the file is there, as a link that never ends."""
    from atlasgen.render.meshes import read_mesh

    loop = tmp_path / "m.obj"
    loop.symlink_to(tmp_path / "m2.obj")
    (tmp_path / "m2.obj").symlink_to(loop)
    assert text.path_kind(loop) == "a symbolic link loop" == text.special_file_kind(loop)
    with pytest.raises(SceneError, match=r"expected an OBJ or PLY file, got a symbolic link loop"):
        read_mesh(loop, "s.toml", "objects[0].file")
    with pytest.raises(InputError, match=r"m.obj: expected a regular file, got a symbolic link loop$"):
        text.read_input_bytes(loop)


def test_an_integer_tomllib_will_not_convert_is_malformed_not_a_bug(tmp_path):
    """Over 4300 digits, int() refuses the literal with a plain ValueError, which escaped as an internal error."""
    material = tmp_path / "huge.toml"
    material.write_text('type = "fresnel"\nior = ' + "1" * 5000 + "\n")
    with pytest.raises(MaterialError) as info:
        read_material_file(material)
    message = str(info.value)
    assert message.startswith(f"{material.as_posix()}: malformed TOML: Exceeds the limit (4300 digits)") and len(message) < 300
    scene = tmp_path / "scene.toml"
    scene.write_text("[camera]\nposition = [" + "9" * 5000 + ", 0, 0]\n")
    with pytest.raises(SceneError, match="malformed TOML: Exceeds the limit"):
        read_scene(scene)


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        # Found by a hostile sweep: "malformed TOML: Cannot overwrite a value (at line 13, column 10)" named no key.
        ("range = 5.0\nrange = 6.0\n", "line 16: 'range' is already set (the key given twice, or a table of its name); "
                                       "expected each key once"),
        ("range = [5.0,\n  6.0]\nrange = [\n  1.0,\n]\n", "line 17: 'range'"),  # the statement that starts the value
        ('"range" = 5.0\n"range" = 6.0\n', 'line 16: "range" is already set'),
        ("[image.width]\nkind = 1\n", "line 15: the table header [image.width] names a key already set; expected each "
                                      "key once"),
        ("[lights]\nkind = 1\n", "line 15: the table [lights] is declared twice; expected each table once"),
        ("[camera]\nfov = 20\n", "line 15: the table [camera] is declared twice; expected each table once"),
    ],
)  # fmt: skip
def test_a_key_given_twice_is_named_with_its_line(tmp_path, extra, words):
    scene = tmp_path / "scene.toml"
    scene.write_bytes(SCENE + extra.encode())
    with pytest.raises(SceneError) as info:
        read_scene(scene)
    assert str(info.value).startswith(f"{scene.as_posix()}: malformed TOML: {words}"), str(info.value)


def test_a_material_s_key_given_twice_is_named_too(tmp_path):
    material = tmp_path / "clay.toml"
    material.write_text('type = "lambert"\ncolour = [0.6, 0.5, 0.4]\ncolour = [1, 1, 1]')  # no newline: "end of document"
    with pytest.raises(MaterialError) as info:
        read_material_file(material)
    assert str(info.value) == (f"{material.as_posix()}: malformed TOML: line 3: 'colour' is already set (the key given "
                               "twice, or a table of its name); expected each key once")  # fmt: skip
