"""``watch_preview``: real file writes (in place, renamed over, broken, fixed) from a thread, checked
against the PNG and the printed lines. A stand-in previewer keeps the fast tests off the GPU."""

from __future__ import annotations

import os
import queue
import threading
from pathlib import Path

import pytest

from atlasgen.materials.material import read_materials
from atlasgen.preview.previewer import Preview
from atlasgen.preview.watch import Update, describe_update, watch_preview

CLAY = 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n'
#: Seconds a step of a test waits for the watch before failing.
PATIENCE = 20.0


class StandIn:
    """A previewer whose picture is the material files' bytes: reads them as the real one does
    (a bad file raises the same MaterialError), and records each call."""

    def __init__(self, extra_inputs=()):
        self.calls: list[bool] = []
        self.extra_inputs = [Path(p) for p in extra_inputs]

    def write(self, paths, output, use_cache=True, drafts=False):
        self.calls.append(use_cache)
        materials = read_materials(paths)
        png = b"".join(Path(m.source).read_bytes() for m in materials)
        Path(output).write_bytes(png)
        inputs = [Path(m.source) for m in materials] + self.extra_inputs
        return Preview(png, [m.name for m in materials], {"bake": 0.001, "render": 0.002}, inputs)


def run_watch(paths, output, previewer, script, max_updates, **options):
    """Watch in this thread while ``script(next_update)`` acts from another; return the updates and lines.

    ``next_update()`` returns the next :class:`Update` (the first is the first picture). A script
    that fails, or a watch that stalls, ends the test instead of hanging it.
    """
    updates: queue.Queue[Update] = queue.Queue()
    lines: list[str] = []
    stop, failures = threading.Event(), []

    def next_update() -> Update:
        try:
            return updates.get(timeout=PATIENCE)
        except queue.Empty:
            raise AssertionError("the watch reported nothing") from None

    def act():
        try:
            script(next_update)
        except BaseException as exc:  # noqa: BLE001 - re-raised in the test's thread
            failures.append(exc)
            stop.set()

    actor = threading.Thread(target=act, daemon=True)
    timer = threading.Timer(6 * PATIENCE, stop.set)
    actor.start(), timer.start()
    try:
        done = watch_preview(paths, output, stop=stop, max_updates=max_updates, echo=lines.append, on_update=updates.put,
                             previewer=previewer, **options)  # fmt: skip
    finally:
        timer.cancel()
        actor.join(PATIENCE)
    if failures:
        raise failures[0]
    assert not stop.is_set() or done == max_updates, "the watch was stopped by the test's timer"
    return done, lines


def rename_over(path: Path, text: str) -> None:
    """Save as vim and most IDEs do: a new file beside the old one, renamed over it."""
    temporary = path.with_name(f".{path.name}.swp")
    temporary.write_text(text)
    os.replace(temporary, path)


def test_saves_in_place_renamed_over_broken_and_fixed(write_material, tmp_path):
    clay = write_material("clay", CLAY)
    out = tmp_path / "materials" / "clay.png"  # in the watched folder: its own writes must not count
    previewer = StandIn()
    seen = []

    def script(next_update):
        first = next_update()
        assert first.changed == [] and first.preview is not None and out.read_bytes() == CLAY.encode()
        for text, save in ((CLAY.replace("0.3", "0.2"), Path.write_text), (CLAY.replace("0.3", "0.1"), rename_over)):
            save(clay, text)
            update = next_update()
            assert update.changed == [clay.as_posix()] and update.error is None
            assert out.read_bytes() == text.encode()
            seen.append(update)
        (tmp_path / "materials" / "notes.txt").write_text("not a material\n")
        clay.write_text('type = "lambert"\ncolour = [0.7, 0.5]\n')
        broken = next_update()
        assert broken.changed == [clay.as_posix()] and broken.preview is None
        assert "field 'colour'" in str(broken.error) and out.read_bytes() == CLAY.replace("0.3", "0.1").encode()
        rename_over(clay, CLAY)
        assert next_update().error is None and out.read_bytes() == CLAY.encode()

    done, lines = run_watch([clay], out, previewer, script, max_updates=4)
    assert done == 4 and len(previewer.calls) == 5 and all(previewer.calls)
    assert lines[0].startswith(f"first picture: {out.as_posix()} in ")
    assert lines[1] == describe_update(seen[0], out) and lines[1].startswith(f"{clay.as_posix()} changed: {out.as_posix()} in ")
    assert "(bake 0.001, render 0.002)" in lines[1]
    assert lines[3].startswith(f"{clay.as_posix()} changed: kept the last picture ({clay.as_posix()}: field 'colour'")
    assert len(lines) == 5 and all("\n" not in line for line in lines)


def test_a_material_broken_from_the_start_says_there_is_no_picture_yet(write_material, tmp_path):
    clay = write_material("clay", 'type = "lambert"\ncolour = [0.7, 0.5]\n')
    out = tmp_path / "clay.png"

    def script(next_update):
        first = next_update()
        assert first.preview is None and "field 'colour'" in str(first.error) and not out.exists()
        assert describe_update(first, out).startswith("first picture: no picture yet (")
        rename_over(clay, CLAY)
        assert next_update().error is None and out.exists()
        clay.write_text('type = "lambert"\ncolour = [0.7, 0.5]\n')
        assert describe_update(next_update(), out).startswith(f"{clay.as_posix()} changed: kept the last picture (")

    run_watch([clay], out, StandIn(), script, max_updates=2)


def test_a_folder_or_a_link_in_the_picture_s_place_is_no_picture_kept(tmp_path):
    """Found by a hostile sweep: with the picture replaced by a folder, a failed update said "kept the last picture"."""
    from atlasgen.preview.watch import picture_kept

    (tmp_path / "p.png").mkdir()
    (tmp_path / "a.toml").write_text(CLAY)
    (tmp_path / "l.png").symlink_to(tmp_path / "a.toml")
    (tmp_path / "f.png").write_bytes(b"png")
    kept = [picture_kept(tmp_path / name) for name in ("p.png", "l.png", "f.png", "none.png")]
    assert kept == ["no picture yet", "no picture yet", "kept the last picture", "no picture yet"]


def test_a_folder_takes_new_material_files(write_material, tmp_path):
    write_material("clay", CLAY)
    folder, out = tmp_path / "materials", tmp_path / "sheet.png"

    def script(next_update):
        assert next_update().preview.names == ["clay"]
        # Emacs's lock link while clay.toml is edited: hidden and pointing nowhere, it is no material file.
        os.symlink("user@host.1234:1700000000", folder / ".#clay.toml")
        (folder / "snow.toml").write_text('type = "lambert"\n')
        update = next_update()
        assert update.changed == [os.path.relpath(folder / "snow.toml")] and update.preview.names == ["clay", "snow"]

    run_watch([folder], out, StandIn(), script, max_updates=1)


def test_a_file_a_material_names_is_watched_and_baked_afresh(write_material, tmp_path):
    clay = write_material("clay", CLAY)
    data = tmp_path / "elsewhere" / "measured.bsdf"
    data.parent.mkdir()
    data.write_bytes(b"1")
    previewer = StandIn(extra_inputs=[data])

    def script(next_update):
        next_update()
        # The watch now covers the data's folder too; give it a moment to start there.
        threading.Event().wait(0.5)
        data.write_bytes(b"2")
        assert next_update().changed == [data.as_posix()]
        clay.write_text(CLAY.replace("0.3", "0.2"))
        assert next_update().changed == [clay.as_posix()]

    run_watch([clay], tmp_path / "clay.png", previewer, script, max_updates=2)
    # The bake cache's key is the material file: a change to the data bakes without it.
    assert previewer.calls == [True, False, True]


def test_an_output_that_is_not_a_png_is_refused_before_watching(write_material, tmp_path):
    from atlasgen.errors import OutputError

    clay = write_material("clay", CLAY)
    with pytest.raises(OutputError, match=r"must end in \.png"):
        watch_preview([clay], tmp_path / "clay.toml", previewer=StandIn(), max_updates=1)


@pytest.mark.slow
def test_the_real_preview_follows_saves_on_a_warm_renderer(gpu_device, write_material, tmp_path):
    import io

    import numpy as np
    from PIL import Image

    from atlasgen.preview.previewer import Previewer
    from atlasgen.preview.scene import HEIGHT, WIDTH

    clay = write_material("clay", CLAY)
    out = tmp_path / "clay.png"
    previewer = Previewer(tmp_path / "cache", gpu_device)

    def centre_of_sphere():
        return np.asarray(Image.open(io.BytesIO(out.read_bytes())).convert("RGB"))[HEIGHT // 2 - 40, WIDTH // 2 - 150].astype(int)

    def script(next_update):
        assert next_update().preview.compiled
        r, g, b = centre_of_sphere()
        assert r > g > b
        renderer = previewer.renderer
        # Blue now: another peak, so another scale; the renderer takes it from a buffer: no shader compiled.
        rename_over(clay, 'type = "lambert"\ncolour = [0.1, 0.2, 0.6]\n')
        update = next_update()
        assert update.error is None and not update.preview.compiled and previewer.renderer is renderer
        r, g, b = centre_of_sphere()
        assert b > g > r
        blue = out.read_bytes()
        clay.write_text('type = "lambert"\ncolour = "#12"\n')
        assert next_update().error is not None and out.read_bytes() == blue
        # The same peak with other channels: only the texels are uploaded.
        rename_over(clay, 'type = "lambert"\ncolour = [0.3, 0.2, 0.6]\n')
        update = next_update()
        assert update.error is None and not update.preview.compiled and centre_of_sphere()[0] > r

    done, lines = run_watch([clay], out, previewer, script, max_updates=3)
    assert "lighting shader compiled" in lines[0] and not any("lighting shader compiled" in line for line in lines[1:])


class Drafting(StandIn):
    """A stand-in whose pictures are drafts: the PNG is the file's bytes, and completing it appends the
    label; ``fail`` makes the completion raise as a material's figures can."""

    def __init__(self, fail: bool = False):
        super().__init__()
        self.fail, self.completed = fail, []

    def write(self, paths, output, use_cache=True, drafts=False):
        preview = super().write(paths, output, use_cache)
        if drafts:
            preview.pending = {name: None for name in preview.names}
        return preview

    def complete(self, preview, references=None):
        from atlasgen.errors import MaterialError

        if self.fail:
            raise MaterialError("clay.toml", None, "the report sample failed")
        self.completed.append(Path(self.out).read_bytes())  # the draft picture stands until now
        preview.png += b"+label"
        preview.pending, preview.label_timings = {}, {"measure": 0.25, "label": 0.0, "encode": 0.01}
        return preview


@pytest.mark.parametrize("fail", [False, True])
def test_a_drafts_picture_comes_first_and_its_label_right_after(write_material, tmp_path, fail):
    clay = write_material("clay", CLAY)
    out = tmp_path / "clay.png"
    previewer, labelled = Drafting(fail), []
    previewer.out = out

    def script(next_update):
        next_update()
        rename_over(clay, CLAY.replace("0.3", "0.2"))
        update = next_update()
        # The picture is reported while the label is still to come.
        assert update.error is None and update.preview.pending == {"clay": None}

    done, lines = run_watch([clay], out, previewer, script, max_updates=1,
                            on_label=lambda preview, error: labelled.append((preview.png, error)))  # fmt: skip
    saved = CLAY.replace("0.3", "0.2").encode()
    assert lines[0].startswith("first picture: ") and lines[2].startswith(f"{clay.as_posix()} changed: ") and len(lines) == 4
    if fail:
        assert [png for png, _ in labelled] == [CLAY.encode(), saved] and all("report sample" in str(e) for _, e in labelled)
        assert lines[3].startswith("error figures: not measured, the picture keeps its label (clay.toml: the report sample")
        assert out.read_bytes() == saved
    else:
        assert previewer.completed == [CLAY.encode(), saved] and [e for _, e in labelled] == [None, None]
        assert [png for png, _ in labelled] == [CLAY.encode() + b"+label", saved + b"+label"]
        assert lines[1] == lines[3] == "error figures measured in 0.260 s"
        assert out.read_bytes() == saved + b"+label"


def test_a_bad_save_leaves_the_kept_picture_s_references_rendering(write_material, tmp_path, monkeypatch):
    """Found by a hostile sweep: with --reference, a bad save cancelled the kept picture's references and nothing
    started them again; the picture said "reference: rendering" for good. A stand-in reference that renders until
    it is cancelled counts its starts: one for the first picture, one more after the bad save."""
    from types import SimpleNamespace

    from atlasgen.preview import watch as watch_module

    starts: queue.Queue[int] = queue.Queue()

    def refine_reference(mi, scene, entry, manifest, radiance, aovs, max_spp=None, stop=None):
        starts.put(1)
        stop.wait(PATIENCE)
        return iter(())

    monkeypatch.setattr(watch_module, "load_reference_mitsuba", lambda: None)
    monkeypatch.setattr(watch_module, "refine_reference", refine_reference)
    monkeypatch.setattr(watch_module, "compose_picture", lambda shots, references: None)
    monkeypatch.setattr(watch_module, "encode_png", lambda picture, compression=None: b"png")

    class WithShots(StandIn):
        def preview(self, paths, use_cache=True, aovs=False, drafts=False, output=None):
            shown = self.write(paths, tmp_path / "scratch.png", use_cache)
            shown.shots = [SimpleNamespace(name="clay", scene=None, entry=None, radiance=None, aovs=None)]
            return shown

    clay = write_material("clay", CLAY)

    def script(next_update):
        assert next_update().error is None
        assert starts.get(timeout=PATIENCE) == 1  # the first picture's references
        clay.write_text('type = "lambert"\ncolour = [0.7, 0.5]\n')
        assert next_update().error is not None
        # Started before the update is reported: well inside the time run_watch waits for this script.
        assert starts.get(timeout=PATIENCE / 4) == 1, "the kept picture's references were not started again"

    run_watch([clay], tmp_path / "clay.png", WithShots(), script, max_updates=1, reference=True)


@pytest.mark.parametrize("where", ["another folder", "the same folder"])
def test_saves_to_a_linked_material_s_target_are_seen(tmp_path, where):
    """Found by a hostile sweep: with the material given as a symbolic link, saves to its target (what an editor
    writes) were never seen, in another folder or in the link's own."""
    real = tmp_path / ("real" if where == "another folder" else "mats") / "b.toml"
    real.parent.mkdir()
    real.write_text(CLAY)
    (tmp_path / "mats").mkdir(exist_ok=True)
    link = tmp_path / "mats" / "clay.toml"
    link.symlink_to(real)
    out = tmp_path / "clay.png"

    def script(next_update):
        assert next_update().error is None and out.read_bytes() == CLAY.encode()
        rename_over(real, CLAY.replace("0.3", "0.2"))
        update = next_update()
        assert update.changed == [link.as_posix()] and out.read_bytes() == CLAY.replace("0.3", "0.2").encode()
        real.write_text('type = "lambert"\ncolour = [0.7, 0.5]\n')
        assert "field 'colour'" in str(next_update().error)

    done, _ = run_watch([link], out, StandIn(), script, max_updates=2)
    assert done == 2


@pytest.mark.parametrize("given", ["the file", "the folder"])
def test_a_folder_removed_and_made_again_is_watched_again(tmp_path, given):
    """Found by a hostile sweep: after `rm -rf mats` and the folder made again (a checkout does both), the watch
    said the file was gone, then saw no save at all, good or bad."""
    import shutil

    folder = tmp_path / "mats"
    folder.mkdir()
    clay = folder / "clay.toml"
    clay.write_text(CLAY)
    out = tmp_path / "clay.png"

    def script(next_update):
        assert next_update().error is None
        shutil.rmtree(folder)
        gone = next_update()
        assert gone.preview is None and "no such file or folder" in str(gone.error)
        folder.mkdir()
        clay.write_text(CLAY.replace("0.3", "0.2"))
        back = next_update()
        assert back.error is None and out.read_bytes() == CLAY.replace("0.3", "0.2").encode(), back
        clay.write_text('type = "lambert"\ncolour = [0.7, 0.5]\n')
        assert "field 'colour'" in str(next_update().error)

    run_watch([clay if given == "the file" else folder], out, StandIn(), script, max_updates=3)
