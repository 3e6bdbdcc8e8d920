"""``python -m atlasgen``: the command line, as the installed ``atlasgen`` script runs it."""

# Ctrl-C's start-up handler first: finding ``atlasgen.cli`` (an editable install's finder) takes
# long enough for a Ctrl-C to land in it before ``cli/__init__.py`` could install the handler.
from atlasgen.start_up import install_start_up_interrupts

install_start_up_interrupts()

from atlasgen.cli.main import main  # noqa: E402

if __name__ == "__main__":
    main()
