"""Reading a user-named input file, as bytes or text, with the one-line refusals every reader shares."""

from __future__ import annotations

import errno
import json
import os
import re
import stat
import sys
import tomllib
from pathlib import Path

from atlasgen.errors import FieldError, InputError, shorten

__all__ = [
    "MISSING",
    "check_path_text",
    "decode_utf8",
    "explain_toml_error",
    "loads_json",
    "parse_toml",
    "path_kind",
    "read_input_bytes",
    "read_input_text",
    "special_file_kind",
]

#: What a path that is neither a regular file nor a folder is, by its stat mode, as a refusal names it.
_SPECIAL_KINDS = ((stat.S_ISFIFO, "a named pipe"), (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a character device"),
                  (stat.S_ISBLK, "a block device"))  # fmt: skip
#: What :func:`path_kind` says of a path with nothing there, or a name the system cannot take.
MISSING = "missing"


def path_kind(path) -> str | None:
    """None where ``path`` is a regular file, else what it is, for a reader's refusal: :data:`MISSING`
    (nothing there, or a name the system cannot take: a NUL character, one too long), "a directory",
    "a named pipe", "a socket", "a character device", "a block device" or "a symbolic link loop".

    A reader asks before it opens: reading a named pipe waits for a writer that may never come,
    and a device has no end.
    """
    try:
        mode = Path(path).stat().st_mode
    except OSError as exc:
        return "a symbolic link loop" if exc.errno == errno.ELOOP else MISSING
    except ValueError:
        return MISSING
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "a directory"
    return next((kind for test, kind in _SPECIAL_KINDS if test(mode)), "not a regular file")


def special_file_kind(path) -> str | None:
    """What ``path`` is when it is a named pipe, socket or device (:func:`path_kind`), else None."""
    kind = path_kind(path)
    return None if kind in (None, MISSING, "a directory") else kind


def _refuse_special(path) -> None:
    kind = special_file_kind(path)
    if kind is not None:
        raise InputError(f"{Path(path).as_posix()}: expected a regular file, got {kind}")


def decode_utf8(data: bytes) -> str:
    """``data`` as UTF-8 text, a leading byte-order mark dropped: Windows editors (Notepad among them)
    write one, and TOML's parser would take it for the first statement. Raises UnicodeDecodeError.

    >>> decode_utf8(b"\\xef\\xbb\\xbftype = 1") == decode_utf8(b"type = 1") == "type = 1"
    True
    """
    return data.decode("utf-8-sig")


def check_path_text(path) -> None:
    """Refuse a path whose name is no UTF-8 text (a byte such as 0xff, which Python keeps as a lone
    surrogate): the manifest, the depfile and the include comments record a material's path as text,
    and a manifest holding one could not be read back, by atlasgen or an engine.

    >>> check_path_text("materials/gold.toml")
    >>> check_path_text(os.fsdecode(b"materials/bad\\xff.toml"))
    Traceback (most recent call last):
    ...
    atlasgen.errors.InputError: materials/bad\\udcff.toml: expected a file name in UTF-8
    """
    try:
        os.fspath(path).encode("utf-8")
    except UnicodeEncodeError:
        shown = Path(path).as_posix().encode("utf-8", "backslashreplace").decode("utf-8")
        raise InputError(f"{shown}: expected a file name in UTF-8") from None


def read_input_bytes(path, missing: str = "no such file", limit: tuple[int, str] | None = None) -> bytes:
    """The bytes of ``path`` (a reader that hashes them before it parses them); with ``limit``,
    ``(most bytes, what the file should be)``, a larger file is refused before it is read.

    Raises
    ------
    InputError
        ``path: {missing}`` when there is no such file; ``path: cannot read (...)`` when the
        system refuses it; ``path: expected a regular file, got ...`` for a folder, named pipe, socket
        or device (:func:`special_file_kind`); ``path: N bytes, ...`` for one over the ``limit``.
    """
    _refuse_special(path)
    try:
        with open(path, "rb") as file:
            if limit is not None and (size := os.fstat(file.fileno()).st_size) > limit[0]:
                raise InputError(f"{Path(path).as_posix()}: {size} bytes; expected {limit[1]}, at most {limit[0]} bytes")
            return file.read()
    except FileNotFoundError:
        raise InputError(f"{Path(path).as_posix()}: {missing}") from None
    except IsADirectoryError:
        # As a named pipe's refusal: "cannot read (Is a directory)" said what failed, not what was expected.
        raise InputError(f"{Path(path).as_posix()}: expected a regular file, got a folder") from None
    except OSError as exc:
        raise InputError(f"{Path(path).as_posix()}: cannot read ({exc.strerror})") from None


def read_input_text(path, missing: str, expected: str, error: type[FieldError], limit: int | None = None) -> str:
    """The UTF-8 text of ``path``; with ``limit``, a file of more bytes is refused before it is read.

    Raises
    ------
    InputError
        ``path: {missing}`` when there is no such file; ``path: cannot read (...)`` when the
        system refuses it; ``path: expected a regular file, got ...`` for a named pipe, socket or device.
    FieldError
        ``error`` (e.g. :class:`~atlasgen.errors.SceneError`), ``path: expected {expected}``,
        when it is a directory, not UTF-8, or over ``limit``.
    """
    shown = Path(path).as_posix()
    _refuse_special(path)
    try:
        with open(path, "rb") as file:
            if limit is not None and (size := os.fstat(file.fileno()).st_size) > limit:
                raise error(shown, None, f"expected {expected}, at most {limit} bytes, got {size} bytes")
            return decode_utf8(file.read())
    except FileNotFoundError:
        raise InputError(f"{shown}: {missing}") from None
    except IsADirectoryError:
        raise error(shown, None, f"expected {expected}, got a directory") from None
    except UnicodeDecodeError:
        raise error(shown, None, f"expected {expected}, got bytes that are not UTF-8") from None
    except OSError as exc:
        raise InputError(f"{shown}: cannot read ({exc.strerror})") from None


#: A JSON escape of a UTF-16 surrogate: a pair decodes to one character, a lone one to no text at all.
_SURROGATE_ESCAPE = re.compile(r"\\u[dD][89a-fA-F]")


def _parse_int(text: str) -> int:
    value = int(text)
    if abs(value) > sys.float_info.max:  # beyond a double: any reader's float() or isfinite() would raise
        raise ValueError(f"an integer of {len(text.lstrip('-'))} digits, beyond any number a double holds")
    return value


def _refuse_lone_surrogates(data) -> None:
    """Raise ValueError where a string of ``data`` (a key or a value, at any depth) holds a lone surrogate."""
    stack = [data]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            stack += [*item.keys(), *item.values()]
        elif isinstance(item, list):
            stack += item
        elif isinstance(item, str):
            try:
                item.encode("utf-8")
            except UnicodeEncodeError:
                raise ValueError(f"the string {ascii(item)[:40]} holds a lone UTF-16 surrogate, which is no text") from None


def loads_json(text: str, **kwargs) -> object:
    r"""``json.loads(text, **kwargs)``, refusing as the ValueError a malformed file raises, so that every
    reader refuses it on one line: arrays or objects nested too deeply for Python's decoder, an integer
    beyond a double (``math.isfinite`` raises on one) and a string holding a lone surrogate escape
    (``"\ud800"``: valid JSON, but no text any file, terminal or shader can hold).

    >>> loads_json("[" * 100000 + "]" * 100000)
    Traceback (most recent call last):
    ...
    ValueError: arrays or objects nested too deeply to read
    >>> loads_json('{"name": "\\ud83d\\ude00", "n": 12}')  # a surrogate pair is one character
    {'name': '😀', 'n': 12}
    >>> loads_json('["\\ud800"]')
    Traceback (most recent call last):
    ...
    ValueError: the string '\ud800' holds a lone UTF-16 surrogate, which is no text

    A key given twice in one object is refused too (Python's decoder keeps the last, so a hand-edited
    ``"encoding": "linear", "encoding": "srgb"`` read as sRGB without a word; TOML refuses it):

    >>> loads_json('{"encoding": "linear", "encoding": "srgb"}')
    Traceback (most recent call last):
    ...
    ValueError: the key 'encoding' appears twice in one object; expected each key once
    """
    kwargs.setdefault("parse_int", _parse_int)
    kwargs.setdefault("object_pairs_hook", _unique_keys)
    try:
        data = json.loads(text, **kwargs)
    except RecursionError:
        raise ValueError("arrays or objects nested too deeply to read") from None
    if _SURROGATE_ESCAPE.search(text):  # only then can a decoded string hold one
        _refuse_lone_surrogates(data)
    return data


def _unique_keys(pairs: list) -> dict:
    out = dict(pairs)
    if len(out) != len(pairs):
        keys = [key for key, _ in pairs]
        twice = next(key for i, key in enumerate(keys) if key in keys[:i])
        raise ValueError(f"the key {shorten(repr(twice))} appears twice in one object; expected each key once")
    return out


#: A TOML key, bare, quoted or dotted (TOML 1.0, "Keys").
_TOML_KEY = r"""(?:[A-Za-z0-9_-]+|"(?:[^"\\]|\\.)*"|'[^']*')(?:\s*\.\s*(?:[A-Za-z0-9_-]+|"(?:[^"\\]|\\.)*"|'[^']*'))*"""
_TOML_STATEMENT = re.compile(rf"\s*(?:(\[\[?)\s*({_TOML_KEY})\s*\]\]?|({_TOML_KEY})\s*=)")
_TOML_AT = r"\((?:at line (\d+), column \d+|at end of document)\)$"


def explain_toml_error(message: str, text: str) -> str:
    r"""tomllib's ``message`` on ``text``, with the key it means where tomllib names none.

    tomllib (Python 3.11) says "Cannot overwrite a value (at line 12, column 12)" for a key given twice, or a
    value and a table of one name, at the end of the offending statement: the key is read back from the last
    statement that starts at or before that line. Any other message is returned as it is.

    >>> explain_toml_error("Cannot overwrite a value (at line 2, column 6)", "a = 1\na = 2\n")
    "line 2: 'a' is already set (the key given twice, or a table of its name); expected each key once"
    >>> explain_toml_error("Cannot declare ('x', 'y') twice (at line 3, column 3)", "")
    'line 3: the table [x.y] is declared twice; expected each table once'
    """
    declared = re.match(r"Cannot declare \((.*)\) twice " + _TOML_AT, message)
    if declared:
        names = re.findall(r"'((?:[^'\\]|\\.)*)'|\"((?:[^\"\\]|\\.)*)\"", declared.group(1))
        table = ".".join(a or b for a, b in names)
        return f"line {declared.group(2)}: the table [{table}] is declared twice; expected each table once"
    overwrite = re.match(r"Cannot overwrite a value " + _TOML_AT, message)
    if not overwrite:
        return message
    lines = text.splitlines()
    last = int(overwrite.group(1)) if overwrite.group(1) else len(lines)
    for number in range(min(last, len(lines)), 0, -1):
        statement = _TOML_STATEMENT.match(lines[number - 1])
        if statement:
            if statement.group(2):
                return (f"line {number}: the table header {statement.group(1)}{statement.group(2)}"
                        f"{statement.group(1).replace('[', ']')} names a key already set; expected each key once")  # fmt: skip
            key = shorten(statement.group(3))
            shown_key = key if key.startswith(("'", '"')) else repr(key)
            return (
                f"line {number}: {shown_key} is already set (the key given twice, or a table of its name); expected each key once"
            )
    return message


def parse_toml(text: str, shown: str, error: type[FieldError]) -> dict:
    """``text`` parsed as TOML, or ``error(shown, None, "malformed TOML: ...")`` on one line.

    tomllib recurses once per level of nested arrays and inline tables, so a file nested a
    thousand deep ends in Python's RecursionError, which is a malformed file, not a bug.
    """
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(shown, None, f"malformed TOML: {explain_toml_error(str(exc), text)}") from None
    except RecursionError:
        raise error(shown, None, "malformed TOML: arrays or inline tables nested too deeply to read") from None
    except ValueError as exc:  # tomllib lets int() refuse an integer of over 4300 digits as a plain ValueError
        raise error(shown, None, f"malformed TOML: {shorten(str(exc))}") from None
