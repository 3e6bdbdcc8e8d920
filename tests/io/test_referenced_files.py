"""atlasgen/io/referenced_files.py: the files a material's parameters name, and how a manifest holds them."""

from __future__ import annotations

import doctest
import os

from atlasgen.io import referenced_files as module
from atlasgen.io.referenced_files import absolute_files, map_files, referenced_files, relative_files


def test_doctests():
    result = doctest.testmod(module)
    assert result.attempted > 0 and result.failed == 0


def test_the_files_a_material_names_are_found_at_any_depth():
    bsdf = {"type": "blendbsdf", "a": {"type": "measured", "filename": "data/gold.bsdf"},
            "b": {"type": "diffuse", "reflectance": {"type": "bitmap", "filename": "tex.png"}}}  # fmt: skip
    params = {"bsdf": bsdf, "terms": 4, "layers": [{"filename": "x.png"}]}
    assert referenced_files(params) == [("bsdf.a.filename", "data/gold.bsdf"), ("bsdf.b.reflectance.filename", "tex.png"),
                                        ("layers[0].filename", "x.png")]  # fmt: skip
    assert referenced_files({"colour": (1, 1, 1)}) == []
    plain = {"colour": (1, 1, 1)}
    assert map_files(plain, str.upper) is plain  # nothing named: the same object


def test_a_manifest_holds_a_file_relative_to_its_folder_and_a_reader_takes_it_back(tmp_path):
    """Through a linked output folder too: the name is measured from the folder's real place and read back from it."""
    image = tmp_path / "materials" / "tex.png"
    image.parent.mkdir()
    image.write_bytes(b"png")
    (tmp_path / "real" / "out").mkdir(parents=True)
    (tmp_path / "lnk").symlink_to(tmp_path / "real" / "out")
    params = {"bsdf": {"type": "bitmap", "filename": os.path.realpath(image)}}
    for folder in (tmp_path / "out", tmp_path / "lnk"):
        held = relative_files(params, folder)
        assert not os.path.isabs(held["bsdf"]["filename"])
        assert absolute_files(held, folder) == params
