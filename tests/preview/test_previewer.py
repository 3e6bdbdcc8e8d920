"""Previews: the labelled picture, contact sheets from one bake, bad inputs, and what the warm state keeps."""

from __future__ import annotations

import io

import numpy as np
import pytest

from atlasgen.errors import InputError, MaterialError, OutputError
from atlasgen.preview import previewer as previewer_module
from atlasgen.preview.previewer import Previewer, check_preview_output
from atlasgen.preview.scene import HEIGHT, WIDTH
from tests.conftest import ROOT

CLAY = 'type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n'


def decode(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


def test_outputs_are_checked_before_anything_runs(tmp_path, write_material):
    clay = write_material("clay", CLAY)
    with pytest.raises(OutputError, match=r"must end in \.png"):
        check_preview_output(tmp_path / "clay.jpg", [clay])
    (tmp_path / "folder.png").mkdir()
    with pytest.raises(OutputError, match="existing folder"):
        check_preview_output(tmp_path / "folder.png", [clay])
    with pytest.raises(InputError, match="no such file or folder"):
        check_preview_output(tmp_path / "x.png", [tmp_path / "missing.toml"])


def test_a_folder_without_materials_is_one_line(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match=r"empty: no material files; expected \.toml files"):
        Previewer(None).preview([tmp_path / "empty"])


@pytest.fixture(scope="module")
def warm(gpu_context, tmp_path_factory):
    """One previewer for the module's tests: the pipelines cost seconds on lavapipe."""
    return Previewer(tmp_path_factory.mktemp("cache"), gpu_context)


@pytest.mark.slow
def test_one_material_is_one_labelled_picture(warm, tmp_path, write_material):
    clay = write_material("clay", CLAY)
    out = tmp_path / "out" / "clay.png"
    shown = warm.write([clay], out)
    picture = decode(out.read_bytes())
    assert shown.names == ["clay"] and picture.shape[1] == WIDTH and picture.shape[0] > HEIGHT + 40
    steps = {"read", "bake", "render", "label", "encode", "write"}
    # The previewer's first preview makes the device and pipelines; a later one uploads the new atlas.
    assert set(shown.timings) in (steps | {"device", "pipelines"}, steps | {"upload"})
    # The sphere's and the ball's middles are the clay's colour (red above green above blue), the
    # background and floor grey.
    for x in (WIDTH // 2 - 150, WIDTH // 2 + 150):
        r, g, b = picture[HEIGHT // 2 - 40, x].astype(int)
        assert r > g > b and r > 80
    assert (warm.cache_dir / "clay.npz").is_file()
    # Again, unchanged: the same renderer, the cache's slices, no shader compiled, the same picture.
    renderer = warm.renderer
    again = warm.write([clay], out)
    assert warm.renderer is renderer and not again.compiled and again.png == shown.png
    assert set(again.timings) == steps | {"upload"}


@pytest.mark.slow
def test_several_materials_are_a_sheet_from_one_bake(warm, tmp_path, write_material, monkeypatch):
    for name, colour in (("red", [0.8, 0.1, 0.1]), ("green", [0.1, 0.8, 0.1]), ("blue", [0.1, 0.1, 0.8])):
        write_material(name, f'type = "lambert"\ncolour = {colour}\n')
    bakes = []
    real_bake = previewer_module.bake_atlas
    monkeypatch.setattr(previewer_module, "bake_atlas", lambda *a, **k: bakes.append(a) or real_bake(*a, **k))
    shown = warm.preview([tmp_path / "materials"])
    assert len(bakes) == 1 and shown.names == ["blue", "green", "red"]
    sheet = decode(shown.png)
    from atlasgen.preview.sheet import GAP

    cell_w = (sheet.shape[1] - 3 * GAP) // 2
    assert cell_w == WIDTH
    cell_h = (sheet.shape[0] - 3 * GAP) // 2
    # Cells in file order, row by row: blue, green / red; the fourth place is empty.
    for i, channel in enumerate((2, 1, 0)):
        y, x = GAP + (i // 2) * (cell_h + GAP) + HEIGHT // 2 - 40, GAP + (i % 2) * (cell_w + GAP) + WIDTH // 2 - 150
        assert np.argmax(sheet[y, x]) == channel
    assert sheet[GAP + cell_h + GAP + cell_h // 2, GAP + cell_w + GAP + cell_w // 2].max() < 20


@pytest.mark.slow
def test_a_bad_material_leaves_the_picture_as_it_was(warm, tmp_path, write_material):
    clay = write_material("clay", CLAY)
    out = tmp_path / "clay.png"
    warm.write([clay], out)
    before = out.read_bytes()
    clay.write_text('type = "lambert"\ncolour = [0.7, 0.5]\n')
    with pytest.raises(MaterialError) as info:
        warm.write([clay], out)
    assert str(info.value).startswith(clay.as_posix() + ": field 'colour'") and "\n" not in str(info.value)
    assert out.read_bytes() == before


READABLE = ("terracotta", "separable-gold", "skin")


@pytest.mark.parametrize("name", READABLE)
def test_a_lambert_a_metal_and_skin_read_well(name, shipped_library_cache, gpu_device):
    """The scene's light suits the three kinds it was picked for: on the objects, almost nothing is
    clipped white or left black, and the middle is a mid-tone (8-bit display codes)."""
    from atlasgen.render.output import display_codes

    shown = Previewer(shipped_library_cache, gpu_device)
    shown.preview([ROOT / "materials" / f"{name}.toml"])
    entries = {e.name: e for e in shown.renderer.atlas.manifest.materials}
    rendered = shown.renderer.render(shown.scene_for(name))
    codes = display_codes(rendered.radiance)[rendered.aov("id") == entries[name].id].astype(int)
    assert len(codes) > 0.2 * WIDTH * HEIGHT
    assert (codes.max(axis=1) >= 254).mean() < 0.03
    assert (codes.max(axis=1) < 10).mean() < 0.2
    assert 50 < np.median(codes.mean(axis=1)) < 200


GLOSSY = 'type = "separable"\nsource = "ggx"\nalpha = 0.3\nterms = 2\n'


@pytest.mark.slow
def test_a_drafts_picture_is_the_full_bakes_and_its_label_follows(warm, tmp_path, write_material):
    from atlasgen.preview.label import MEASURING, error_text, label_lines
    from atlasgen.preview.watch import describe_label

    glossy = write_material("glossy", GLOSSY)
    full = warm.preview([glossy], use_cache=False)  # a full bake, as `atlasgen preview` makes it
    draft = warm.preview([glossy], drafts=True)
    assert list(draft.pending) == ["glossy"] and full.pending == {}
    assert draft.shots[0].lines[:2] == full.shots[0].lines[:2] and draft.shots[0].lines[2] == MEASURING
    np.testing.assert_array_equal(draft.shots[0].radiance, full.shots[0].radiance)
    # The picture above the label is the full bake's; only the label differs.
    picture, full_picture = decode(draft.png), decode(full.png)
    np.testing.assert_array_equal(picture[:HEIGHT], full_picture[:HEIGHT])
    assert not (warm.cache_dir / "glossy.npz").exists()
    warm.complete(draft)
    # Now the label is the one a full bake's manifest gives, the PNG the full preview's, byte for byte.
    entry = full.manifest.entry_named("glossy")
    assert draft.pending == {} and draft.shots[0].lines == label_lines(entry) and error_text(entry) in draft.shots[0].lines
    assert error_text(entry).startswith("error: ") and "%" in error_text(entry)
    assert draft.png == full.png and set(draft.label_timings) == {"measure", "label", "encode"}
    assert describe_label(draft).startswith(f"glossy: {error_text(entry)} (measured in ")
    assert (warm.cache_dir / "glossy.npz").is_file()  # the completion filled the cache
    again = warm.preview([glossy], drafts=True)
    assert again.pending == {} and again.png == full.png


def test_the_ball_s_mesh_file_is_written_again_where_it_has_gone(tmp_path):
    """Found by a hostile sweep: `rm -rf build` (make clean) under a watch removed the ball's mesh file, which the
    previewer remembered: every later save failed on "no such mesh file", and the watch never drew again."""
    import shutil

    previewer = Previewer(tmp_path / "cache")
    first = previewer.ball_file
    assert first.is_file()
    shutil.rmtree(tmp_path / "cache")
    assert previewer.ball_file == first and first.is_file()
    assert previewer.scene_for("clay").objects  # the scene's parser finds the mesh file it names


@pytest.mark.parametrize("name", ["atlasgen-preview-floor", "Atlasgen_Preview_Floor"])
def test_a_material_named_as_the_floor_is_the_one_refused(tmp_path, name):
    """Found by a hostile sweep: the refusal named the floor's installed file, which no user can edit."""
    material = tmp_path / "fl.toml"
    material.write_text(f'type = "lambert"\nname = "{name}"\n')
    with pytest.raises(MaterialError) as info:
        Previewer(None).preview([material])
    assert str(info.value).startswith(f"{material.as_posix()}: field 'name': duplicate material name {name!r}"), info.value
