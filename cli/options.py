"""Options and output helpers every command shares: ``-q``/``-v`` and per-material progress."""

from __future__ import annotations

import functools
import os
import sys

import click
from click.core import ParameterSource

from atlasgen.backend_messages import keep_backend_messages_to_errors

__all__ = [
    "QUIET",
    "NORMAL",
    "VERBOSE",
    "MAX_SPP",
    "HELP_OPTIONS",
    "PathArg",
    "verbosity_options",
    "MaterialProgress",
    "refuse_options",
]

QUIET, NORMAL, VERBOSE = -1, 0, 1
#: The most samples per pixel a command takes (Mitsuba's count is a 32-bit integer): far more than a
#: validation or a preview's reference needs, and past it a CPU reference runs for days.
#: Every command's context settings: -h as well as --help. Each command module declares them itself, since
#: click builds (and keeps) a command's help option from the context it is first asked in, and a command run
#: on its own (a test's CliRunner) has no parent context to inherit them from.
HELP_OPTIONS = {"help_option_names": ["-h", "--help"]}
MAX_SPP = 65536


class PathArg(click.Path):
    """``click.Path`` that refuses an empty string: pathlib reads ``""`` as ``.``, so ``bake ""`` baked the
    current folder and ``-o ""`` named it. It leaves readability to the library's readers: click refused an
    unreadable file as a usage error (exit 2, three lines of usage and message), where a reader says
    ``path: cannot read (Permission denied)`` on one line, exit 3, as for any input it cannot read.

    It refuses ``-`` as well: by the convention of command-line tools it means standard input or output, which
    no atlasgen command reads or writes, and ``--depfile -`` quietly wrote a file named ``-``. ``./-`` names
    that file.

    With ``file_output``, a path ending in a separator is refused too: it names a folder (``-o newdir.png/``), and
    pathlib drops the separator, so a file ``newdir.png`` was written instead, as ``cp`` or ``open`` would not."""

    def __init__(self, *args, file_output: bool = False, **kwargs):
        kwargs.setdefault("readable", False)
        self.file_output = file_output
        super().__init__(*args, **kwargs)

    def convert(self, value, param, ctx):
        if isinstance(value, str) and not value:
            self.fail("expected a path, got an empty string", param, ctx)
        if self.file_output and isinstance(value, str) and value.endswith(("/", os.sep)):
            self.fail(f"{value!r} ends in '/', a folder's path; expected a file's path", param, ctx)
        if isinstance(value, str) and value == "-":
            self.fail("'-' would be a file named '-', not standard input or output, which atlasgen neither reads "
                      "nor writes; expected a path (./- for a file of that name)", param, ctx)  # fmt: skip
        return super().convert(value, param, ctx)


def refuse_options(ctx: click.Context, names, reason: str, expected: str = "one or the other") -> None:
    """Refuse the first option of ``names`` given on the command line, where ``reason`` (``"with --merge, which
    renders nothing"``) says why it would do nothing: one usage line (exit 2), never a silent no-op.

    ``names`` holds parameter names (``"spp"``) or option strings (``"--verbose"``): ``-q`` and ``-v`` are one
    parameter, ``verbosity``, and a flag of such a pair counts as given only where its value is the one it sets.
    """
    for param in ctx.command.params:
        if param.name not in names and not any(opt in names for opt in param.opts):
            continue
        given = ctx.get_parameter_source(param.name) in (ParameterSource.COMMANDLINE, ParameterSource.ENVIRONMENT)
        shared = getattr(param, "is_flag", False) and not getattr(param, "is_bool_flag", False)
        if given and (not shared or ctx.params.get(param.name) == param.flag_value):
            raise click.UsageError(f"{param.opts[-1]} has no effect {reason}; expected {expected}")


def verbosity_options(quiet: str = "Print only errors.", verbose: str = "Print more detail."):
    """``-q/--quiet`` and ``-v/--verbose``, passed to the command as one ``verbosity``.

    ``verbosity`` is :data:`QUIET`, :data:`NORMAL` or :data:`VERBOSE`; of ``-q`` and
    ``-v`` the last one given wins. ``quiet`` and ``verbose`` are the command's help
    texts, which say what it prints then.
    """

    def decorate(func):
        @functools.wraps(func)
        def wrapper(*args, verbosity=None, **kwargs):
            if verbosity == QUIET:
                keep_backend_messages_to_errors()  # Dr.Jit writes its own warnings past ours
            return func(*args, verbosity=NORMAL if verbosity is None else verbosity, **kwargs)

        wrapper = click.option("-v", "--verbose", "verbosity", flag_value=VERBOSE, type=int, help=verbose)(wrapper)
        return click.option("-q", "--quiet", "verbosity", flag_value=QUIET, type=int, help=quiet)(wrapper)

    return decorate


class MaterialProgress:
    """A ``(name, done, total)`` callback that reports each finished material on stderr.

    A progress bar when stderr is a terminal, else one plain line per material
    (``validated skin (3/12)``), so that logs of ``make -j`` stay readable; nothing
    with ``-q``. With ``-v`` the plain lines are used, since the command prints its own
    detail between them. Use it as a context manager, which closes the bar.
    """

    def __init__(self, verb: str, verbosity: int):
        self.verb = verb
        self.verbosity = verbosity
        self.bar = None

    def __call__(self, name: str, done: int, total: int) -> None:
        if self.verbosity == QUIET:
            return
        if self.verbosity == NORMAL and sys.stderr.isatty():
            if self.bar is None:
                # The total is known only once the library has checked its inputs.
                self.bar = click.progressbar(length=total, label=self.verb, file=sys.stderr,
                                             item_show_func=lambda item: item)  # fmt: skip
                self.bar.__enter__()
            self.bar.update(1, name)
            return
        click.echo(f"{self.verb} {name} ({done}/{total})", err=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        if self.bar is not None:
            if exc_info[0] is None:
                self.bar.__exit__(*exc_info)
            else:
                # The bar's line is erased, not finished: the error that follows is then the one line left.
                self.bar.file.write("\r\033[2K\033[?25h")
                self.bar.file.flush()
            self.bar = None
