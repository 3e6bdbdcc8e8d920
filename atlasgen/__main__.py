"""``python -m atlasgen``: the command line, as the installed ``atlasgen`` script runs it."""

from atlasgen.cli.main import main

if __name__ == "__main__":
    main()
