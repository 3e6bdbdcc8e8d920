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
            "Every failure is one line on stderr (`atlasgen: error: ...`, `atlasgen: interrupted`, `atlasgen: terminated`, `atlasgen: internal "
            "error: ...`). Diagnostics (errors, warnings, progress) go to stderr; results (the bake's one-line summary, "
            "`info`) go to stdout.",
            "",
        ]
    )


OUTPUTS = f"""\
## Outputs: one generation on disk

Every command writes its outputs as one set: a bake's atlas, manifest, includes, side-car,
timings, preview and depfile; a render's EXR and PNG; a report's pages, plots and JSON. Any
reader, one that checks the hashes or one that does not (an engine loading `X.dds` and `X.json`),
sees them change together, at one instant, even if the command is killed
(`atlasgen/io/atomic.py`):

- Each output at its documented path is a relative symbolic link, made once and never changed:
  `X.dds -> .X.atlasgen/current/X.dds` (`images/a.png -> ../.X.atlasgen/current/images/a.png`),
  `X` being the primary output's name up to its first dot. `.X.atlasgen/current` is a link to the
  generation folder `gen-<n>` that holds the files.
- A commit writes every new file into a fresh `gen-<n+1>` (with hard links of the files of the
  previous generation that it neither rewrites nor removes), then renames a new link over
  `current`. That one rename is the commit: before it every path reads the old generation, after
  it the new one. Names that leave the set (a stale side-car, includes in languages not asked
  for, the other container) are then links to nothing, which a reader cannot open either, and
  are removed. One previous generation is kept, for readers that resolved `current` a moment
  earlier; the next commit removes the older ones, and whatever a killed run left.
- **Lock.** `fcntl.flock` on `.X.atlasgen/lock`: a second writer of the same set waits for the
  first, up to {LOCK_TIMEOUT_S:g} s (`ATLASGEN_LOCK_TIMEOUT_S`), then exits 4 with one line; two
  bakes of one target, as two `make -j` jobs might run, end as one bake's generation.
- **Exit 4 changes nothing.** A file marked immutable or append-only (`chattr +i`, which through
  the link marks the generation's file), an output path that is a folder, or a failing rename
  stops the command before the commit: `X.dds: cannot replace (Operation not permitted); nothing
  was replaced`. A Ctrl-C (exit 130) or SIGTERM (143) that comes while the commit runs is held
  until just before the swap and stops the command there, the old set left as it was; one that
  comes after that instant is dropped, and the command ends with its new set. Only one that comes
  after the commit, as the command prints its last lines, ends it with 130 or 143 and its new set.
  An output path inside a store (`-o v/.report.atlasgen/current`, or through a link into one) is
  refused the same way: it would have changed a committed generation in place.
- **Found before the work.** An output, report or cache folder that takes no new file (read-only to
  a user who is not root, immutable, on a read-only mount; probed by making and removing an empty
  folder in it, or in the nearest existing folder above it) is refused with exit 4 and one line
  naming the output, its option and the folder, before anything bakes or renders. So is an output
  that lies under another output's path (`--preview a.dds/sheet.png`, `--cache a.dds`, a preview's
  `--cache` under its `-o`), and one whose folder is a symbolic link to nothing.
- **Plain files of an older atlasgen** are taken over first without a visible change: a holding
  generation gets a hard link of each, `current` points at it, and a link is renamed over each
  file (the same bytes before and after), then the commit swaps as above.
- **`make`** follows the link: a commit's targets are new files, with new times, and a killed
  commit leaves the old ones, so `make` runs the command again.

What this asks of other tools: copy an output folder with its links (`cp -r`, `cp -a`,
`rsync -a`, `tar`; the links are relative, so the copy reads its own generation), or copy the
files themselves (`cp -L`, `rsync -L`); `rsync -r` without `-l` skips links. A folder copied with
`cp -rL` reads, but its store's `current` is then a folder, not the link to a generation, and a
command writing there refuses it (exit 4, nothing changed) rather than guess which generation it
holds: copy it again with `cp -a`, or with `cp -L` and without the `.X.atlasgen` folders. A single file copied
out (`cp X.dds elsewhere/`) is a plain file. Open a report page by its documented path: a tool that
resolves the link first (`realpath`) finds the page inside `gen-<n>`, where a report's links to
other folders do not lead. A reader holding a file open keeps reading its generation. A file
written in place through its link (an editor) changes that generation's file. A file written on
its own, not as part of a set (caches, `atlasgen preview`'s image), stays a plain file, replaced
by one rename.

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
