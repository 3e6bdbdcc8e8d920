"""Ctrl-C: one line from the first byte of the command line's start-up, and held while native libraries start up."""

from __future__ import annotations

import contextlib
import signal
import threading

from atlasgen.start_up import exit_on_interrupt, install_start_up_interrupts

__all__ = ["deferred_interrupts", "exit_on_interrupt", "install_start_up_interrupts", "end_start_up_interrupts"]


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
