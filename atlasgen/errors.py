"""Typed errors raised by the library; the CLI maps each to a message and an exit code.

:data:`EXIT_CODES` is the one list of the CLI's exit statuses: docs/cli.md's table is
generated from it, and the tests reach every one of them.
"""

from __future__ import annotations

import difflib

__all__ = [
    "AtlasgenError",
    "InputError",
    "FieldError",
    "MaterialError",
    "SceneError",
    "ManifestError",
    "OutputError",
    "OutputNameError",
    "BackendError",
    "GoalsMissed",
    "BakeWarnings",
    "describe_failure",
    "did_you_mean",
    "shorten",
    "EXIT_OK",
    "EXIT_INTERNAL",
    "EXIT_USAGE",
    "EXIT_INTERRUPTED",
    "EXIT_TERMINATED",
    "Terminated",
    "EXIT_CODES",
    "REPORT_BUGS_TO",
]


def shorten(text: str, limit: int = 80) -> str:
    """``text`` for a one-line message, its head and its length where it is longer than ``limit``.

    >>> shorten("k" * 100)
    'kkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkkk... (100 characters)'
    >>> shorten("ior")
    'ior'
    """
    return text if len(text) <= limit else f"{text[: limit - 12]}... ({len(text)} characters)"


def describe_failure(exc: BaseException) -> str:
    """What ``exc`` (a reader's or formatter's own failure on a damaged file) says, for a one-line message,
    without Python's class name: a user edited a field, not a program.

    >>> describe_failure(KeyError("height"))
    "no key 'height'"
    >>> describe_failure(TypeError("string indices must be integers, not 'str'"))
    "string indices must be integers, not 'str'"
    >>> describe_failure(ValueError())
    'a value it cannot use'
    """
    if isinstance(exc, KeyError) and exc.args:
        return f"no key {shorten(repr(exc.args[0]))}"
    lines = str(exc).strip().splitlines()
    return shorten(lines[0]) if lines else "a value it cannot use"


class AtlasgenError(Exception):
    """Base class of every error atlasgen raises on purpose.

    ``exit_code`` is the process exit status the CLI uses for it (see docs/cli.md).
    """

    exit_code = 1


class InputError(AtlasgenError):
    """A path the user named is missing or unreadable."""

    exit_code = 3


class FieldError(InputError):
    """An input file's field is invalid: ``path: field 'name': expected ..., got ...`` on one line.

    ``field`` is ``None`` when the whole file is at fault (then ``path: expected ...``).
    """

    def __init__(self, path, field: str | None, expected: str):
        self.path = str(path)
        self.field = field
        self.expected = expected
        # A field named by a file (an unknown key) may be any length: the line shows its head.
        where = f"{self.path}: field '{shorten(field)}'" if field else self.path
        super().__init__(f"{where}: {expected}")

    def __reduce__(self):
        # Rebuilt from its own arguments, not from the message, so that an error raised in a bake
        # worker process (atlasgen.bake.workers) reaches the command as the same typed error.
        return type(self), (self.path, self.field, self.expected)


class MaterialError(FieldError):
    """A material definition is invalid.

    The message always names the file, the field and what was expected, on one line:
    ``materials/gold.toml: field 'ior': expected a finite number >= 1, got nan``.
    """


class SceneError(FieldError):
    """A scene file is invalid, or asks for something the atlas or renderer lacks."""


class ManifestError(FieldError):
    """An atlas manifest (``X.json``) is not one this atlasgen can read.

    One line naming the file and the field:
    ``build/atlas.json: field 'materials[3].first_slice': expected an integer >= 0, got -1``.
    """


class OutputError(AtlasgenError):
    """An output file or folder cannot be written."""

    exit_code = 4


class OutputNameError(OutputError):
    """An output named with an extension of another kind (``-o atlas.png``): a bad option value, so a usage
    error's status (docs/cli.md), though it is an output's error to the code that catches it."""

    exit_code = 2


class BackendError(AtlasgenError):
    """An optional backend (Mitsuba's LLVM variant, a GPU adapter) is missing."""

    exit_code = 5


class GoalsMissed(AtlasgenError):
    """``validate --strict``: a material missed a validation goal (the report is still written)."""

    exit_code = 6


class BakeWarnings(AtlasgenError):
    """``bake --strict``: a material warned (a measured error over the threshold, a dropped lobe,
    tolerated non-finite samples, texels clamped to a scale given: :mod:`atlasgen.bake.quality`); nothing is written."""

    exit_code = 7


def did_you_mean(word: str, known) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``known`` to a mistyped ``word``, else ``""``.

    Closeness is :func:`difflib.get_close_matches` (Ratcliff/Obershelp similarity >= 0.6).
    """
    close = difflib.get_close_matches(word, list(known), n=1)
    return f" (did you mean '{close[0]}'?)" if close else ""


EXIT_OK = 0
#: An exception atlasgen did not raise on purpose: a bug.
EXIT_INTERNAL = 1
#: click's status for a bad command line.
EXIT_USAGE = 2
#: 128 + SIGINT, as a shell reports a process that Ctrl-C ended.
EXIT_INTERRUPTED = 130
#: 128 + SIGTERM, as a shell reports a process that ``kill`` ended.
EXIT_TERMINATED = 143


class Terminated(KeyboardInterrupt):
    """SIGTERM to the command line (``kill``, a CI job's time-out, an IDE's stop button).

    An interrupt like Ctrl-C, so that every clean-up a Ctrl-C runs runs for it too (a bake's
    workers stopped, an output set left whole); the CLI prints one line and exits
    :data:`EXIT_TERMINATED`.
    """


#: Where the internal-error message asks users to report the bug.
REPORT_BUGS_TO = "the atlasgen maintainers (README.md)"

#: ``(status, meaning)`` of every exit status the CLI uses, in order.
EXIT_CODES = (
    (EXIT_OK, "success"),
    (
        EXIT_INTERNAL,
        "internal error (a bug): one line names the exception; `atlasgen --debug ...` or "
        "`ATLASGEN_DEBUG=1` shows the traceback to report",
    ),
    (
        EXIT_USAGE,
        "usage error: an unknown option, a bad option value (an output named with another kind's "
        "extension, such as `-o atlas.png`, included) or an option its mode ignores (`validate --merge --spp 4`)",
    ),
    (
        InputError.exit_code,
        "bad input: a material, scene, atlas or cache file, a missing path; the message names the "
        "file, the field and what was expected",
    ),
    (
        OutputError.exit_code,
        "an output cannot be written or replaced, would overwrite an input, another output or a folder, or "
        "another writer held its output set's lock past the timeout; existing outputs are left untouched",
    ),
    (
        BackendError.exit_code,
        "a backend is missing: Mitsuba's LLVM variant (`apt-get install libllvm19`) or a WebGPU "
        "adapter (`apt-get install mesa-vulkan-drivers`)",
    ),
    (GoalsMissed.exit_code, "validate --strict: a material missed a validation goal (the report is still written)"),
    (
        BakeWarnings.exit_code,
        "bake --strict: a material warned (its measured error over the threshold, a dropped delta lobe, "
        "tolerated non-finite samples, texels clamped to a scale given); nothing is written",
    ),
    (
        EXIT_INTERRUPTED,
        "interrupted (Ctrl-C, at any instant once atlasgen's code runs); each output set is left whole, as it was "
        "unless the interrupt came after its commit (see 'Outputs: one generation on disk'). "
        "`preview --watch` is the exception: Ctrl-C is how it ends, with exit 0",
    ),
    (
        EXIT_TERMINATED,
        "terminated (SIGTERM: `kill`, a job's time-out), at any instant once atlasgen's code runs; as Ctrl-C, "
        "each output set is left whole and no bake worker outlives the command",
    ),
)
