"""Ctrl-C: one line from the first byte of the command line's start-up, and held while native libraries start up."""

from __future__ import annotations

import contextlib
import os
import signal
import threading

__all__ = ["deferred_interrupts", "exit_on_interrupt", "install_start_up_interrupts", "end_start_up_interrupts"]

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
    """Make Ctrl-C :func:`exit_on_interrupt` until :func:`end_start_up_interrupts`.

    Done by ``atlasgen.cli`` (``cli/__init__.py``), the first module of the command line's
    package to run, before ``cli/main.py`` imports click, NumPy and the library. Only where
    SIGINT still has Python's own handler, in the main thread.
    """
    if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, exit_on_interrupt)


def end_start_up_interrupts() -> None:
    """Back to Python's handler (Ctrl-C raises :class:`KeyboardInterrupt`, which a command turns into one line)."""
    if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGINT) is exit_on_interrupt:
        signal.signal(signal.SIGINT, signal.default_int_handler)


@contextlib.contextmanager
def deferred_interrupts():
    """Hold SIGINT until the block ends, then raise :class:`KeyboardInterrupt`.

    Mitsuba's and Dr.Jit's start-up (their C++ modules' initialisation, the LLVM
    backend's) does not survive an exception raised in the middle of it: interrupted
    there, it fails with ``SystemError``, ``NameError`` or a crash, which would read as a
    missing backend. Inside the block a Ctrl-C is only noted; it is raised once the block
    is done, or instead of whatever exception the block ends with. Outside the main
    thread, or where SIGINT is ignored, the block runs as it is.
    """
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGINT) in (signal.SIG_IGN, None):
        yield
        return
    pending = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: pending.append(signum))
    try:
        yield
    except BaseException:
        if pending:
            raise KeyboardInterrupt from None
        raise
    finally:
        signal.signal(signal.SIGINT, previous)
    if pending:
        raise KeyboardInterrupt
