"""Generate docs/cli.md from the click app itself, so the reference cannot drift from the code."""

from __future__ import annotations

import click

from atlasgen.cli.main import app
from atlasgen.errors import EXIT_CODES

__all__ = ["render_cli_reference", "render_exit_codes"]

#: Fixed, so the file does not depend on the terminal it was generated in.
WIDTH = 100


def render_exit_codes() -> str:
    """The exit-code table, from :data:`atlasgen.errors.EXIT_CODES`."""
    rows = [f"| {code} | {meaning} |" for code, meaning in EXIT_CODES]
    return "\n".join(
        [
            "## Exit codes",
            "",
            "| code | meaning |",
            "|---|---|",
            *rows,
            "",
            "Every failure is one line on stderr (`atlasgen: error: ...`, `atlasgen: interrupted`, `atlasgen: internal "
            "error: ...`). Diagnostics (errors, warnings, progress) go to stderr; results (the bake's one-line summary, "
            "`info`) go to stdout.",
            "",
        ]
    )


USAGE = """\
## Running it

`atlasgen` is installed as a script; `python -m atlasgen` runs the same command line. Bare
`atlasgen` prints the help above. The material library shipped with atlasgen is installed with
it: `atlasgen bake --library` bakes it, and `atlasgen report separable --library` picks from it,
from any folder.

## Shell completion

click completes commands, options and file names. Add one line to your shell's start-up file:

| shell | line |
|---|---|
| bash (`~/.bashrc`) | `eval "$(_ATLASGEN_COMPLETE=bash_source atlasgen)"` |
| zsh (`~/.zshrc`) | `eval "$(_ATLASGEN_COMPLETE=zsh_source atlasgen)"` |
| fish (`~/.config/fish/completions/atlasgen.fish`) | `_ATLASGEN_COMPLETE=fish_source atlasgen \\| source` |

Running `atlasgen` at every shell start costs its start-up time; to avoid it, write the script
once (`_ATLASGEN_COMPLETE=bash_source atlasgen > ~/.atlasgen-complete.bash`) and source that file.
"""


def _command_section(ctx, name, command, level=2):
    sub_ctx = command.make_context(name, [], parent=ctx, resilient_parsing=True, terminal_width=WIDTH, max_content_width=WIDTH)
    lines = [f"{'#' * level} `{sub_ctx.command_path}`", "", "```", command.get_help(sub_ctx).rstrip(), "```", ""]
    if isinstance(command, click.Group):
        for sub in command.list_commands(sub_ctx):
            lines += _command_section(sub_ctx, sub, command.get_command(sub_ctx, sub), level + 1)
    return lines


def render_cli_reference() -> str:
    """Markdown reference of every command and option, generated from the click app."""
    # make_context applies each command's context_settings (e.g. -h as a help option).
    ctx = app.make_context("atlasgen", [], resilient_parsing=True, terminal_width=WIDTH, max_content_width=WIDTH)
    lines = [
        "# Command-line reference",
        "",
        "Generated from the click app by `python -m atlasgen.cli.docgen`; a test fails when this file is stale.",
        "",
        "```",
        app.get_help(ctx).rstrip(),
        "```",
        "",
        render_exit_codes(),
        USAGE,
    ]
    for name in app.list_commands(ctx):
        command = app.get_command(ctx, name)
        if command is not None:
            lines += _command_section(ctx, name, command)
    return "\n".join(lines).rstrip() + "\n"


if __name__ == "__main__":
    import sys
    from pathlib import Path

    target = Path(sys.argv[1] if len(sys.argv) > 1 else "docs/cli.md")
    target.write_text(render_cli_reference())
    print(f"wrote {target}")
