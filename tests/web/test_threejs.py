"""The three.js example (web/atlas.js, docs/engine-integration.md) in headless Chromium: a KTX2 atlas
loaded with ktx-parse, every mip level, sampled by the GLSL include's ``atlas_sample`` in WebGL2.

web/probe.html renders ``atlas_sample`` at a grid of (material, N.L, N.V, lod) points into an RGBA32F
target (EXT_color_buffer_float on SwiftShader) and reads it back; the test compares each value with
the CPU sampler, :func:`atlasgen.optics.interpolation.sample_slice` over the decoded slice (and the
same bilinear lookup on the level's texels for lod > 0). Needs Chromium, chromedriver, selenium and
``web/node_modules`` (``make setup`` runs ``npm ci`` there); skips, saying which is missing, without.
"""

from __future__ import annotations

import functools
import http.server
import re
import shutil
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest

from atlasgen.contract import HEIGHT, WIDTH, atlas_uv
from atlasgen.optics.interpolation import interpolate_2d, sample_slice

ROOT = Path(__file__).resolve().parents[2]
WEB = ROOT / "web"
#: A lambert (sRGB-sensitive colour), a toon read at its nearest texel, and a Fresnel fit with a
#: scale above 1 (its slices are stored as texel * scale).
MATERIALS = ("terracotta", "toon-hero", "separable-gold")
LODS = (0, 1, 3)
#: |three.js - CPU| allowed, absolute. A float render target leaves the f32 filtering and, for an sRGB
#: atlas, the sampler's sRGB decode (SwiftShader's is within 1e-5 of the exact formula here).
TOLERANCE = 5e-5


def test_the_doc_shows_the_example_as_it_is():
    """docs/engine-integration.md's three.js block is web/atlas.js, character for character."""
    doc = (ROOT / "docs" / "engine-integration.md").read_text()
    blocks = re.findall(r"```js\n(.*?)```", doc, re.S)
    assert (WEB / "atlas.js").read_text() in blocks, "docs/engine-integration.md: no ```js block equal to web/atlas.js"
    assert f"within {TOLERANCE:.0e} of".replace("e-0", "e-") in doc, "docs/engine-integration.md: not the test's tolerance"


@pytest.fixture(scope="module")
def atlases(tmp_path_factory):
    """KTX2 bakes of :data:`MATERIALS`, sRGB and linear, with their includes: {encoding: path}."""
    from atlasgen.bake.pipeline import bake_atlas, write_bake
    from atlasgen.materials.material import read_materials

    folder = tmp_path_factory.mktemp("atlas")
    materials = read_materials([ROOT / "materials" / f"{n}.toml" for n in MATERIALS])
    paths = {}
    for encoding in ("srgb", "linear"):
        paths[encoding] = folder / f"{encoding}.ktx2"
        write_bake(bake_atlas(materials, "array", encoding == "linear", {}), paths[encoding])
    return paths


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("glslangValidator") is None, reason="glslangValidator (Debian glslang-tools) is not installed")
@pytest.mark.parametrize("layout", ["array", "volume"])
def test_glslang_compiles_the_documented_webgl_shading(atlases, tmp_path, layout):
    """GLSL ES 3.00 as the page builds it (prelude, include, body) with the doc's two lines in the body; a volume
    include's texture3D parameters failed to compile (the prelude named the 2D kinds only)."""
    doc = (ROOT / "docs" / "engine-integration.md").read_text()
    section = doc[doc.index("## three.js") :]
    usage = re.search(r"```glsl\n(.*?)```", section, re.S)[1]
    prelude = re.search(r"GLSL_ES_PRELUDE = `(.*?)`;", (WEB / "atlas.js").read_text(), re.S)[1]
    include = atlases["srgb"].with_suffix(".glsl")
    if layout == "volume":
        from atlasgen.bake.pipeline import bake_atlas, write_bake
        from atlasgen.materials.material import read_materials

        include = tmp_path / "volume.ktx2"
        write_bake(bake_atlas(read_materials([ROOT / "materials" / "terracotta.toml"]), "volume", False, {}), include)
        include = include.with_suffix(".glsl")
    source = tmp_path / "shading.frag"
    source.write_text(f"""#version 300 es
{prelude}{include.read_text()}
uniform {"sampler3D" if layout == "volume" else "sampler2DArray"} atlas;
out vec4 fragColor;
void main() {{
    vec3 n = vec3(0.0, 0.0, 1.0); vec3 l = vec3(0.6, 0.0, 0.8); vec3 v = vec3(0.0, 0.6, 0.8);
    vec3 E = vec3(2.0); vec3 albedo = vec3(0.8); float gloss = 0.5; uint material = MATERIAL_TERRACOTTA;
    vec3 L = vec3(0.0);
{usage}    fragColor = vec4(L, 1.0);
}}
""")
    run = subprocess.run(["glslangValidator", str(source)], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr


class _Handler(http.server.SimpleHTTPRequestHandler):
    # Module scripts need a JavaScript MIME type, whatever /etc/mime.types says.
    extensions_map = {**http.server.SimpleHTTPRequestHandler.extensions_map, ".js": "text/javascript", ".mjs": "text/javascript"}

    def log_message(self, format, *args):  # noqa: A002 - the base class's name
        pass


@pytest.fixture(scope="module")
def served(atlases, tmp_path_factory):
    """An http.server in a thread over web/ (the page, node_modules) and :func:`atlases`, as /web and /atlas."""
    if not (WEB / "node_modules" / "three" / "package.json").exists() or not (WEB / "node_modules" / "ktx-parse").exists():
        pytest.skip("web/node_modules is missing (make setup runs npm ci in web/; needs Node.js and npm)")
    root = tmp_path_factory.mktemp("served")
    (root / "web").symlink_to(WEB)
    (root / "atlas").symlink_to(atlases["srgb"].parent)
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(_Handler, directory=str(root)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_port}"
    server.shutdown()
    thread.join()


@pytest.fixture(scope="module")
def page(served, tmp_path_factory):
    """web/probe.html open in headless Chromium."""
    from tests.chromium import start_chromium

    driver = start_chromium(tmp_path_factory.mktemp("chromium-profile"))
    driver.set_script_timeout(120)
    driver.get(f"{served}/web/probe.html")
    yield driver
    driver.quit()


def _points(atlas, rng) -> np.ndarray:
    """(material ID, N.L, N.V, lod) rows: a grid with the range ends, and random points between texels."""
    n_dot_l = np.concatenate([np.linspace(-1.0, 1.0, 9), rng.uniform(-1.0, 1.0, 12)])
    n_dot_v = np.concatenate([np.linspace(0.0, 1.0, 5), rng.uniform(0.0, 1.0, 6)])
    ids = [atlas.material(name).first_slice for name in MATERIALS]
    grid = np.meshgrid(ids, n_dot_l, n_dot_v, LODS, indexing="ij")
    return np.stack([g.ravel() for g in grid], axis=1).astype(np.float32)


def _cpu(atlas, points: np.ndarray) -> np.ndarray:
    """What ``atlas_sample`` returns at each point, from the decoded texels (float64).

    Level 0 is :func:`sample_slice`. At lod k the include keeps level 0's texel-centre mapping
    (u, v from :func:`atlas_uv` at 64x32) and the sampler filters level k's texels there.
    """
    out = np.empty((len(points), 4))
    for i, (slice_id, n_dot_l, n_dot_v, lod) in enumerate(points.astype(np.float64)):
        entry = atlas.manifest.by_slice(int(slice_id))
        nearest = bool(entry.flag("nearest"))
        level = atlas.decode_slice(int(slice_id), int(lod))
        if lod == 0:
            out[i] = sample_slice(level, n_dot_l, n_dot_v, nearest=nearest)
            continue
        u, v = atlas_uv(n_dot_l, n_dot_v)
        if nearest:
            u, v = (np.floor(u * WIDTH) + 0.5) / WIDTH, (np.floor(v * HEIGHT) + 0.5) / HEIGHT
        h, w = level.shape[:2]
        out[i] = interpolate_2d(level, u * w - 0.5, v * h - 0.5)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("encoding", ["srgb", "linear"])
def test_three_js_samples_what_the_cpu_samples(encoding, page, atlases):
    from atlasgen.io.atlas import read_atlas

    path = atlases[encoding]
    atlas = read_atlas(path)
    assert atlas.srgb == (encoding == "srgb")
    points = _points(atlas, np.random.default_rng(20))
    got = page.execute_async_script(
        "const done = arguments[arguments.length - 1];"
        "window.probe(arguments[0], arguments[1], arguments[2]).then(done, e => done('error: ' + e.message));",
        f"/atlas/{path.name}", f"/atlas/{path.with_suffix('.glsl').name}", points.ravel().tolist(),
    )  # fmt: skip
    severe = [e["message"] for e in page.get_log("browser") if e["level"] == "SEVERE"]
    assert isinstance(got, list), f"{got}; console: {severe}"
    assert severe == [], severe
    gpu = np.asarray(got, dtype=np.float64).reshape(-1, 4)
    cpu = _cpu(atlas, points)
    diff = np.abs(gpu - cpu)
    worst = int(diff.max(axis=1).argmax())
    assert diff.max() <= TOLERANCE, (
        f"{encoding}: |three.js - CPU| = {diff.max():.3g} at {points[worst]}: {gpu[worst]} vs {cpu[worst]}"
    )
    # Each level is a different picture: a loader that uploads level 0 alone (or zeros) cannot pass.
    for lod in LODS[1:]:
        assert not np.allclose(cpu[points[:, 3] == lod], cpu[points[:, 3] == 0], atol=10 * TOLERANCE), lod
