"""Interrupts held while native libraries start (atlasgen/interrupts.py): Ctrl-C and, from the
command line, SIGTERM are noted inside the block and raised, each as its own kind, once it ends."""

from __future__ import annotations

import os
import signal

import pytest

from atlasgen import start_up
from atlasgen.errors import EXIT_INTERRUPTED, EXIT_TERMINATED, Terminated
from atlasgen.interrupts import deferred_interrupts, raise_terminated


@pytest.fixture
def command_line_sigterm():
    """SIGTERM as the command line has it once started (atlasgen.cli.main.main)."""
    previous = signal.signal(signal.SIGTERM, raise_terminated)
    yield
    signal.signal(signal.SIGTERM, previous)


@pytest.mark.parametrize(("signum", "raised"), [(signal.SIGINT, KeyboardInterrupt), (signal.SIGTERM, Terminated)])
def test_a_signal_inside_the_block_is_raised_after_it_as_its_own_kind(command_line_sigterm, signum, raised):
    finished = []
    with pytest.raises(raised) as caught:
        with deferred_interrupts():
            os.kill(os.getpid(), signum)
            finished.append(True)  # the block ran on past the signal
    assert finished == [True]
    assert (caught.type is Terminated) == (signum == signal.SIGTERM)
    assert signal.getsignal(signal.SIGTERM) is raise_terminated
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_held_sigterm_replaces_the_exception_the_block_ends_with(command_line_sigterm):
    with pytest.raises(Terminated):
        with deferred_interrupts():
            os.kill(os.getpid(), signal.SIGTERM)
            raise SystemError("a native start-up cut in the middle")


def test_sigterm_with_python_s_default_action_is_left_alone():
    """Imported as a library, SIGTERM keeps its default (the process ends): nothing to hold or raise."""
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    with deferred_interrupts():
        assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL


def test_the_start_up_handlers_exit_with_the_cli_s_statuses():
    """start_up.py imports nothing of atlasgen's, so it holds its own copy of the statuses and lines."""
    assert (start_up.INTERRUPTED_STATUS, start_up.TERMINATED_STATUS) == (EXIT_INTERRUPTED, EXIT_TERMINATED)
    assert (start_up.INTERRUPTED_STATUS, start_up.TERMINATED_STATUS) == (128 + signal.SIGINT, 128 + signal.SIGTERM)
    assert start_up.TERMINATED_LINE == b"atlasgen: terminated\n"
