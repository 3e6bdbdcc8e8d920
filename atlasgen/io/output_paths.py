"""Checking a command's output paths before anything is written.

An output that is also an input (``atlasgen bake m.toml -o m.toml``), two outputs on one
path, an output that is a folder, a device, a named pipe or a socket, one under a file, or one
in a folder that takes no new file (read-only, immutable): each is refused with one line, before
any work, so that a failing command never replaces anything, nor finds out only after minutes of it.
"""

from __future__ import annotations

import os
import tempfile
import unicodedata
from pathlib import Path

from atlasgen.errors import OutputError, OutputNameError, shorten
from atlasgen.interrupts import deferred_interrupts
from atlasgen.io.atomic import (
    MAX_OUTPUT_NAME_BYTES,
    TEMP_SUFFIX,
    refuse_another_sets,
    refuse_inside_store,
    refuse_other_writers,
    remove_stale_temporaries,
    temp_prefix,
)
from atlasgen.io.text import special_file_kind

__all__ = ["check_cache_folder", "check_output_folder", "check_output_paths", "check_suffix", "refuse_inputs_in_folder"]


def _key(path: Path) -> str:
    return os.path.realpath(path)


def _same_file(a: Path, b: Path) -> bool:
    if _key(a) == _key(b):
        return True
    try:
        return os.path.samefile(a, b)  # hard links
    except OSError:
        return False


def _nearest_existing(path: Path) -> Path | None:
    """The nearest existing ancestor of ``path``: where making its folder would start."""
    return next((parent for parent in path.absolute().parents if parent.exists()), None)


def _blocking_file(path: Path) -> Path | None:
    """The nearest existing ancestor of ``path`` when it is not a folder, else None."""
    parent = _nearest_existing(path)
    return None if parent is None or parent.is_dir() else parent


def _blocked(folder: Path, blocker: Path, output: str) -> OutputError:
    """The refusal of an output file (``output``: ``"b/x.d: --depfile"``) whose folder ``folder`` cannot be made:
    ``blocker``, an existing file on its path, stands in for it."""
    kind = special_file_kind(blocker) or "a file"
    return OutputError(f"{output}: cannot write its folder {folder.as_posix()} ({blocker.as_posix()} is {kind})")


def check_output_paths(outputs, inputs=()) -> None:
    """Refuse outputs that would overwrite an input, each other, or a folder.

    Parameters
    ----------
    outputs
        ``(path, role)`` pairs, ``role`` saying what the path is in the message
        (``"the manifest"``, ``"--preview"``).
    inputs
        ``(path, role)`` pairs of files the command reads.

    Raises
    ------
    OutputError
        On the first clash, naming the path and both roles, on one line.
    """
    outputs = [(Path(p), role) for p, role in outputs]
    # One file read for many materials (a MaterialX document's every surfacematerial) is checked once, under its
    # first role: a document of 5000 materials compared each cache entry with 5000 copies of itself, for minutes.
    unique: dict[str, tuple[Path, str]] = {}
    for p, role in inputs:
        unique.setdefault(_key(Path(p)), (Path(p), role))
    inputs = list(unique.values())
    seen: dict[str, tuple[Path, str]] = {}
    for path, role in outputs:
        try:
            _check_output(path, role, inputs, seen)
        except OSError as exc:  # a name the system cannot take (too long, say): stat() itself fails
            raise OutputError(f"{path.as_posix()}: {role}: cannot write ({exc.strerror or type(exc).__name__}); "
                              "expected a path the file system can hold") from None  # fmt: skip
    _refuse_nested_outputs(seen)
    probed = set()
    for path, role in outputs:  # a bake's cache entries share one folder: probed once
        if _key(path.parent) not in probed:
            probed.add(_key(path.parent))
            _refuse_unwritable(path.parent, f"{path.as_posix()}: {role}")


def _refuse_nested_outputs(seen: dict) -> None:
    """Refuse an output lying under another output's path (``--preview a.dds/sheet.png``, ``--cache a.dds``): the
    commit made the one a folder and then could not write the other, after the work, naming neither option."""
    for key, (path, role) in seen.items():
        for parent in Path(key).parents:
            other = seen.get(str(parent))
            if other is not None:
                raise OutputError(f"{path.as_posix()}: {role} lies under {other[0].as_posix()}, {other[1]}'s path; "
                                  "expected outputs beside each other, not one inside another")  # fmt: skip


def _refuse_dangling_folder(path: Path, where: str) -> None:
    """Refuse ``where`` (``"b/x.dds: the atlas (-o)"``) where the nearest folder on ``path``'s way that does not exist
    is a symbolic link to nothing: making it failed after the work ("cannot write output folder (File exists)"),
    naming no option."""
    for parent in path.parents:
        if parent.exists():
            return
        if parent.is_symlink():
            raise OutputError(f"{where}: its folder {parent.as_posix()} is a symbolic link to {os.readlink(parent)!r}, "
                              "which does not exist; expected a folder path")  # fmt: skip


def _check_output(path: Path, role: str, inputs, seen: dict) -> None:
    """:func:`check_output_paths` for one output, ``seen`` holding the outputs checked before it."""
    shown = path.as_posix()
    # C0, DEL and C1 (NEL, CSI: a terminal's escapes), and Unicode's line and paragraph separators, which line-based
    # readers (Python's splitlines, the error lines here) break at.
    control = next((c for c in shown if unicodedata.category(c) in ("Cc", "Zl", "Zp")), None)
    if control is not None:
        # A line break in a name split the command's "wrote ..." line in two, and a make rule that names it.
        raise OutputNameError(f"{shorten(repr(shown))}: {role}: a name holding the control character {control!r}; "
                              "expected a path without line breaks, tabs or other control characters")  # fmt: skip
    size = len(os.fsencode(path.name))
    if size > MAX_OUTPUT_NAME_BYTES:
        raise OutputNameError(f"{(path.parent / shorten(path.name)).as_posix()}: {role}: a file name of {size} bytes; expected at most "
                              f"{MAX_OUTPUT_NAME_BYTES} (the temporary files written beside it add to the name)")  # fmt: skip
    if path.is_dir():
        raise OutputError(f"{shown}: {role} is an existing folder; expected a file path")
    kind = special_file_kind(path)
    if kind is not None and kind != "a symbolic link loop":
        # Committing replaces the name with a link into the set's store: --depfile /dev/null replaced the
        # system's /dev/null, and a named pipe or a link to /dev/stdout went the same way.
        raise OutputError(f"{shown}: {role} is {kind}; expected a regular file path, which the command replaces")
    blocker = _blocking_file(path)
    if blocker is not None:
        raise _blocked(path.parent, blocker, f"{shown}: {role}")
    _refuse_dangling_folder(path, f"{shown}: {role}")
    refuse_inside_store(path)
    key = _key(path)
    if key in seen:
        other, other_role = seen[key]
        raise OutputError(f"{shown}: both {other_role} and {role}; expected a different path for each output")
    seen[key] = (path, role)
    for source, source_role in inputs:
        if _same_file(path, source):
            raise OutputError(f"{shown}: {role} would overwrite {source_role} ({source.as_posix()}); "
                              "expected an output path that is not an input")  # fmt: skip


def check_suffix(path, role: str, suffixes) -> None:
    """Refuse an output whose extension is not one of ``suffixes`` (case-insensitive)."""
    path = Path(path)
    if path.suffix.lower() not in suffixes:
        expected = " or ".join(suffixes)
        raise OutputNameError(f"{path.as_posix()}: {role} must end in {expected}, not {path.suffix or 'no extension'!r}")


def check_output_folder(path, role: str, writes=()) -> None:
    """Refuse an output folder (a report's ``-o``) that is an existing file or lies under one, takes no new file, or
    is inside an output set's store, before the command renders or measures anything; and one where a file the
    command always writes (``writes``, names in the folder, its set's primary first) is another command's."""
    path = Path(path)
    _check_folder(path, role, "output folder")
    refuse_inside_store(path, folder=True)
    if writes:
        # A folder in a file's place failed the commit, after the command's work.
        check_output_paths([(path / name, f"the report's {name}") for name in writes])
        refuse_another_sets([path / name for name in writes], path / writes[0])
        refuse_other_writers(path / writes[0])


def refuse_inputs_in_folder(folder, inputs, role: str = "the report folder (-o)") -> None:
    """Refuse ``inputs`` (``(path, what)`` pairs) lying directly in a report's ``folder``: the report's files (plots
    named by material, say) are known only once measured, and a scene named speed_error.png or a material named
    index.md there was replaced by the report, exit 0. A link is judged by where it lies, not where it points."""
    real = os.path.realpath(folder)
    for path, what in inputs:
        if os.path.realpath(os.path.dirname(os.path.abspath(path))) == real:
            raise OutputError(f"{Path(path).as_posix()}: {what} lies in {role}, {Path(folder).as_posix()}, whose files "
                              "the report replaces; expected the inputs outside it")  # fmt: skip


def check_cache_folder(path, role: str) -> None:
    """Refuse a cache folder (``--cache``) that is an existing file, lies under one or takes no new file, before the
    command renders or bakes what it would store there: a store failing at the end lost that work."""
    _check_folder(Path(path), role, "cache folder")


def _check_folder(path: Path, role: str, noun: str) -> None:
    """Refuse a folder ``path`` (``noun``: ``"output folder"``) that is an existing file, lies under one, or takes
    no new file."""
    if path.exists() and not path.is_dir():
        kind = special_file_kind(path) or "an existing file"
        raise OutputError(f"{path.as_posix()}: {role} is {kind}; expected a folder path")
    if path.is_symlink() and not path.exists():
        # mkdir then failed on the link (File exists), after the command's work, naming no option.
        raise OutputError(f"{path.as_posix()}: {role} is a symbolic link to {os.readlink(path)!r}, which does not exist; "
                          f"expected a folder path")  # fmt: skip
    _refuse_dangling_folder(path, f"{path.as_posix()}: {role}")
    blocker = _blocking_file(path)
    if blocker is not None:
        kind = special_file_kind(blocker) or "a file"
        raise OutputError(f"{path.as_posix()}: cannot write {noun}: {role} lies under {blocker.as_posix()}, which is "
                          f"{kind}; expected a folder path")  # fmt: skip
    _refuse_unwritable(path, f"{path.as_posix()}: {role}")


#: The name of the empty folder a probe makes and removes (:func:`_refuse_unwritable`).
_PROBE = "atlasgen-probe"


def _refuse_unwritable(folder: Path, where: str) -> None:
    """Refuse ``where`` (``"b/x.dds: the atlas (-o)"``) when ``folder``, or the nearest existing folder above it that
    the command would make it in, takes no new entry.

    Probed by making and removing an empty folder there, not by ``os.access``: permission bits do not bind root,
    while an immutable folder (``chattr +i``) or a read-only mount binds everyone; ``os.access`` sees neither."""
    at = folder.absolute() if folder.is_dir() else _nearest_existing(folder)
    if at is None:
        return
    # Named by this process, as the commit's temporaries are: one a kill left between making and removing it was
    # there for good (its name held no pid); the next probe here removes it. Ctrl-C waits for the two steps.
    remove_stale_temporaries(at / _PROBE)
    try:
        with deferred_interrupts():
            os.rmdir(tempfile.mkdtemp(prefix=temp_prefix(_PROBE), suffix=TEMP_SUFFIX, dir=at))
    except OSError as exc:
        raise OutputError(
            f"{where}: cannot write in {at.as_posix()} ({exc.strerror or type(exc).__name__}); "
            "expected a folder this user may write"
        ) from None
