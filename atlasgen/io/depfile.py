"""Make dependency files (the ``gcc -MMD -MP`` format) naming the inputs an output was built from."""

from __future__ import annotations

from pathlib import Path

from atlasgen.errors import InputError
from atlasgen.io.atomic import write_file_atomically

__all__ = ["encode_depfile", "format_depfile", "write_depfile"]


def _escape(path) -> str:
    r"""``path`` as make reads it back: ``$`` doubled, ``#``, space and ``:`` escaped with a backslash.

    Make splits prerequisites on spaces, reads ``#`` as a comment, ``$`` as a variable and ``:`` as
    the end of a rule's targets. A line break cannot be escaped (make ends the rule there).

    >>> print(_escape("out/a b:c#1$.toml"))
    out/a\ b\:c\#1$$.toml

    Raises
    ------
    InputError
        ``path`` holds a line break.
    """
    text = Path(path).as_posix()
    if "\n" in text or "\r" in text:
        raise InputError(f"--depfile: cannot write {text!r} as a make prerequisite (make ends a rule at a line break); "
                         "expected paths without line breaks")  # fmt: skip
    return text.replace("$", "$$").replace("#", r"\#").replace(" ", r"\ ").replace(":", r"\:")


def format_depfile(target, prerequisites) -> str:
    """``target: prerequisite ...``, then an empty rule per prerequisite.

    The empty rules (gcc's ``-MP``) keep ``make`` working when a prerequisite is
    deleted: the output is then rebuilt instead of the build stopping with "No rule to
    make target". A prerequisite that has a pattern rule keeps it, since a rule
    without a recipe does not replace one.

    Raises
    ------
    InputError
        A path holds a line break, which a depfile cannot hold.
    """
    prerequisites = list(dict.fromkeys(_escape(p) for p in prerequisites))
    lines = [" \\\n  ".join([f"{_escape(target)}:", *prerequisites]), ""]
    lines += [f"{p}:" for p in prerequisites]
    return "\n".join(lines) + "\n"


def encode_depfile(target, prerequisites) -> bytes:
    """:func:`format_depfile` as the bytes of a file: each path's own bytes, as make reads names, even where
    a name is no UTF-8 (Python holds such a byte as a lone surrogate, which UTF-8 cannot encode).

    >>> import os
    >>> encode_depfile(os.fsdecode(b"out/X\\xff.dds"), ["a.toml"])
    b'out/X\\xff.dds: \\\\\\n  a.toml\\n\\na.toml:\\n'
    """
    return format_depfile(target, prerequisites).encode("utf-8", "surrogateescape")


def write_depfile(path, target, prerequisites) -> Path:
    """Write :func:`encode_depfile` to ``path`` atomically; returns the path."""
    write_file_atomically(path, encode_depfile(target, prerequisites))
    return Path(path)
