"""Every report page, opened in headless Chromium at 1280 px: images load, nothing overflows, no console errors.

Needs Debian's ``chromium`` and ``chromium-driver`` (``make setup`` installs them) and
selenium; skips cleanly without them. Full-page screenshots land in
``build/screenshots/`` for a person to look at.
"""

from __future__ import annotations

import base64
import textwrap
from pathlib import Path

import pytest

from tests.chromium import start_chromium

pytestmark = pytest.mark.slow

WIDTH = 1280
SCREENSHOTS = Path(__file__).resolve().parents[2] / "build" / "screenshots"
#: A lambert and a separable material: one LUT page row, one factor-slice row and a separable study.
MATERIALS = {
    "clay": 'type = "lambert"\ncolour = [0.7, 0.4, 0.2]\n',
    "gloss": 'type = "separable"\nsource = "ggx"\nalpha = 0.3\nterms = 2\n',
}


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    """A headless Chromium at 1280 CSS px wide, through chromedriver."""
    driver = start_chromium(
        tmp_path_factory.mktemp("chromium-profile"),
        ("--allow-file-access-from-files", f"--window-size={WIDTH},900", "--force-device-scale-factor=1"),
    )
    # The layout viewport, whatever the window decorations take: exactly WIDTH CSS px.
    driver.execute_cdp_cmd(
        "Emulation.setDeviceMetricsOverride", {"width": WIDTH, "height": 900, "deviceScaleFactor": 1, "mobile": False}
    )
    yield driver
    driver.quit()


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    """A baked atlas of :data:`MATERIALS` and its materials folder."""
    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.materials.material import read_materials

    root = tmp_path_factory.mktemp("browser")
    (root / "materials").mkdir()
    for name, text in MATERIALS.items():
        (root / "materials" / f"{name}.toml").write_text(textwrap.dedent(text))
    atlas = root / "build" / "atlas.dds"
    write_bake(bake_atlas(read_materials([root / "materials"])), atlas)
    return root, atlas


def check_page(driver, page: Path, shot: str) -> dict:
    """Open ``page``, assert what every report page must satisfy, save a full-page screenshot."""
    driver.get_log("browser")  # drop what earlier pages logged
    driver.get(page.absolute().as_uri())  # the documented path: resolved, it is the generation's file
    driver.execute_script("return document.readyState")
    images = driver.execute_script(
        "return Array.from(document.images).map(i => [i.getAttribute('src'), i.complete, i.naturalWidth]);"
    )
    assert images, f"{page}: no images"
    broken = [src for src, complete, width in images if not complete or width == 0]
    assert broken == [], f"{page}: images that did not load: {broken}"
    severe = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    assert severe == [], f"{page}: console errors: {severe}"
    scroll_width = driver.execute_script("return document.documentElement.scrollWidth")
    assert scroll_width <= WIDTH, f"{page}: {scroll_width} px wide, over {WIDTH}"
    # No element reaches past the viewport, and no scroll box hides part of what it holds (a clipped chart).
    wide = driver.execute_script(
        "return Array.from(document.body.querySelectorAll('*')).filter(e => {"
        " const r = e.getBoundingClientRect(); const s = getComputedStyle(e);"
        " const clips = ['auto', 'scroll', 'hidden'].includes(s.overflowX) && e.scrollWidth > e.clientWidth + 1;"
        " return r.right > window.innerWidth + 0.5 || clips; })"
        ".map(e => e.tagName + (e.className ? '.' + e.className : '') + ' ' + Math.round(e.getBoundingClientRect().right)"
        " + '/' + e.scrollWidth);"
    )
    assert wide == [], f"{page}: elements wider than the {WIDTH} px viewport or clipped: {wide[:8]}"
    # A chart's point labels (HTML text over its image, class point-label) do not overlap one another.
    boxes = driver.execute_script(
        "const charts = []; return Array.from(document.querySelectorAll('.point-label')).map(e => {"
        " const c = e.parentElement; if (!charts.includes(c)) charts.push(c); const r = e.getBoundingClientRect();"
        " return [charts.indexOf(c), e.textContent.trim(), r.left, r.top, r.right, r.bottom]; });"
    )
    overlaps = [(a[:2], b[:2]) for i, a in enumerate(boxes) for b in boxes[i + 1 :]
                if a[0] == b[0] and a[2] < b[4] and b[2] < a[4] and a[3] < b[5] and b[3] < a[5]]  # fmt: skip
    assert overlaps == [], f"{page}: point labels overlap: {overlaps[:5]}"
    height = driver.execute_script("return document.documentElement.scrollHeight")
    shot_data = driver.execute_cdp_cmd("Page.captureScreenshot", {
        "format": "png", "captureBeyondViewport": True,
        "clip": {"x": 0, "y": 0, "width": WIDTH, "height": height, "scale": 1}})  # fmt: skip
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    (SCREENSHOTS / f"{shot}.png").write_bytes(base64.b64decode(shot_data["data"]))
    return {"images": images, "height": height, "labels": boxes}


def test_library_and_separable_pages(browser, library, tmp_path):
    from atlasgen.materials.material import read_material
    from atlasgen.reports.library import write_library_report
    from atlasgen.reports.separable import write_separable_report

    root, atlas = library
    separable = write_separable_report([read_material(root / "materials" / "gloss.toml")], root / "build" / "separable",
                                       atlas_path=atlas, resolutions=(8, 16), repeats=1,
                                       parametrizations=("half_diff", "in_out"))  # fmt: skip
    check_page(browser, separable["html"], "separable")
    index = write_library_report(atlas, root / "build" / "report", separable_dir=separable["html"].parent)
    shown = check_page(browser, index, "library")
    assert shown["labels"], "the library page's charts label their fronts"  # so the overlap check saw labels
    # The library page links the separable report's HTML page, which the check above opened.
    assert browser.execute_script("return Array.from(document.links).some(a => a.href.endsWith('/separable/index.html'))")
    assert len(shown["images"]) >= 2


@pytest.mark.mitsuba
@pytest.mark.gpu
def test_validation_pages(browser, library, gpu_device, mitsuba_llvm):
    from atlasgen.reports.validation import merge_validation_reports, write_validation
    from atlasgen.validate.run import validate_atlas

    root, atlas = library
    out = root / "build" / "validation"
    for name in MATERIALS:
        run = validate_atlas(atlas, [name], scenes=["front"], resolution=(48, 36), physical_spp=4, max_physical_spp=64)
        write_validation(run, out / "materials" / name)
    merge_validation_reports([out / "materials" / name for name in MATERIALS], out)
    shown = check_page(browser, out / "index.html", "validation")
    assert shown["labels"], "the validation plot labels its front"
    for name in MATERIALS:
        check_page(browser, out / "materials" / name / "index.html", f"validation-{name}")
    # Images at their native size (the default view), pixel for pixel.
    sizes = browser.execute_script(
        "return Array.from(document.querySelectorAll('.figures img')).map(i => [i.naturalWidth, i.naturalHeight, i.width, i.height]);"
    )
    assert sizes and all(s == [48, 36, 48, 36] for s in sizes), sizes
    # Every material shows the same figures in the same order: the captions differ only in the material's numbers.
    rows = browser.execute_script(
        "return Array.from(document.querySelectorAll('.figures')).map(f => f.querySelectorAll('figure').length);"
    )
    assert len(set(rows)) == 1 and rows[0] == 7, rows
    # The zoom is a whole factor and keeps pixels square.
    browser.execute_script("document.getElementById('zoom3').click()")
    zoomed = browser.execute_script(
        "const i = document.querySelector('.figures img'); const r = i.getBoundingClientRect();"
        "return [r.width, r.height, getComputedStyle(i).imageRendering];"
    )
    assert zoomed == [144, 108, "pixelated"]
    assert browser.execute_script("return document.documentElement.scrollWidth") <= WIDTH
    assert shown["height"] > 0
    # The library page with validation's figures beside each material: its widest table fits the page
    # (1392 px of columns once, in a scroll box that hid each material's cost chart).
    from atlasgen.reports.library import write_library_report

    index = write_library_report(atlas, root / "build" / "report-validated", validation_dir=out, physical=False)
    check_page(browser, index, "library-validated")
    assert browser.execute_script("return document.querySelectorAll('table.inner').length") >= len(MATERIALS)


def test_the_checks_catch_a_clipped_chart_and_overlapping_labels(browser, tmp_path):
    """check_page fails on a page whose chart is clipped by its scroll box, and on one whose labels overlap."""
    pixel = base64.b64decode("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8BQDwAEhQGAhKmMIQAAAABJRU5ErkJggg==")
    (tmp_path / "p.png").write_bytes(pixel)
    clipped = '<div class="scroll" style="overflow-x: auto; width: 300px"><img src="p.png" width="900" height="10"></div>'
    overlapping = ('<div style="position: relative"><img src="p.png" width="200" height="100">'
                   '<span class="point-label" style="position: absolute; left: 10px; top: 10px">alpha</span>'
                   '<span class="point-label" style="position: absolute; left: 20px; top: 14px">beta</span></div>')  # fmt: skip
    for name, body, message in (("clipped", clipped, "clipped"), ("overlapping", overlapping, "overlap")):
        page = tmp_path / f"{name}.html"
        page.write_text(f"<!DOCTYPE html><html><body>{body}</body></html>")
        with pytest.raises(AssertionError, match=message):
            check_page(browser, page, f"check-{name}")
