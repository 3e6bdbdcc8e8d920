"""OpenImageIO, imported where a Ctrl-C cannot abort the process."""

from __future__ import annotations

from atlasgen.interrupts import deferred_interrupts

__all__ = ["import_oiio"]


def import_oiio():
    """The ``OpenImageIO`` module, imported with Ctrl-C and SIGTERM held (:func:`~atlasgen.interrupts.deferred_interrupts`).

    Its nanobind start-up creates enums in C++: an interrupt raised there ended the process with SIGABRT ("Critical
    nanobind error: ... enum_create") and a 30-line traceback, where a command prints one line and exits 130 or 143.
    Held, the interrupt is raised once the import is done.
    """
    with deferred_interrupts():
        import OpenImageIO
    return OpenImageIO
