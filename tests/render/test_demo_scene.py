"""scenes/demo.toml: valid, and showing every material family with translucent objects among them."""

from __future__ import annotations

import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

from atlasgen.materials.scene import read_scene
from atlasgen.models import MODEL_TYPES

ROOT = Path(__file__).resolve().parents[2]


def test_demo_scene_shows_every_material_family():
    scene = read_scene(ROOT / "scenes" / "demo.toml")
    # Material files are only parsed here (validating them imports Mitsuba for some).
    library = {p.stem: tomllib.loads(p.read_text()) for p in (ROOT / "materials").glob("*.toml")}
    library = {raw.get("name", stem): raw for stem, raw in library.items()}
    # A MaterialX document's surfacematerials bake as separable materials named as in the document.
    imported = {node.get("name") for p in (ROOT / "materials").glob("*.mtlx") for node in ET.parse(p).iter("surfacematerial")}
    library.update({name: {"type": "separable", "materialx": True} for name in imported})
    used = [library[obj.material] for obj in scene.objects]  # KeyError = unknown material
    # type = "bsdf" ships as docs/examples/bsdf-roughplastic.toml, outside the golden-baked library.
    assert {m["type"] for m in used} == set(MODEL_TYPES) - {"bsdf"}
    assert len([obj for obj in scene.objects if obj.translucent]) >= 3
    assert any(obj.shape == "mesh" for obj in scene.objects)
    assert any(m.get("outline") for m in used)
    assert {obj.material for obj in scene.objects} >= imported  # make demo renders the shipped MaterialX document
    assert len(scene.lights) >= 8 and (scene.width, scene.height) == (1280, 720)


def test_the_demo_sets_no_gloss_its_material_ignores():
    """Three of its objects set a gloss their fitted materials never used (render now warns of each)."""
    scene = read_scene(ROOT / "scenes" / "demo.toml")
    library = {p.stem: tomllib.loads(p.read_text()) for p in (ROOT / "materials").glob("*.toml")}
    library = {raw.get("name", stem): raw for stem, raw in library.items()}
    own_lobe = [obj.material for obj in scene.objects if obj.gloss_given
                and (obj.material not in library or library[obj.material].get("from") == "physical"
                     or library[obj.material]["type"] == "separable")]  # fmt: skip
    assert own_lobe == []
