"""Ctrl-C in the command line's first instant: one line and exit 130, before any other import.

``atlasgen.cli`` (``cli/__init__.py``) installs this handler as its first statement, before
``cli/main.py`` imports click, NumPy and the library, and before :mod:`atlasgen.interrupts`
imports threading. This module imports only what Python's start-up already holds (``os``,
``_signal``): a signal that lands inside an import prints that import's traceback, and
threading's import alone took long enough for a Ctrl-C 20 ms into start-up to land in it.
"""

from __future__ import annotations

import _signal
import os

__all__ = ["exit_on_interrupt", "install_start_up_interrupts", "INTERRUPTED_LINE", "INTERRUPTED_STATUS"]

#: What Ctrl-C prints, and the status it ends with (128 + SIGINT, :data:`atlasgen.errors.EXIT_INTERRUPTED`).
INTERRUPTED_LINE = b"atlasgen: interrupted\n"
INTERRUPTED_STATUS = 130


def exit_on_interrupt(signum, frame) -> None:
    """SIGINT handler of the start-up: the one line, then exit 130 at once.

    While the command line imports its modules nothing has been written, so there is
    nothing to clean up, and an exception raised there would print Python's traceback
    (the import machinery's frames): ``os._exit`` ends the process instead.
    """
    os.write(2, INTERRUPTED_LINE)
    os._exit(INTERRUPTED_STATUS)


def install_start_up_interrupts() -> None:
    """Make Ctrl-C :func:`exit_on_interrupt` until :func:`atlasgen.interrupts.end_start_up_interrupts`.

    Only where SIGINT still has Python's own handler, and in the main thread (elsewhere
    ``signal`` refuses, and Python's handler stays).
    """
    if _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler:
        try:
            _signal.signal(_signal.SIGINT, exit_on_interrupt)
        except ValueError:
            pass
