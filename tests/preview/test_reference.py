"""``--reference``: the physical reference of the preview scene beside the picture, its label, and the watch's
background refinement (Mitsuba's LLVM variant and a GPU: slow)."""

from __future__ import annotations

import io
import threading
import time

import numpy as np
import pytest

from atlasgen.preview.previewer import Previewer
from atlasgen.preview.reference import ReferenceShot, reference_lines
from atlasgen.preview.scene import HEIGHT, WIDTH
from atlasgen.preview.watch import watch_preview

CLAY = 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n'
TOON = 'type = "toon"\nthresholds = [0.05, 0.55]\ncolours = ["#3a2f5b", "#8c7fb8", "#f2eefc"]\n'


def decode(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


def test_a_converged_shot_is_labelled_without_refining():
    lines = reference_lines(ReferenceShot("clay", np.zeros((1, 1, 3)), "diffuse", 64, 52.0, 40.0, 1.0, True))
    assert lines[1] == "64 spp, noise floor 52.0 dB" and "PSNR 40.0 dB" in lines[2]
    # Final without converging: the cap stopped it.
    assert reference_lines(ReferenceShot("c", np.zeros((1, 1, 3)), "d", 8, 30.0, 40.0, 1.0, True))[1].endswith("(at the cap)")


@pytest.mark.slow
def test_a_lambert_reference_matches_the_atlas_picture(gpu_context, mitsuba_llvm, write_material, tmp_path):
    shown = Previewer(tmp_path / "cache", gpu_context).write([write_material("clay", CLAY)], tmp_path / "clay.png",
                                                              reference=True, max_spp=16)  # fmt: skip
    ref = shown.references["clay"]
    # Measured: 30.4 dB at 16 spp with a floor of 24.6 dB; the error is the reference's noise, so it is a bound.
    assert ref.spp == 16 and ref.final and ref.psnr_db > 28.0 and ref.floor_db > 20.0
    picture = decode((tmp_path / "clay.png").read_bytes())
    assert picture.shape[1] > 2 * WIDTH and picture.shape[0] > HEIGHT
    # The reference (right) shows the clay's colour where the atlas picture (left) does.
    left, right = picture[HEIGHT // 2 - 40, 4 + WIDTH // 2 - 150], picture[HEIGHT // 2 - 40, 8 + WIDTH + WIDTH // 2 - 150]
    assert right[0] > right[1] > right[2] and np.abs(left.astype(int) - right.astype(int)).max() < 30
    assert "16 spp, noise floor" in reference_lines(ref)[1]


@pytest.mark.slow
def test_a_material_without_a_physical_reference_says_so(gpu_context, write_material, tmp_path):
    shown = Previewer(tmp_path / "cache", gpu_context).write([write_material("hero", TOON)], tmp_path / "hero.png",
                                                              reference=True)  # fmt: skip
    ref = shown.references["hero"]
    assert ref.image is None and reference_lines(ref) == ["hero: no physical reference", "no reference image"]
    assert "reference" in shown.timings


@pytest.mark.slow
def test_the_watch_writes_the_picture_before_the_reference(gpu_context, mitsuba_llvm, write_material, tmp_path):
    clay, out = write_material("clay", CLAY), tmp_path / "clay.png"
    stop, events = threading.Event(), []

    def on_update(update):
        events.append(("picture", time.perf_counter(), out.read_bytes(), update.preview.references))

    def on_reference(name, shot):
        events.append(("reference", time.perf_counter(), out.read_bytes(), shot))
        if shot is None or not isinstance(shot, ReferenceShot) or shot.final:
            stop.set()

    watcher = threading.Thread(target=watch_preview, args=([clay], out), daemon=True,
                               kwargs={"previewer": Previewer(tmp_path / "cache", gpu_context), "stop": stop,
                                       "reference": True, "max_spp": 8, "on_update": on_update, "on_reference": on_reference})  # fmt: skip
    watcher.start()
    assert stop.wait(300)
    watcher.join(10)
    kinds = [e[0] for e in events]
    assert kinds == ["picture", "reference", "reference"], kinds
    assert [e[3].spp for e in events[1:]] == [4, 8] and events[2][3].final
    first, refined = decode(events[0][2]), decode(events[2][2])
    # The first PNG has the atlas picture and a dark panel where the reference will be; the refinement
    # rewrites the PNG with the same atlas picture and the reference beside it.
    x = 8 + WIDTH + WIDTH // 2 - 150
    assert first.shape == refined.shape and (first[HEIGHT // 2 - 40, x] == 24).all()
    assert (refined[:HEIGHT, :WIDTH] == first[:HEIGHT, :WIDTH]).all() and refined[HEIGHT // 2 - 40, x, 0] > 60
