"""The files a material's parameters name (a Mitsuba ``measured`` BSDF's data, a ``bitmap``'s image): found, resolved
from the material file's folder, and written into a manifest relative to its own folder.

Mitsuba resolves a relative ``filename`` from the working folder, so the same material file baked from another folder
read another file, or none. A material file's relative names are therefore taken from its own folder, as a scene's
meshes are from the scene file's; in memory they are absolute, and a manifest holds them relative to the manifest's
folder, as it holds ``source`` (:func:`relative_files`, :func:`absolute_files`).

>>> params = {"bsdf": {"type": "blendbsdf", "a": {"type": "measured", "filename": "data/gold.bsdf"}}}
>>> [(field, name) for field, name in referenced_files(params)]
[('bsdf.a.filename', 'data/gold.bsdf')]
>>> map_files(params, str.upper)["bsdf"]["a"]["filename"]
'DATA/GOLD.BSDF'
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

__all__ = ["referenced_files", "map_files", "relative_files", "absolute_files", "real_folder_path", "files_state"]

#: The parameter key Mitsuba's plugins name a file by.
FILE_KEY = "filename"


def referenced_files(params: dict, prefix: str = "") -> list[tuple[str, str]]:
    """``(dotted field, name as given)`` of every file ``params`` name, at any depth, in order."""
    found: list[tuple[str, str]] = []

    def walk(value, where: str) -> None:
        if isinstance(value, dict):
            for key, item in value.items():
                field = f"{where}.{key}" if where else str(key)
                if key == FILE_KEY and isinstance(item, str):
                    found.append((field, item))
                else:
                    walk(item, field)
        elif isinstance(value, (list, tuple)):
            for i, item in enumerate(value):
                walk(item, f"{where}[{i}]")

    walk(params, prefix)
    return found


def files_state(params: dict) -> tuple:
    """What an in-process cache keyed on ``params`` must add to its key: each file they name, with its size, time
    stamp and inode (None for one that cannot be read). ``params`` name a file by its path, so a cache keyed on them
    alone kept the first texture's fit after the texture was saved anew (``preview --watch`` showed it, stale).

    >>> files_state({"type": "diffuse"})
    ()
    >>> files_state({"b": {"type": "bitmap", "filename": "/nonexistent/x.png"}})
    (('/nonexistent/x.png', None),)
    """
    state: list[tuple[str, tuple[int, int, int] | None]] = []
    for _, name in referenced_files(params):
        try:
            st = os.stat(name)
        except (OSError, ValueError):
            state.append((name, None))
        else:
            state.append((name, (st.st_size, st.st_mtime_ns, st.st_ino)))
    return tuple(state)


def map_files(params: dict, change: Callable[[str], str]) -> dict:
    """A copy of ``params`` with every file name ``change``\\ d (the same object where it names none)."""
    if not referenced_files(params):
        return params

    def walk(value):
        if isinstance(value, dict):
            return {k: change(v) if k == FILE_KEY and isinstance(v, str) else walk(v) for k, v in value.items()}
        if isinstance(value, list):
            return [walk(v) for v in value]
        if isinstance(value, tuple):
            return tuple(walk(v) for v in value)
        return value

    return walk(params)


def real_folder_path(path) -> str:
    """``path`` with its folder where the system finds it (links followed, then each ``..`` from where a link led)
    and its own name kept, so a linked file is named as given. ``os.path.abspath`` folds ``link/..`` as text, which
    names another folder's file than the one the system opens.

    >>> real_folder_path("/") == os.path.realpath("/")
    True
    """
    folder, name = os.path.split(os.fspath(path))
    return os.path.join(os.path.realpath(folder or os.curdir), name)


def relative_files(params: dict, folder) -> dict:
    """``params`` as a manifest in ``folder`` holds them: each absolute file name relative to ``folder``, POSIX (folders
    resolved first, as :func:`atlasgen.bake.pipeline.relative_source` does), so the bytes do not depend on where the
    checkout lies."""
    base = os.path.realpath(folder)

    def relative(name: str) -> str:
        if not os.path.isabs(name):
            return name
        return Path(os.path.relpath(real_folder_path(name), base)).as_posix()

    return map_files(params, relative)


def absolute_files(params: dict, folder) -> dict:
    """``params`` read from a manifest in ``folder``: each relative file name made absolute from ``folder``'s real place,
    where :func:`relative_files` measured it from (a ``..`` out of a folder reached through a link is followed from
    where the folder really is, not textually from the link)."""
    base = os.path.realpath(folder)
    return map_files(params, lambda name: name if os.path.isabs(name) else os.path.normpath(os.path.join(base, name)))
