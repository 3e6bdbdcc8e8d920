"""Files installed with atlasgen: the shipped material library and the validation scenes.

They are package data under ``atlasgen/data/`` (see ``pyproject.toml``), found with
:mod:`importlib.resources`, so a regular ``pip install`` and an editable one from the
source tree find the same files. In the source tree ``atlasgen/data/materials`` is a
link to the repository's ``materials/`` folder, which stays the one copy of the library;
a wheel holds the files themselves.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from atlasgen.errors import AtlasgenError

__all__ = ["package_data_path", "shipped_library"]


def package_data_path(*parts: str) -> Path:
    """The file-system path of ``atlasgen/data/<parts>``.

    Raises
    ------
    AtlasgenError
        atlasgen is imported from somewhere without a file system (a zip archive), or
        the install lacks the file: a broken install, not a user error (exit code 1).
    """
    found = resources.files("atlasgen").joinpath("data", *parts)
    # Material and scene readers need real paths (globbing, relative mesh files);
    # every way pip installs atlasgen unpacks it.
    if not isinstance(found, Path) or not found.exists():
        raise AtlasgenError(f"atlasgen/data/{'/'.join(parts)}: not installed with atlasgen; reinstall the package")
    return found


def shipped_library() -> Path:
    """The folder of the material library shipped with atlasgen (``materials/`` in the source tree)."""
    return package_data_path("materials")
