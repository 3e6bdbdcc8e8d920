"""Loading the WGSL files shipped in ``atlasgen/shaders`` and assembling pass sources."""

from __future__ import annotations

import re
from functools import cache
from importlib import resources

from atlasgen.render.layout import declaration_wgsl

__all__ = ["read_shader", "fill_declarations", "assemble_shader"]

_DECLARE = re.compile(r"^// @declare (\w+)[ \t]*$", re.MULTILINE)


@cache
def read_shader(name: str) -> str:
    """The text of ``atlasgen/shaders/<name>``, as shipped (``// @declare`` lines unfilled)."""
    return resources.files("atlasgen").joinpath("shaders", name).read_text(encoding="utf-8")


def fill_declarations(text: str) -> str:
    """Replace each ``// @declare NAME`` line with the generated WGSL of ``NAME``.

    Structs and constants shared with the CPU are declared once, in
    :mod:`atlasgen.render.layout`; the shader files only say where they go.
    """
    return _DECLARE.sub(lambda m: declaration_wgsl(m[1]).rstrip("\n"), text)


def assemble_shader(*parts: str, include: str | None = None) -> str:
    """Concatenate the generated atlas include (if any) and shader files, in order.

    WGSL has no ``#include``; the renderer prepends the bake's include text verbatim, so
    the (N.L, N.V) mapping and scale/bias tables exist in exactly one place.
    """
    texts = [] if include is None else [f"// ---- generated atlas include ----\n{include}"]
    texts += [f"// ---- {name} ----\n{fill_declarations(read_shader(name))}" for name in parts]
    return "\n".join(texts)
