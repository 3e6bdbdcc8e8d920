"""The renderer's pass sources: the WGSL files shipped in ``atlasgen/shaders``, their shared declarations filled in.

A shader file names each struct or constant it shares with the CPU on a ``// @declare NAME``
line; the caller hands in ``declare``, which gives the generated WGSL of a name (the renderer's
:func:`atlasgen.render.layout.declaration_wgsl`), so this module needs nothing from the renderer.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from functools import cache
from importlib import resources

__all__ = ["read_shader", "fill_declarations", "assemble_shader"]

_DECLARE = re.compile(r"^// @declare (\w+)[ \t]*$", re.MULTILINE)


@cache
def read_shader(name: str) -> str:
    """The text of ``atlasgen/shaders/<name>``, as shipped (``// @declare`` lines unfilled)."""
    return resources.files("atlasgen").joinpath("shaders", name).read_text(encoding="utf-8")


def fill_declarations(text: str, declare: Callable[[str], str]) -> str:
    """Replace each ``// @declare NAME`` line with ``declare(NAME)``, the generated WGSL of ``NAME``.

    Structs and constants shared with the CPU are declared once, in Python
    (:mod:`atlasgen.render.layout`); the shader files only say where they go.
    """
    return _DECLARE.sub(lambda m: declare(m[1]).rstrip("\n"), text)


def assemble_shader(*parts: str, declare: Callable[[str], str], include: str | None = None) -> str:
    """Concatenate the generated atlas include (if any) and shader files, in order, declarations filled.

    WGSL has no ``#include``; the renderer prepends the bake's include text verbatim, so
    the (N.L, N.V) mapping and scale/bias tables exist in exactly one place.
    """
    texts = [] if include is None else [f"// ---- generated atlas include ----\n{include}"]
    texts += [f"// ---- {name} ----\n{fill_declarations(read_shader(name), declare)}" for name in parts]
    return "\n".join(texts)
