"""The ``atlasgen`` command line (installed as ``atlasgen.cli``).

This runs before ``cli/main.py``'s imports, so a Ctrl-C from the first instant of start-up
is one line and exit 130 (:func:`atlasgen.start_up.install_start_up_interrupts`).
"""

# A Ctrl-C landing while start_up.py is found and read ends the same way (see atlasgen/__main__.py).
try:
    from atlasgen.start_up import install_start_up_interrupts

    install_start_up_interrupts()
except KeyboardInterrupt:
    import os

    os.write(2, b"atlasgen: interrupted\n")
    os._exit(130)
