"""Ctrl-C (or SIGTERM) in the command line's first instant: one line and exit 130 (143), before any other import.

``atlasgen.cli`` (``cli/__init__.py``) installs this handler as its first statement, before
``cli/main.py`` imports click, NumPy and the library, and before :mod:`atlasgen.interrupts`
imports threading. This module imports only what Python's start-up already holds (``os``,
``_signal``): a signal that lands inside an import prints that import's traceback, and
threading's import alone took long enough for a Ctrl-C 20 ms into start-up to land in it.
"""

from __future__ import annotations

import _signal
import os

__all__ = [
    "exit_on_interrupt",
    "exit_on_terminate",
    "install_start_up_interrupts",
    "INTERRUPTED_LINE",
    "INTERRUPTED_STATUS",
    "TERMINATED_LINE",
    "TERMINATED_STATUS",
]

#: What Ctrl-C prints, and the status it ends with (128 + SIGINT, :data:`atlasgen.errors.EXIT_INTERRUPTED`).
INTERRUPTED_LINE = b"atlasgen: interrupted\n"
INTERRUPTED_STATUS = 130
#: What SIGTERM prints, and its status (128 + SIGTERM, :data:`atlasgen.errors.EXIT_TERMINATED`).
TERMINATED_LINE = b"atlasgen: terminated\n"
TERMINATED_STATUS = 143


def exit_on_interrupt(signum, frame) -> None:
    """SIGINT handler of the start-up: the one line, then exit 130 at once.

    While the command line imports its modules nothing has been written, so there is
    nothing to clean up, and an exception raised there would print Python's traceback
    (the import machinery's frames): ``os._exit`` ends the process instead.
    """
    os.write(2, INTERRUPTED_LINE)
    os._exit(INTERRUPTED_STATUS)


def exit_on_terminate(signum, frame) -> None:
    """SIGTERM handler of the start-up: its one line, then exit 143 at once (as :func:`exit_on_interrupt`)."""
    os.write(2, TERMINATED_LINE)
    os._exit(TERMINATED_STATUS)


def install_start_up_interrupts() -> None:
    """Make Ctrl-C :func:`exit_on_interrupt`, and SIGTERM :func:`exit_on_terminate`, until
    :func:`atlasgen.interrupts.end_start_up_interrupts`.

    Only where each signal still has Python's own disposition (SIGINT its handler, SIGTERM the
    default), and in the main thread (elsewhere ``signal`` refuses, and Python's stays).
    """
    for signum, python_s, handler in ((_signal.SIGINT, _signal.default_int_handler, exit_on_interrupt),
                                      (_signal.SIGTERM, _signal.SIG_DFL, exit_on_terminate)):  # fmt: skip
        if _signal.getsignal(signum) == python_s:  # SIG_DFL is the int 0
            try:
                _signal.signal(signum, handler)
            except ValueError:
                pass
