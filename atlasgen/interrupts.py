"""Ctrl-C and SIGTERM: one line from the first byte of the command line's start-up, and held while native libraries start up."""

from __future__ import annotations

import _thread
import contextlib
import os
import signal
import sys
import threading
import time

from atlasgen.errors import Terminated
from atlasgen.start_up import exit_on_interrupt, exit_on_terminate, install_start_up_interrupts

__all__ = [
    "HeldInterrupts",
    "deferred_interrupts",
    "exit_on_interrupt",
    "install_start_up_interrupts",
    "end_start_up_interrupts",
    "raise_terminated",
    "as_received",
    "raise_unraisable_interrupts",
    "send_once_returned",
    "interrupt_behind",
]


#: Set by :func:`raise_terminated`: a library that turns the interrupt its signal check raised into one of its own
#: (watchfiles raises a plain KeyboardInterrupt) loses which signal it was; :func:`as_received` gets it back.
_TERMINATED = threading.Event()


def raise_terminated(signum, frame) -> None:
    """The command line's SIGTERM handler once started: raise :class:`~atlasgen.errors.Terminated`, so a
    command's clean-up runs as for Ctrl-C (Python's default would end the process at once, its bake
    workers left running)."""
    _TERMINATED.set()
    raise Terminated


def as_received(interrupt: KeyboardInterrupt) -> KeyboardInterrupt:
    """``interrupt``, or :class:`~atlasgen.errors.Terminated` where SIGTERM was what arrived and a library
    re-raised it as a plain KeyboardInterrupt."""
    return Terminated() if _TERMINATED.is_set() and not isinstance(interrupt, Terminated) else interrupt


def end_start_up_interrupts(command_line: bool = False) -> None:
    """Back to Python's handler: Ctrl-C raises :class:`KeyboardInterrupt`, which a command turns into one line.

    SIGTERM: with ``command_line``, :func:`raise_terminated`; imported as a library, Python's default.
    The command line also takes back an interrupt that lands where Python cannot raise it
    (:func:`raise_unraisable_interrupts`).
    """
    if threading.current_thread() is not threading.main_thread():
        return
    if signal.getsignal(signal.SIGINT) is exit_on_interrupt:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if signal.getsignal(signal.SIGTERM) is exit_on_terminate:
        signal.signal(signal.SIGTERM, raise_terminated if command_line else signal.SIG_DFL)
    if command_line:
        raise_unraisable_interrupts()


def raise_unraisable_interrupts() -> None:
    """Install a :data:`sys.unraisablehook` that sends an interrupt Python could not raise back to this process.

    A Ctrl-C or SIGTERM whose handler runs inside a finalizer or a weakref callback (the garbage
    collector's, wgpu's and trimesh's objects have them) raises there, where Python can only print
    "Exception ignored in ..." with a traceback and carry on: the command then ran to the end and
    replaced its outputs. The hook sends the same signal again, so that its handler runs in the
    command's own code, as any other interrupt does. It is sent from another thread once the hook
    has returned (:func:`send_once_returned`): sent while the hook runs, the handler would run inside
    it, where an exception is as unraisable as in the callback. Every other unraisable error goes to
    the hook that was installed before.
    """
    previous = sys.unraisablehook
    if getattr(previous, "raises_interrupts", False):
        return

    def hook(unraisable) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt):
            signum = signal.SIGTERM if isinstance(unraisable.exc_value, Terminated) else signal.SIGINT
            # A bare thread: threading.Thread.start waits for the thread to run, and on a loaded machine a
            # threading.Timer's signal landed in that wait, inside the hook (once in 20 under load).
            _thread.start_new_thread(send_once_returned, (signum, sys._getframe().f_code, threading.get_ident()))
            return
        previous(unraisable)

    hook.raises_interrupts = True  # type: ignore[attr-defined]
    sys.unraisablehook = hook


def send_once_returned(signum: int, code, thread_id: int, poll_s: float = 0.001) -> None:
    """Send ``signum`` to this process once thread ``thread_id``'s stack holds no frame of ``code``.

    Python runs a signal's handler in the main thread at its next instruction, wherever that is: a
    delay alone cannot say the thread has left ``code`` by then, however long, on a loaded machine.
    """
    while True:
        frame = sys._current_frames().get(thread_id)
        while frame is not None and frame.f_code is not code:
            frame = frame.f_back
        if frame is None:
            break
        time.sleep(poll_s)
    os.kill(os.getpid(), signum)


#: The signals :func:`deferred_interrupts` holds: what each is raised as once the block is done, and the
#: dispositions it is left alone under (ignored; SIGTERM's default, a library's process, which it ends).
_HELD = {
    signal.SIGINT: (KeyboardInterrupt, (signal.SIG_IGN, None)),
    signal.SIGTERM: (Terminated, (signal.SIG_IGN, signal.SIG_DFL, None)),
}


class HeldInterrupts:
    """The signals a :func:`deferred_interrupts` block has held so far, for a block that must act on them before
    it ends: :meth:`raise_now` before a step that cannot be undone, :meth:`drop` once it is done."""

    def __init__(self):
        self.pending: list[int] = []

    def raise_now(self) -> None:
        """Raise the last signal held so far (as the block's end would), forgetting the others."""
        if self.pending:
            signum = self.pending[-1]
            self.pending.clear()
            raise _HELD[signum][0]

    def drop(self) -> None:
        """Forget the signals held so far: the block has done what they would have stopped."""
        self.pending.clear()


@contextlib.contextmanager
def deferred_interrupts():
    """Hold SIGINT (and SIGTERM where it raises) until the block ends, then raise the interrupt.

    Mitsuba's and Dr.Jit's start-up (their C++ modules' initialisation, the LLVM
    backend's) does not survive an exception raised in the middle of it: interrupted
    there, it fails with ``SystemError``, ``NameError`` or a crash, which would read as a
    missing backend. Inside the block a Ctrl-C is only noted; it is raised once the block
    is done, or instead of whatever exception the block ends with (a SIGTERM as
    :class:`~atlasgen.errors.Terminated`). Outside the main thread, or for a signal that is
    ignored (or SIGTERM with its default action, outside the command line), it is left as it is.
    The block gets the :class:`HeldInterrupts`, to raise them earlier or drop them.
    """
    held = HeldInterrupts()
    if threading.current_thread() is not threading.main_thread():
        yield held
        return
    pending = held.pending
    previous = {}
    for signum, (_, left_alone) in _HELD.items():
        if signal.getsignal(signum) not in left_alone:
            previous[signum] = signal.signal(signum, lambda number, frame: pending.append(number))
    try:
        yield held
    except BaseException:
        if pending:
            raise _HELD[pending[-1]][0] from None
        raise
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    if pending:
        raise _HELD[pending[-1]][0]


def interrupt_behind(exc: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C or SIGTERM that ``exc`` was raised from, if any: ``exc`` itself, or an interrupt in its chain of
    causes. Dr.Jit wraps one landing in a Python callback (a Mitsuba BSDF written in Python, mid-render) in a
    RuntimeError ("error while performing a custom differentiable operation"), raised from it: the command was
    interrupted, and ended as an internal error.

    >>> try:
    ...     try:
    ...         raise KeyboardInterrupt
    ...     except KeyboardInterrupt as inner:
    ...         raise RuntimeError("wrapped") from inner
    ... except RuntimeError as outer:
    ...     type(interrupt_behind(outer)).__name__
    'KeyboardInterrupt'
    >>> interrupt_behind(ValueError("no interrupt")) is None
    True
    """
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:  # a cycle of causes ends the walk
        if isinstance(current, KeyboardInterrupt):
            return current
        seen.add(id(current))
        current = current.__cause__
    return None
