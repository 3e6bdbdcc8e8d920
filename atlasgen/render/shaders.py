"""Loading the WGSL files shipped in ``atlasgen/shaders`` and assembling pass sources."""

from __future__ import annotations

from functools import cache
from importlib import resources

__all__ = ["read_shader", "assemble_shader"]


@cache
def read_shader(name: str) -> str:
    """The text of ``atlasgen/shaders/<name>``."""
    return resources.files("atlasgen").joinpath("shaders", name).read_text(encoding="utf-8")


def assemble_shader(*parts: str, include: str | None = None) -> str:
    """Concatenate the generated atlas include (if any) and shader files, in order.

    WGSL has no ``#include``; the renderer prepends the bake's include text verbatim, so
    the (N.L, N.V) mapping and scale/bias tables exist in exactly one place.
    """
    texts = [] if include is None else [f"// ---- generated atlas include ----\n{include}"]
    texts += [f"// ---- {name} ----\n{read_shader(name)}" for name in parts]
    return "\n".join(texts)
