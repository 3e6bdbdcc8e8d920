"""Typed errors: one line whatever the input, and rebuilt whole across a worker process."""

from __future__ import annotations

import doctest
import pickle

import pytest

from atlasgen import errors
from atlasgen.errors import MaterialError
from atlasgen.materials.material import read_material_file


def test_the_examples_in_the_docstrings_hold():
    result = doctest.testmod(errors)
    assert result.attempted > 0 and result.failed == 0


def test_an_unknown_key_of_any_length_gets_a_short_line(tmp_path):
    """A key is whatever the file says: its line shows the head and the length, not 5000 characters."""
    key = "k" * 5000
    path = tmp_path / "clay.toml"
    path.write_text(f'type = "lambert"\n{key} = 1\n')
    with pytest.raises(MaterialError) as caught:
        read_material_file(path)
    line = str(caught.value)
    assert len(line) < len(path.as_posix()) + 300 and "\n" not in line  # the file's own path is as long as it is
    assert f"field '{'k' * 68}... (5000 characters)': unknown key" in line
    assert caught.value.field == key  # the error keeps the whole name; only the message is short
    assert pickle.loads(pickle.dumps(caught.value)).field == key
