"""``python -m atlasgen``: the command line, as the installed ``atlasgen`` script runs it."""

# Ctrl-C's start-up handler first: finding ``atlasgen.cli`` (an editable install's finder) takes
# long enough for a Ctrl-C to land in it before ``cli/__init__.py`` could install the handler.
# A Ctrl-C can also land while start_up.py itself is found and read: the same line and status
# then, not a traceback through this file.
try:
    from atlasgen.start_up import install_start_up_interrupts

    install_start_up_interrupts()
except KeyboardInterrupt:
    import os

    os.write(2, b"atlasgen: interrupted\n")
    os._exit(130)

from atlasgen.cli.main import main  # noqa: E402

if __name__ == "__main__":
    main()
