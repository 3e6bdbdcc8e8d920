"""Generate docs/cli.md from the click app itself, so the reference cannot drift from the code."""

from __future__ import annotations

import click

from atlasgen.cli.main import app
from atlasgen.errors import EXIT_CODES
from atlasgen.io.atomic import LOCK_TIMEOUT_S

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


OUTPUTS = f"""\
## Outputs: one generation on disk

Every command writes its outputs as one set: a bake's atlas, manifest, includes, side-car,
timings, preview and depfile; a render's EXR and PNG; a report's pages, plots and JSON. A reader
that trusts the files (an engine loading `X.dds` and `X.json` without checking their hashes) sees
them change together, by a journaled commit (`atlasgen/io/atomic.py`):

1. **Lock.** `fcntl.flock` on `.X.atlasgen.lock` beside the primary output (`X`: its name up to
   the first dot). A second writer of the same set waits for the first, up to {LOCK_TIMEOUT_S:g} s
   (`ATLASGEN_LOCK_TIMEOUT_S`), then exits 4 with one line; two bakes of one target, as two
   `make -j` jobs might run, end as one bake's generation. The lock file exists only while held.
2. **Stage.** Each file is written to `.<name>.<pid>.<random>.atlasgen.tmp` beside its target and
   flushed to disk.
3. **Check.** Every existing target, and every stale sibling the commit removes, gets a hard-linked
   backup. Linking fails as the rename would (an immutable or append-only file, a read-only file
   system), so a target that cannot be replaced stops the command before its first rename: exit 4,
   `X.dds: cannot replace (Operation not permitted); nothing was replaced`.
4. **Journal.** `.X.atlasgen.journal` names every target, its new file and its backup; it is
   flushed to disk before the first rename.
5. **Rename** each file over its target, the primary (the file a `make` rule targets: the atlas,
   the render's PNG, `report.json`, `index.md`, `index.html`) last, remove the stale siblings,
   delete the journal, then the backups. A rename that still fails puts every renamed target back
   from its backup: exit 4, every output as it was. Ctrl-C here is held until the set is whole.
6. **Recover.** A commit killed during its renames leaves its journal. The next atlasgen command
   that writes the set, and every atlasgen reader of the folder (`read_atlas`, so `info`, `render`,
   `validate` and the reports; the report merges), rolls it forward under the lock before anything
   else; a killed roll-back is rolled back. Until then the primary is stale, so `make` runs the
   command again, and a reader that checks the hashes refuses the mix.

The documented paths stay plain files, as engines and asset pipelines expect; the price is that
a plain reader looking at a folder after a kill, before any atlasgen command has, can see the
half-done set (the primary still old). Exit 4 leaves every existing output untouched; exit 130
leaves each set whole, old or new.

"""

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
        OUTPUTS,
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
