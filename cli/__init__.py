"""The ``atlasgen`` command line (installed as ``atlasgen.cli``).

This runs before ``cli/main.py``'s imports, so a Ctrl-C from the first instant of start-up
is one line and exit 130 (:func:`atlasgen.start_up.install_start_up_interrupts`).
"""

from atlasgen.start_up import install_start_up_interrupts

install_start_up_interrupts()
