"""``atlasgen preview``: the picture, its default path, one-line errors with their exit codes, and Ctrl-C."""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app

CLAY = 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n'


@pytest.mark.parametrize(
    "body, args, code, words",
    [
        ('type = "lambert"\ncolour = [0.7, 0.5]\n', [], 3, "field 'colour'"),
        (CLAY, ["-o", "clay.jpg"], 2, "the preview (-o) must end in .png"),
        (CLAY, ["missing.toml"], 3, "missing.toml: no such file or folder"),
    ],
    ids=["bad material", "not a png", "missing file"],
)
def test_bad_input_is_one_line_and_the_picture_stays(tmp_path, monkeypatch, write_material, body, args, code, words):
    monkeypatch.chdir(tmp_path)
    clay = write_material("clay", body)
    old = tmp_path / "build" / "preview" / "clay.png"
    old.parent.mkdir(parents=True)
    old.write_bytes(b"the last good picture")
    paths = [a for a in args if a.endswith(".toml")] or [str(clay)]
    res = CliRunner().invoke(app, ["preview", *paths, "--cache", str(tmp_path / "cache"), *[a for a in args if a not in paths]])
    assert res.exit_code == code, res.output
    assert len(res.stderr.splitlines()) == 1 and res.stderr.startswith("atlasgen: error: ") and words in res.stderr
    assert old.read_bytes() == b"the last good picture"


@pytest.mark.parametrize(("cache", "where"), [("pv/c.png", "is"), ("pv/c.png/cache", "lies under")])
def test_a_cache_at_or_under_the_preview_s_path_is_refused_before_any_work(tmp_path, monkeypatch, write_material, cache,
                                                                           where):  # fmt: skip
    """A hostile sweep: --cache pv/c.png with -o pv/c.png made the folder pv/c.png and filled it with cache entries,
    then failed on writing the picture over it (exit 4, "it was left as it was"); so did a cache under it."""
    monkeypatch.chdir(tmp_path)
    clay = write_material("clay", CLAY)
    res = CliRunner().invoke(app, ["preview", str(clay), "-o", "pv/c.png", "--cache", cache])
    assert res.exit_code == 2 and res.stderr == (f"atlasgen: error: {cache}: --cache {where} the preview (-o); expected "
                                                 "a cache folder of another name\n"), res.output  # fmt: skip
    assert not (tmp_path / "pv").exists()


def test_materials_that_leave_the_floor_no_slice_are_refused_naming_the_floor(tmp_path, monkeypatch):
    # 256 one-slice materials fill the atlas: the preview's floor needs one more.
    monkeypatch.chdir(tmp_path)
    (tmp_path / "many").mkdir()
    for i in range(256):
        (tmp_path / "many" / f"clay{i:03d}.toml").write_text(CLAY)
    res = CliRunner().invoke(app, ["preview", "many", "-o", "many.png", "--cache", str(tmp_path / "cache")])
    assert res.exit_code == 3, res.output
    assert res.stderr == ("atlasgen: error: many/clay255.toml: the materials need 256 slices and the preview's floor 1; "
                          "expected at most 255 for the materials (the atlas has 256)\n")  # fmt: skip
    assert not (tmp_path / "many.png").exists()


def test_paths_are_required():
    res = CliRunner().invoke(app, ["preview"])
    assert res.exit_code == 2 and "Missing argument 'PATHS...'" in res.stderr


@pytest.mark.slow
def test_the_picture_goes_to_build_preview_by_default(gpu_device, tmp_path, monkeypatch, write_material):
    monkeypatch.chdir(tmp_path)
    write_material("clay", CLAY)
    res = CliRunner().invoke(app, ["preview", "materials/clay.toml", "-v", "--cache", "cache"])
    assert res.exit_code == 0, res.output
    assert res.stdout.startswith("wrote build/preview/clay.png (clay) in ")
    assert res.stderr.startswith("  read ") and "render" in res.stderr
    assert (tmp_path / "build" / "preview" / "clay.png").read_bytes().startswith(b"\x89PNG")
    assert (tmp_path / "cache" / "clay.npz").is_file()
    # A folder: a contact sheet named after it.
    res = CliRunner().invoke(app, ["preview", "materials", "-q", "--no-cache"])
    assert res.exit_code == 0 and res.output == "" and (tmp_path / "build" / "preview" / "materials.png").is_file()


@pytest.mark.slow
def test_ctrl_c_ends_a_watch_with_success(gpu_device, tmp_path, write_material):
    clay = write_material("clay", CLAY)
    out = tmp_path / "clay.png"
    code = ("import signal; signal.signal(signal.SIGINT, signal.default_int_handler)\n"
            "from atlasgen.cli.main import main\n"
            f"main(['preview', {str(clay)!r}, '--watch', '-o', {str(out)!r}, '--cache', {str(tmp_path / 'cache')!r}])\n")  # fmt: skip
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=os.environ)  # fmt: skip
    # The picture is renamed into place before its line is printed, so the test waits for the
    # line: a Ctrl-C between the two would (rightly) end the watch without it.
    said: queue.Queue[str] = queue.Queue()
    reader = threading.Thread(target=lambda: [said.put(line.rstrip("\n")) for line in child.stdout], daemon=True)
    reader.start()
    try:
        lines = [said.get(timeout=120)]
        first = out.read_bytes()
        clay.write_text(CLAY.replace("0.3", "0.1"))
        # A draft's error figures may be measured in between, on lines of their own.
        while " changed: " not in lines[-1]:
            lines.append(said.get(timeout=120))
        child.send_signal(signal.SIGINT)
        stderr = child.stderr.read()
        child.wait(timeout=60)
    finally:
        child.kill()
    reader.join(timeout=10)
    assert child.returncode == 0, stderr
    assert stderr.splitlines()[0].startswith("watching ") and stderr.splitlines()[-1] == "stopped watching"
    assert lines[0].startswith(f"first picture: {out.as_posix()} in ")
    assert all(line.startswith("error figures measured in ") for line in lines[1:-1]), lines
    assert lines[-1].startswith(f"{clay.as_posix()} changed: {out.as_posix()} in ") and lines[-1].endswith(" s")
    assert out.read_bytes() != first and out.read_bytes().startswith(b"\x89PNG")


@pytest.mark.slow
def test_sigterm_ends_a_watch_as_it_ends_every_command(gpu_device, tmp_path, write_material):
    """SIGTERM (a job's time-out, an IDE's stop) ended a watch as Ctrl-C does, "stopped watching" and exit 0, where
    every command exits 143 with its line (docs/cli.md): the caller could not tell a kill from a user's stop."""
    clay = write_material("clay", CLAY)
    out = tmp_path / "clay.png"
    script = Path(sys.executable).parent / "atlasgen"  # the command line itself: it installs the SIGTERM handler
    child = subprocess.Popen([str(script), "preview", str(clay), "--watch", "-o", str(out), "--cache", str(tmp_path / "c")],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=os.environ)  # fmt: skip
    try:
        first = child.stdout.readline()
        assert first.startswith(f"first picture: {out.as_posix()} in "), first
        child.send_signal(signal.SIGTERM)
        stderr = child.stderr.read()
        child.wait(timeout=60)
    finally:
        child.kill()
    assert child.returncode == 143, stderr
    assert stderr.splitlines()[-1] == "atlasgen: terminated" and "stopped watching" not in stderr
    assert out.read_bytes().startswith(b"\x89PNG")


@pytest.mark.slow
@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM], ids=["Ctrl-C", "SIGTERM"])
def test_a_watch_ended_while_its_reference_renders_ends_cleanly(gpu_device, mitsuba_llvm, tmp_path, write_material, stop):
    """Found by a hostile sweep: Ctrl-C or SIGTERM while the reference rendered in its thread aborted the process
    (exit 134, "Fatal Python error: PyGILState_Release" and a thread dump), three runs in three."""
    clay = write_material("clay", CLAY)
    out = tmp_path / "clay.png"
    script = Path(sys.executable).parent / "atlasgen"
    child = subprocess.Popen([str(script), "preview", str(clay), "--watch", "--reference", "--reference-spp", "64",
                              "-o", str(out), "--cache", str(tmp_path / "c")], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=os.environ)  # fmt: skip
    try:
        first = child.stdout.readline()
        assert first.startswith(f"first picture: {out.as_posix()} in "), first
        time.sleep(5)  # the reference's passes under way (at 3 s, Mitsuba was still loading)
        child.send_signal(stop)
        stderr = child.stderr.read()
        child.wait(timeout=120)
    finally:
        child.kill()
    assert child.returncode == (0 if stop == signal.SIGINT else 143), stderr
    assert stderr.splitlines()[-1] == ("stopped watching" if stop == signal.SIGINT else "atlasgen: terminated"), stderr


@pytest.mark.parametrize("verbosity", [[], ["-q"]])
def test_a_watch_prints_the_label_once_measured_and_its_failure_on_one_line(tmp_path, monkeypatch, write_material, verbosity):
    from atlasgen.cli import preview_cmd
    from atlasgen.errors import MaterialError
    from atlasgen.preview.previewer import Preview

    clay = write_material("clay", CLAY)
    measured = Preview(b"", ["clay"], label_timings={"measure": 0.2, "label": 0.0, "encode": 0.01})

    def fake_watch(paths, output, cache, on_label, **_):
        on_label(measured, None)
        on_label(measured, MaterialError("clay.toml", None, "report sample\nfailed"))

    monkeypatch.setattr(preview_cmd, "watch_preview", fake_watch)
    res = CliRunner().invoke(app, ["preview", str(clay), "--watch", "-o", str(tmp_path / "clay.png"), *verbosity])
    assert res.exit_code == 0, res.output
    failure = "atlasgen: error: clay.toml: report sample; failed (the picture stands without its error figures; watching)"
    assert res.stderr.splitlines()[-1] == failure
    assert res.stdout.splitlines() == ([] if verbosity else ["error figures measured in 0.210 s"])


@pytest.mark.slow
def test_a_material_the_atlas_holds_badly_is_shown_with_the_bake_s_warning(gpu_device, tmp_path, write_material):
    """A material ``bake`` warns about was previewed in silence: black balls, exit 0, no line."""
    lost = write_material("lost", 'type = "lambert"\nrgb_scale = 3e38\n')
    out = str(tmp_path / "lost.png")
    res = CliRunner().invoke(app, ["preview", str(lost), "--no-cache", "-o", out])
    assert res.exit_code == 0, res.output
    warning = f"atlasgen: warning: {lost.as_posix()}: material 'lost': 100.0% of the texels whose RGB is above 0 are stored as 0"
    assert [line[: len(warning)] for line in res.stderr.splitlines()] == [warning], res.stderr
    quiet = CliRunner().invoke(app, ["preview", str(lost), "--no-cache", "-o", out, "-q"])
    assert (quiet.exit_code, quiet.output) == (0, "")  # -q: errors only, as bake's


def test_a_watch_warns_once_a_picture_and_again_for_the_next(tmp_path, monkeypatch, write_material):
    """Each picture's warnings once: the draft picture's, then those its measured labels add, and again
    for the next save's picture."""
    from types import SimpleNamespace

    from atlasgen.cli import preview_cmd
    from atlasgen.preview.previewer import Preview
    from atlasgen.preview.watch import Update

    clay = write_material("clay", CLAY)
    draft = Preview(b"", ["clay"], bake=SimpleNamespace(warnings=[], material_warnings=["clay.toml: lost to 8 bits"]))
    measured = Preview(b"", ["clay"], label_timings={"measure": 0.2},
                       bake=SimpleNamespace(warnings=[], material_warnings=["clay.toml: lost to 8 bits", "clay.toml: 30%"]))  # fmt: skip

    def fake_watch(paths, output, cache, on_update, on_label, **_):
        for changed in ([], ["clay.toml"]):
            on_update(Update(changed, draft, timings={"total": 0.1}))
            on_label(measured, None)

    monkeypatch.setattr(preview_cmd, "watch_preview", fake_watch)
    res = CliRunner().invoke(app, ["preview", str(clay), "--watch", "-o", str(tmp_path / "clay.png")])
    assert res.exit_code == 0, res.output
    warnings = [line for line in res.stderr.splitlines() if line.startswith("atlasgen: warning: ")]
    assert warnings == ["atlasgen: warning: clay.toml: lost to 8 bits", "atlasgen: warning: clay.toml: 30%"] * 2


def test_the_reference_s_samples_are_bounded_as_validate_s_are(tmp_path):
    """An unbounded --reference-spp ran a CPU reference for as long as it was asked: days."""
    from atlasgen.cli.main import app

    (tmp_path / "grey.toml").write_text('type = "lambert"\n')
    res = CliRunner().invoke(
        app, ["preview", str(tmp_path / "grey.toml"), "--reference-spp", "65537", "-o", str(tmp_path / "p.png")]
    )
    assert res.exit_code == 2
    assert "'--reference-spp': 65537 is not in the range 4<=x<=65536" in res.output


def test_a_picture_over_a_file_the_material_reads_is_refused(mitsuba_llvm, tmp_path, monkeypatch):
    """Found by a hostile sweep: `preview tb.toml -o tex.png` replaced the texture the material reads with the
    picture (exit 0), and a watch saw its own write as a change and drew again, forever."""
    import numpy as np

    from atlasgen.io.images import write_png

    monkeypatch.chdir(tmp_path)
    write_png(tmp_path / "tex.png", np.full((4, 4, 3), 200, np.uint8))
    texture = (tmp_path / "tex.png").read_bytes()
    (tmp_path / "tb.toml").write_text('type = "bsdf"\ngloss = 0.5\nbsdf = { type = "diffuse", reflectance = '
                                      '{ type = "bitmap", filename = "tex.png" } }\n')  # fmt: skip
    res = CliRunner().invoke(app, ["preview", "tb.toml", "-o", "tex.png", "--no-cache"])
    assert res.exit_code == 4, res.output
    assert res.stderr == ("atlasgen: error: tex.png: the preview (-o) would overwrite a file the material file of 'tb' "
                          f"includes ({(tmp_path / 'tex.png').as_posix()}); expected an output path that is not an "
                          "input\n"), res.stderr  # fmt: skip
    assert (tmp_path / "tex.png").read_bytes() == texture
