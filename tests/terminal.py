"""What a child process started by a test inherits from a terminal, whatever started the test.

A shell's background job (``make test &``, ``nohup``) starts with SIGINT ignored, its children
inherit that, and Python then leaves SIGINT ignored instead of raising KeyboardInterrupt: a test
that presses Ctrl-C on a child would see it finish instead. Children started with
``preexec_fn=as_in_a_terminal`` take SIGINT as a terminal's foreground process does.
"""

from __future__ import annotations

import signal


def as_in_a_terminal() -> None:
    """Restore SIGINT's default action in a child before it runs (``subprocess.Popen(preexec_fn=...)``)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
