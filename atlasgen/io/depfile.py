"""Make dependency files (the ``gcc -MMD -MP`` format) naming the inputs an output was built from."""

from __future__ import annotations

import os
from pathlib import Path

from atlasgen.errors import InputError, OutputNameError, shorten
from atlasgen.io.atomic import write_file_atomically

__all__ = ["encode_depfile", "format_depfile", "write_depfile"]


#: Characters make reads in a rule's names and no escape makes plain, with what make takes each for: a depfile
#: naming them made make stop ("missing separator"), wait on a file of another name, or read a rule as a pattern.
_UNWRITABLE = {
    "\n": "the end of the rule", "\r": "the end of the rule", "\t": "a separator", ";": "the start of a recipe",
    "|": "the start of order-only prerequisites", "%": "a pattern's stem", "=": "a variable assignment",
    "*": "a wildcard", "?": "a wildcard", "[": "a wildcard", "]": "a wildcard", "(": "an archive member",
    ")": "an archive member", "\\": "an escape",
}  # fmt: skip


def _escape(path, role: str = "prerequisite") -> str:
    r"""``path`` as make reads it back: ``$`` doubled, ``#``, space and ``:`` escaped with a backslash.

    Make splits prerequisites on spaces, reads ``#`` as a comment, ``$`` as a variable and ``:`` as
    the end of a rule's targets. The characters of :data:`_UNWRITABLE` cannot be escaped (a line break
    ends the rule, ``;`` starts a recipe, ``%`` makes a pattern): a path holding one is refused.

    >>> print(_escape("out/a b:c#1$.toml"))
    out/a\ b\:c\#1$$.toml

    Raises
    ------
    InputError
        A prerequisite holds a character of :data:`_UNWRITABLE`.
    OutputNameError
        The target (an output named on the command line) does: a bad option value.
    """
    text = Path(path).as_posix()
    bad = next((c for c in text if c in _UNWRITABLE), None)
    if bad is not None:
        error = OutputNameError if role == "target" else InputError
        raise error(f"--depfile: cannot write {shorten(repr(text))} as a make {role}: make reads {bad!r} in it as "
                    f"{_UNWRITABLE[bad]}; expected a path without ; | % = * ? [ ] ( ) \\, tabs or line breaks")  # fmt: skip
    return text.replace("$", "$$").replace("#", r"\#").replace(" ", r"\ ").replace(":", r"\:")


def _from_working_folder(path) -> str:
    """``path`` from the working folder where it is an absolute path inside it (a file a material names, which the
    reader resolves from the material's folder), else as given: an absolute one made the same tree's depfiles differ
    by where the tree lies.

    >>> import os
    >>> _from_working_folder(os.path.join(os.getcwd(), "materials", "t.png")), _from_working_folder("/elsewhere/t.png")
    ('materials/t.png', '/elsewhere/t.png')
    """
    text = os.fspath(path)
    here = os.getcwd()
    if os.path.isabs(text) and text.startswith(here.rstrip(os.sep) + os.sep):
        return Path(os.path.relpath(text, here)).as_posix()
    return text


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
    prerequisites = list(dict.fromkeys(_escape(_from_working_folder(p)) for p in prerequisites))
    lines = [" \\\n  ".join([f"{_escape(target, 'target')}:", *prerequisites]), ""]
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
