"""All-or-nothing output sets: a generation folder swapped by one rename, under a lock.

A command's outputs (a bake's ``X.dds``, ``X.json``, includes, side-car and timings; a
render's EXR and PNG; a report's pages) change together or not at all, as seen by any
reader, atlasgen or not. Each output at its documented path is a relative symbolic link
that never changes once made::

    X.dds -> .X.atlasgen/current/X.dds        images/a.png -> ../.X.atlasgen/current/images/a.png
    .X.atlasgen/current -> gen-7              .X.atlasgen/gen-7/X.dds, X.json, ...

(``X``: the primary output's name up to its first dot, :func:`set_key`.) A commit, under the
set's lock (``fcntl.flock`` on ``.X.atlasgen/lock``, waiting up to :data:`LOCK_TIMEOUT_S`):

1. **Check** every file the commit replaces or removes: one marked immutable or append-only
   (``chattr +i``), a folder, or another set's link (two commands' outputs pointed at one folder,
   which would leave the other set's files beside this one's) refuses the commit, so nothing is
   replaced.
2. **Write** every new file into a fresh ``gen-<n+1>`` and flush it to disk.
3. **Migrate**, only where a documented path is not yet this set's link (a plain file of an
   older atlasgen, a foreign link): a holding generation gets a hard link of it (and of the
   current generation's files), ``current`` is pointed at it, and the link is renamed over the
   file. A plain reader sees the same bytes before and after each step.
4. **Link** each new name (a link into ``current`` that does not resolve yet: absent to a reader).
5. **Swap**: a temporary link ``current.<pid>.<random>.tmp -> gen-<n+1>`` renamed over
   ``current``. This one rename is the commit: before it every path resolves to the old
   generation, after it to the new one.
6. **Tidy**: the links of names that left the set (stale siblings, ``remove``) now resolve to
   nothing and are unlinked; generations older than the previous one are removed by the
   next commit (a reader that resolved ``current`` just before the swap still finds its files).

The new generation holds the files written, plus (hard links of) the previous generation's
files that were neither rewritten nor removed: files a command did not write are left as they
were, as with plain files. A commit may name its writer (a scene's bake and its render share the
set ``.X.atlasgen``): the store then records who wrote each file (``gen-<n>.writers``), the
commit is refused a file another writer wrote, and this writer's own earlier files that it does
not write again (a render's old depfile) are not carried over. A run killed at any instant
leaves every path resolving into one whole generation; the next commit removes what it left. Ctrl-C is held from step 3 to 6.
Because every new file is new, ``make`` (whose ``stat`` follows the link) sees the targets of
a commit as fresh, and those of a killed one as stale.

A failure before step 5 leaves what every reader sees as it was (exit 4). Single files
(:func:`write_file_atomically`: caches, ``atlasgen preview``'s image) stay
plain files, replaced by one rename of a temporary ``.<name>.<pid>.<random>.atlasgen.tmp``
beside them; the next write of the same target removes those whose process is gone.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import math
import os
import re
import secrets
import shutil
import struct
import tempfile
import time
from pathlib import Path

from atlasgen.errors import InputError, OutputError, shorten
from atlasgen.interrupts import deferred_interrupts
from atlasgen.io.text import special_file_kind

__all__ = [
    "write_files_atomically",
    "write_file_atomically",
    "staged_folder",
    "scratch_folder",
    "remove_stale_temporaries",
    "temp_prefix",
    "output_lock",
    "lock_timeout",
    "set_key",
    "store_path",
    "refuse_inside_store",
    "refuse_another_sets",
    "refuse_set_link",
    "refuse_other_writers",
    "TEMP_SUFFIX",
    "STORE_SUFFIX",
    "LOCK_TIMEOUT_S",
    "WRITERS_SUFFIX",
    "WHOLE_WRITER",
    "MAX_OUTPUT_NAME_BYTES",
]

#: Every temporary file or folder this module creates beside an output ends with this.
TEMP_SUFFIX = ".atlasgen.tmp"
#: ``.<key>.atlasgen``: the folder of an output set's generations, its ``current`` link and its lock.
STORE_SUFFIX = ".atlasgen"
CURRENT = "current"
LOCK_NAME = "lock"
GENERATION = re.compile(r"gen-(\d+)$")
#: A generation stores an output outside the primary's folder as ``@up<k>/<rest>`` (``k`` leading ``..``).
UP = "@up"
#: The longest output file name, in bytes, whose temporaries (``.<name>.<pid>.<random>.atlasgen.tmp``) and store
#: still fit the file system's 255: a 250-byte name failed at its scratch file, naming the folder ".".
MAX_OUTPUT_NAME_BYTES = 215
#: Seconds a writer waits for another writer of the same output set (``ATLASGEN_LOCK_TIMEOUT_S``
#: overrides it) before it refuses with one line.
LOCK_TIMEOUT_S = 120.0

#: ``<generation>.writers`` beside a generation in the store: which command wrote each of its files
#: (``{stored name: writer}``, JSON). Two commands may share a set (a scene's bake ``X.dds`` and its render
#: ``X.exr``): a commit that names its writer may not replace the other's files, and does not carry forward
#: its own earlier files that it no longer writes (a render's old depfile beside a render that wrote none).
WRITERS_SUFFIX = ".writers"
#: The writer recorded for the files of a commit that replaces its set whole and names no writer (a report's folder):
#: a named writer (a bake, a render) may not share such a set, which the report's next commit would replace.
WHOLE_WRITER = "a report, replaced whole"

#: Test hook: when set, called as ``hook(step, path)`` before each step of a commit: ``"write"``
#: (a new file for ``path``), ``"migrate"`` (``path`` turned into its link), ``"link"`` (a new
#: name's link), ``"swap"`` (the commit, ``path`` the primary), ``"remove"`` (a stale link).
#: Tests set it to kill the process at every step in turn; it is None otherwise.
commit_hook = None


def _step(step: str, path: Path) -> None:
    if commit_hook is not None:
        commit_hook(step, path)


def temp_prefix(name: str) -> str:
    """The start of a temporary's name beside ``name``: ``.<name>.<pid>.`` (then a random part and TEMP_SUFFIX), which
    :func:`remove_stale_temporaries` recognises once the process is gone."""
    return f".{name}.{os.getpid()}."


def _folder(path: Path) -> Path:
    return path.parent if str(path.parent) else Path(".")


def set_key(primary) -> str:
    """The name an output set's store and lock are called by: the primary's name up to its first dot.

    >>> set_key("build/atlas.dds"), set_key("out/report.json"), set_key(".hidden")
    ('atlas', 'report', '.hidden')
    """
    name = Path(primary).name
    return name.split(".", 1)[0] or name


def store_path(primary) -> Path:
    """``.<key>.atlasgen`` beside ``primary``: the folder that holds its set's generations.

    >>> store_path("build/atlas.dds").as_posix()
    'build/.atlas.atlasgen'
    """
    return _folder(Path(primary)) / f".{set_key(primary)}{STORE_SUFFIX}"


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    return True


def remove_stale_temporaries(path) -> list[Path]:
    """Remove the temporaries of ``path`` left by runs that died; return what was removed.

    Only names this module makes (``.<name>.<pid>.<random>.atlasgen.tmp``) whose pid is no
    longer running are touched; files, links and folders alike.
    """
    path = Path(path)
    folder = _folder(path)
    pattern = re.compile(re.escape(f".{path.name}.") + r"(\d+)\.[^.]+" + re.escape(TEMP_SUFFIX) + "$")
    removed: list[Path] = []
    try:
        candidates = list(folder.iterdir())
    except OSError:
        return removed
    for candidate in candidates:
        match = pattern.match(candidate.name)
        if match is None or _pid_alive(int(match.group(1))):
            continue
        try:
            if candidate.is_dir() and not candidate.is_symlink():
                shutil.rmtree(candidate)
            else:
                candidate.unlink()
            removed.append(candidate)
        except OSError:
            pass
    return removed


def _fsync_folder(folder) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _discard(path) -> None:
    """Remove a link or file if it can be: an immutable one stays, without harm."""
    with contextlib.suppress(OSError):
        os.unlink(path)


def lock_timeout() -> float:
    """``ATLASGEN_LOCK_TIMEOUT_S`` if set, else :data:`LOCK_TIMEOUT_S`; a value that is no finite
    number of seconds >= 0 is refused rather than read as "wait forever" (nan, inf) or ignored."""
    text = os.environ.get("ATLASGEN_LOCK_TIMEOUT_S")
    if text is None:
        return LOCK_TIMEOUT_S
    try:
        seconds = float(text)
    except ValueError:
        seconds = math.nan
    if not (math.isfinite(seconds) and seconds >= 0.0):
        raise InputError(f"ATLASGEN_LOCK_TIMEOUT_S: expected a finite number of seconds >= 0, got {shorten(repr(text))}")
    return seconds


@contextlib.contextmanager
def output_lock(folder, key: str, timeout: float | None = None):
    """Hold ``folder/.<key>.atlasgen/lock`` (``fcntl.flock``, exclusive) for the block; yield its path.

    Waits up to ``timeout`` seconds (default :data:`LOCK_TIMEOUT_S`, or
    ``ATLASGEN_LOCK_TIMEOUT_S``) for another process holding it. The lock file stays in the
    set's store, so a waiter always locks the file the holder locked.

    Raises
    ------
    OutputError
        The lock file cannot be opened, or another writer held it for the whole timeout.
    """
    store = Path(folder) / f".{key}{STORE_SUFFIX}"
    lock_path = store / LOCK_NAME
    timeout = lock_timeout() if timeout is None else timeout
    if os.path.lexists(store) and not store.is_dir():
        # A file of the store's name: "lock: cannot open ... (File exists)" named neither it nor what was expected.
        raise OutputError(f"{store.as_posix()}: expected the folder atlasgen keeps this output set's files in, got a "
                          "file; move it away (the name is atlasgen's)")  # fmt: skip
    try:
        store.mkdir(parents=True, exist_ok=True)
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise OutputError(f"{lock_path.as_posix()}: cannot open the output set's lock file ({exc.strerror})") from None
    try:
        deadline = time.monotonic() + timeout
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    raise OutputError(f"{lock_path.as_posix()}: another atlasgen process is writing this output set "
                                      f"(waited {timeout:g} s); expected one writer at a time") from None  # fmt: skip
                time.sleep(0.05)
        yield lock_path
    finally:
        os.close(fd)  # closing releases the lock


# ---- a generation store: .<key>.atlasgen/{lock, current -> gen-<n>, gen-<n>/...} ----


def _stored_name(home: Path, path: Path) -> str:
    """Where ``path`` lives inside a generation: its path from the primary's folder ``home``,
    ``..`` parts (an output outside ``home``, e.g. a ``--preview`` elsewhere) written ``@up<k>/``.

    >>> _stored_name(Path("/b"), Path("/b/img/a.png")), _stored_name(Path("/b/x"), Path("/b/y/p.png"))
    ('img/a.png', '@up1/y/p.png')
    """
    parts = Path(os.path.relpath(os.path.abspath(path), os.path.abspath(home))).parts
    ups = len(parts) - len(tuple(p for p in parts if p != ".."))
    return "/".join((f"{UP}{ups}",) * (ups > 0) + parts[ups:])


def _target_path(home: Path, stored: str) -> Path:
    """The output path a generation's ``stored`` name stands for (the inverse of :func:`_stored_name`)."""
    first, _, rest = stored.partition("/")
    if first.startswith(UP) and first[len(UP) :].isdigit() and rest:
        return home.joinpath(*([".."] * int(first[len(UP) :])), rest)
    return home / stored


def _link_text(store: Path, stored: str, path: Path) -> str:
    """The relative text of ``path``'s link into ``store/current``; from the real folders, as the
    kernel resolves ``..`` in a link from the folder it is really in."""
    return os.path.relpath(os.path.join(os.path.realpath(store), CURRENT, stored), os.path.realpath(_folder(path)))


def _is_link_to(path: Path, text: str) -> bool:
    try:
        return os.readlink(path) == text
    except OSError:
        return False


def _names(gen: Path) -> list[str]:
    """Every stored name of a generation (files and links, folders walked), sorted."""
    names: list[str] = []

    def walk(folder: Path, prefix: str) -> None:
        with os.scandir(folder) as entries:
            for entry in sorted(entries, key=lambda e: e.name):
                if entry.is_dir(follow_symlinks=False):
                    walk(Path(entry.path), f"{prefix}{entry.name}/")
                else:
                    names.append(prefix + entry.name)

    with contextlib.suppress(OSError):
        walk(gen, "")
    return names


def _current(store: Path) -> str | None:
    """The name of the generation ``store/current`` points at (None before the first commit)."""
    try:
        name = os.readlink(store / CURRENT)
    except OSError:
        return None
    return name if GENERATION.match(name) else None


def _read_writers(store: Path, generation: str | None) -> dict:
    """The writers of ``generation``'s files (:data:`WRITERS_SUFFIX`); empty where none is recorded (a set an
    older atlasgen wrote, or commits that named no writer)."""
    if generation is None:
        return {}
    try:
        data = json.loads((store / f"{generation}{WRITERS_SUFFIX}").read_text())
    except (OSError, ValueError):
        return {}
    return {k: v for k, v in data.items() if isinstance(k, str) and isinstance(v, str)} if isinstance(data, dict) else {}


def _write_writers(store: Path, gen: Path, writers: dict) -> None:
    """Record ``writers`` for ``gen`` (none where it is empty), flushed before the swap that makes it current."""
    record = store / f"{gen.name}{WRITERS_SUFFIX}"
    if os.path.lexists(record):  # a killed commit's, of a generation number collected since and taken again
        _discard(record)
    if writers:
        _write_file(record, json.dumps(dict(sorted(writers.items())), indent=0).encode())


def _taken(path: Path, writer: str, store: Path) -> OutputError:
    return OutputError(f"{path.as_posix()}: already written by `atlasgen {writer}` into the same output set "
                       f"({store.name}); expected a name of its own; nothing was replaced")  # fmt: skip


def _refuse_taken(home: Path, store: Path, paths, writer: str | None, owners: dict) -> None:
    """Refuse ``paths`` that ``owners`` (the current generation's writers) record as another writer's files."""
    if writer is None:
        return
    # A report's set: `bake -o L1/index.dds` beside `report library -o L1` committed into the page's set, and the
    # report's next run was refused (or, before that check, removed the atlas).
    for stored, other in sorted(owners.items()):
        if other == WHOLE_WRITER and _linked(home, store, [stored]):
            raise OutputError(f"{_target_path(home, stored).as_posix()}: written by a report into the output set "
                              f"({store.name}) it replaces whole; expected a folder of its own for each command's "
                              "outputs; nothing was replaced")  # fmt: skip
    for path in paths:
        other = owners.get(_stored_name(home, Path(path)))
        if other is not None and other != writer:
            raise _taken(Path(path), other, store)


def _new_generation(store: Path) -> Path:
    numbers = [int(m.group(1)) for m in map(GENERATION.match, os.listdir(store)) if m]
    gen = store / f"gen-{max(numbers, default=0) + 1}"
    gen.mkdir()
    return gen


def _unchanged(path: Path, exc: OSError) -> OutputError:
    return OutputError(f"{path.as_posix()}: cannot replace ({exc.strerror}); every output was left as it was")


def _swap(store: Path, gen: Path, primary: Path) -> None:
    """Point ``store/current`` at ``gen`` by one rename of a fresh link over it: the commit.

    Raises
    ------
    OutputError
        The link cannot be made or renamed; ``current`` is then as it was.
    """
    tmp = store / f"{CURRENT}.{os.getpid()}.{secrets.token_hex(4)}.tmp"
    try:
        os.symlink(gen.name, tmp)
        _fsync_folder(store)
        _step("swap", primary)
        os.replace(tmp, store / CURRENT)
    except OSError as exc:
        _discard(tmp)
        raise _unchanged(primary, exc) from None
    _fsync_folder(store)


def _drop_links(home: Path, store: Path, names, keep: set) -> None:
    """Unlink this set's links of ``names`` not in ``keep``: they resolve to nothing once the
    generation that held them is no longer ``current`` (absent to a reader already)."""
    for stored in _linked(home, store, set(names) - keep):
        path = _target_path(home, stored)
        _step("remove", path)
        _discard(path)


def _check_current(store: Path, primary: Path) -> None:
    """Refuse a store whose ``current`` is there but is no link to a generation: a copy that followed links (``cp
    -rL``) makes a folder of it, whose files the outputs' links still reach. Read as "no generation yet", every
    generation was garbage: a bake removed the outputs' links and the generation, then failed on the folder,
    saying "every output was left as it was"."""
    entry = store / CURRENT
    if not os.path.lexists(entry) or _current(store) is not None:
        return
    if entry.is_symlink():
        got = f"a link to {os.readlink(entry)!r}"
    else:
        got = "a folder" if entry.is_dir() else special_file_kind(entry) or "a file"
    raise OutputError(f"{entry.as_posix()}: expected the link to the generation that {primary.name}'s set reads "
                      f"(gen-<n>), got {got}; nothing was changed (a copy that follows links, cp -rL, makes a folder "
                      "of it: copy output folders with cp -a)")  # fmt: skip


def _collect_garbage(home: Path, store: Path, previous: str | None = None) -> None:
    """Remove what earlier commits left in ``store`` (the caller holds the lock): every generation
    but ``current`` (and ``previous``), with the links of names only they held (a commit killed
    after its swap), and killed commits' temporary links."""
    current = _current(store)
    keep = set(_names(store / current)) if current else set()
    kept = {CURRENT, LOCK_NAME} | {f"{g}{suffix}" for g in (current, previous) if g for suffix in ("", WRITERS_SUFFIX)}
    for name in sorted(os.listdir(store)):
        if name in kept:
            continue
        entry = store / name
        if GENERATION.match(name) and entry.is_dir() and not entry.is_symlink():
            _drop_links(home, store, _names(entry), keep)
            shutil.rmtree(entry, ignore_errors=True)  # an immutable file stays, and is tried again next time
        elif not entry.is_dir() or entry.is_symlink():
            _discard(entry)


#: ``FS_IOC_GETFLAGS`` (``_IOR('f', 1, long)``) and the inode flags that forbid replacing a file.
FS_IOC_GETFLAGS = 0x80086601
FS_IMMUTABLE_FL, FS_APPEND_FL = 0x10, 0x20


def _check_replaceable(path: Path, stored_file: Path) -> None:
    """Refuse, before anything changes, to replace a file marked immutable or append-only
    (``chattr +i``/``+a``, which through a link marks the generation's file): swapping
    ``current`` would replace it all the same, against what the mark asks for. A file system
    without inode flags has no such files."""
    try:
        fd = os.open(stored_file, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return
    try:
        flags = struct.unpack("i", fcntl.ioctl(fd, FS_IOC_GETFLAGS, bytes(8))[:4])[0]
    except OSError:
        return
    finally:
        os.close(fd)
    if flags & (FS_IMMUTABLE_FL | FS_APPEND_FL):
        raise OutputError(f"{path.as_posix()}: cannot replace ({os.strerror(errno.EPERM)}); nothing was replaced")


def _hold(source: Path, held: Path) -> None:
    """Put what a reader of ``source`` sees at ``held``: a hard link of a file (a copy across file
    systems), or, for a link, one with the same target made absolute."""
    held.parent.mkdir(parents=True, exist_ok=True)
    if source.is_symlink():
        os.symlink(os.path.join(os.path.abspath(_folder(source)), os.readlink(source)), held)
        return
    try:
        os.link(source, held, follow_symlinks=False)
    except OSError as exc:
        if exc.errno != errno.EXDEV:
            raise
        shutil.copy2(source, held)


def _write_file(path: Path, data: bytes) -> None:
    with open(path, "xb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    os.chmod(path, 0o644)


def _link_into(path: Path, text: str) -> None:
    """Turn ``path`` (a plain file, a foreign link) into the link ``text`` by one rename."""
    tmp = Path(tempfile.mktemp(prefix=temp_prefix(path.name), suffix=TEMP_SUFFIX, dir=_folder(path)))
    os.symlink(text, tmp)
    try:
        os.replace(tmp, path)
    except OSError:
        _discard(tmp)
        raise


def _is_store(name: str) -> bool:
    return name.startswith(".") and name.endswith(STORE_SUFFIX) and len(name) > len(STORE_SUFFIX) + 1


def refuse_inside_store(path, folder: bool = False) -> None:
    """Refuse an output inside an output set's store (``-o v1/.report.atlasgen/current``, or a folder
    linked into one): it was written into a committed generation in place, which changed the files of
    the set's links (``v1/report.json``) without a commit, outside the lock. ``path`` is an output file,
    or with ``folder`` an output folder. Commands check it before their work (atlasgen.io.output_paths)."""
    path = Path(path)
    where = os.path.abspath(path if folder else _folder(path))
    for shown in (where, os.path.realpath(where)):
        store = next((part for part in Path(shown).parts if _is_store(part)), None)
        if store is not None:
            raise OutputError(f"{path.as_posix()}: inside {store}, the generations of an output set; expected a path "
                              "outside atlasgen's .*.atlasgen folders; nothing was replaced")  # fmt: skip


def _refuse_another_sets(path: Path, store: Path | None) -> None:
    """Refuse to take over a path that is another output set's link (``out/index.html`` of
    ``report library``, written again by ``validate -o out``): the other set would keep its other
    files beside this set's page, a folder of two commands' outputs mixed. Links of no set (a
    user's own) are migrated as before. ``store`` None: a plain file's write, for which every set is another."""
    try:
        text = os.readlink(path)
    except OSError:
        return
    parts = Path(text).parts
    at = next((i for i, part in enumerate(parts[:-1]) if _is_store(part) and parts[i + 1] == CURRENT), None)
    if at is None:
        return
    # From the real folders, as the kernel resolves the link (and as _link_text wrote it).
    other = os.path.normpath(os.path.join(os.path.realpath(_folder(path)), *parts[: at + 1]))
    if store is None or other != os.path.realpath(store):
        raise OutputError(f"{path.as_posix()}: already written by another command's outputs ({Path(other).name} beside it); "
                          "expected a folder of its own for each command's outputs; nothing was replaced")  # fmt: skip


def _refuse_others_files(home: Path, store: Path, names, writer: str | None, owners: dict) -> None:
    """Refuse to replace a set whole where ``names`` (its current files) hold one another writer wrote: a report
    folder holding a bake's ``index.dds`` set (the same key, ``index``) had that atlas's files removed, exit 0."""
    mine = WHOLE_WRITER if writer is None else writer
    for stored in _linked(home, store, names):
        other = owners.get(stored)
        if other is not None and other not in (writer, mine):
            raise OutputError(f"{_target_path(home, stored).as_posix()}: written by `atlasgen {other}` into the output set "
                              f"({store.name}) this command replaces whole; expected a folder of its own for each "
                              "command's outputs; nothing was replaced")  # fmt: skip


def refuse_other_writers(primary, writer: str | None = None) -> None:
    """Refuse, before a command's work, to replace whole the set of ``primary`` (a report's folder) where another
    command wrote files into it: :func:`write_files_atomically` refuses it at the commit, after the work."""
    primary = Path(primary)
    store = store_path(primary)
    current = _current(store)
    if current is not None:
        _refuse_others_files(_folder(primary), store, _names(store / current), writer, _read_writers(store, current))


def refuse_set_link(path) -> None:
    """Refuse to replace ``path`` with a plain file where it is an output set's link: ``preview -o
    report/cost-vs-error.png`` replaced the library report's link with a PNG, that set's folder then mixed."""
    _refuse_another_sets(Path(path), None)


def refuse_another_sets(paths, primary, writer: str | None = None) -> None:
    """Refuse, before a command's work, to write ``paths`` (the fixed files of the set whose primary is
    ``primary``) where one is another output set's link, or with ``writer``, another writer's file of this set:
    :func:`write_files_atomically` refuses it at the commit, after the work, and a report would have left its
    folders and lock behind by then."""
    store = store_path(primary)
    for path in paths:
        _refuse_another_sets(Path(path), store)
    if writer is not None:
        _refuse_taken(_folder(Path(primary)), store, paths, writer, _read_writers(store, _current(store)))


def write_files_atomically(contents: dict, primary=None, remove=(), whole: bool = False, writer: str | None = None) -> None:
    """Write ``{path: bytes}`` and remove the files ``remove`` names as one set: all or nothing.

    The generation commit of this module's docstring, under the set's lock: the new files
    written into a fresh generation, every file replaced or removed checked replaceable, the
    documented paths made links (once), and ``current`` swapped to the new generation by one
    rename. Any failure leaves every output as a reader saw it (a plain file of an older
    atlasgen may have become a link to the same bytes); a process killed at any instant leaves
    every output resolving into one generation, old or new.

    Parameters
    ----------
    contents
        ``{path: bytes}``.
    primary
        The path a build rule targets (a key of ``contents``); default: the last key. Its
        folder holds the set's store ``.<key>.atlasgen`` (:func:`store_path`).
    remove
        Paths that must not survive the commit (stale siblings); those absent are skipped.
    whole
        The files written are the whole set: the previous generation's other files are not carried
        over, and their links are removed (a report's images of materials it no longer shows).
    writer
        Who writes (``"render -o X.exr"``), where two commands share a set (:data:`WRITERS_SUFFIX`): a file
        another writer wrote is refused, and this writer's earlier files that it does not write again are
        not carried over. None: neither (the files written belong to no writer).

    Raises
    ------
    OutputError
        A folder cannot be created, a file cannot be written, a target cannot be replaced
        (nothing is then replaced), or another writer holds the set's lock past the timeout.
    """
    items = [(Path(p), data) for p, data in contents.items()]
    if not items:
        return
    if primary is not None:
        primary = Path(primary)
        if primary not in {p for p, _ in items}:
            raise ValueError(f"primary {primary} is not one of the files written")
    primary = Path(primary) if primary is not None else items[-1][0]
    written = {os.path.abspath(p) for p, _ in items}
    removals = [Path(p) for p in dict.fromkeys(os.path.abspath(p) for p in remove) if p not in written]
    for path, _ in items:
        refuse_inside_store(path)
    # Before the lock, which makes this set's store: refused under it only (as _commit does again, for a link
    # changed meanwhile), a path that is another set's link left an empty store behind on every command.
    refuse_another_sets([p for p, _ in items], primary, writer)
    home = _folder(primary)
    # The folders this commit makes, removed again (where still empty) if it fails: a report refused at its commit
    # left a new, empty images/ folder behind.
    created = _missing_folders([home, *(_folder(p) for p, _ in items)])
    try:
        try:
            home.mkdir(parents=True, exist_ok=True)
            for path, _ in items:
                _folder(path).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(f"{exc.filename or home.as_posix()}: cannot write output folder ({exc.strerror})") from None
        key = set_key(primary)
        with output_lock(home, key):
            store = home / f".{key}{STORE_SUFFIX}"
            _check_current(store, primary)
            _collect_garbage(home, store)
            _commit(home, store, primary, items, removals, whole, writer)
    except BaseException:
        _remove_empty(created)
        raise


def _missing_folders(folders) -> list[Path]:
    """Each of ``folders`` and its ancestors that do not exist yet, deepest first."""
    missing: dict[Path, None] = {}
    for folder in folders:
        at = Path(os.path.abspath(folder))
        while not os.path.lexists(at) and at != at.parent:
            missing[at] = None
            at = at.parent
    return sorted(missing, key=lambda p: len(p.parts), reverse=True)


def _remove_empty(folders) -> None:
    """Remove ``folders`` (deepest first) where they are empty; leave the rest."""
    for folder in folders:
        with contextlib.suppress(OSError):
            os.rmdir(folder)


def _commit(home: Path, store: Path, primary: Path, items: list, removals: list, whole: bool = False,
            writer: str | None = None) -> None:  # fmt: skip
    """Steps 1-6 of the module's docstring; the caller holds the lock."""
    names = {path: _stored_name(home, path) for path, _ in items}
    names.update({path: _stored_name(home, path) for path in removals})
    texts = {path: _link_text(store, stored, path) for path, stored in names.items()}
    current = _current(store)
    live = store / current if current else store  # the current generation (no names in it without one)
    old = set(_names(live)) if current else set()
    owners = _read_writers(store, current)
    _refuse_taken(home, store, [path for path, _ in items], writer, owners)  # again under the lock
    if whole:
        _refuse_others_files(home, store, old, writer, owners)
    # This writer's earlier files that it does not write now are stale: not carried over.
    own = {stored for stored, w in owners.items() if writer is not None and w == writer}
    # Each path: this set's link already, absent, or to be migrated (a plain file, another link).
    migrate, absent = [], []
    for path in names:
        if _is_link_to(path, texts[path]):
            if names[path] in old:
                _check_replaceable(path, live / names[path])
        elif not os.path.lexists(path):
            absent.append(path)
        elif path.is_dir() and not path.is_symlink():
            raise OutputError(f"{path.as_posix()}: cannot replace (Is a directory); nothing was replaced")
        else:
            _refuse_another_sets(path, store)
            migrate.append(path)
    absent = [path for path in absent if path not in removals]
    holding = None
    try:
        holding = _new_generation(store) if migrate else None  # numbered before the new generation
        gen = _new_generation(store)
    except OSError as exc:  # the store itself is read-only or marked immutable
        if holding is not None:
            shutil.rmtree(holding, ignore_errors=True)
        raise OutputError(f"{store.as_posix()}: cannot write ({exc.strerror}); nothing was replaced") from None
    done = False
    made: list[Path] = []
    try:
        for path, data in items:
            _step("write", path)
            remove_stale_temporaries(path)
            target = gen / names[path]
            try:
                target.parent.mkdir(parents=True, exist_ok=True)
                _write_file(target, data)
            except OSError as exc:
                raise OutputError(f"{path.as_posix()}: cannot write ({exc.strerror})") from None
        _fsync_tree(gen)
        if holding is not None:
            try:
                for stored in _linked(home, store, old):
                    _carry(live / stored, holding / stored)
                _write_writers(store, holding, owners)
            except OSError as exc:
                raise OutputError(f"{store.as_posix()}: cannot write ({exc.strerror}); nothing was replaced") from None
            for path in migrate:
                try:  # never a name carried above: those paths are this set's links
                    _hold(path, holding / names[path])
                except OSError as exc:
                    raise OutputError(f"{path.as_posix()}: cannot replace ({exc.strerror}); nothing was replaced") from None
            _fsync_tree(holding)
        fresh = {names[path] for path, _ in items}
        gone = {names[path] for path in removals}
        carried = set(_linked(home, store, set() if whole else old - fresh - gone - own))
        writers = {stored: w for stored, w in owners.items() if stored in carried}
        recorded = WHOLE_WRITER if whole and writer is None else writer
        writers.update({stored: recorded for stored in fresh} if recorded is not None else {})
        try:
            _write_writers(store, gen, writers)
        except OSError as exc:
            raise OutputError(f"{store.as_posix()}: cannot write ({exc.strerror}); nothing was replaced") from None
        with deferred_interrupts() as held:
            if holding is not None:
                _swap(store, holding, primary)
                current, old = holding.name, set(_names(holding))
                holding = None  # current now: not to be removed on failure
                for path in migrate:
                    _step("migrate", path)
                    try:
                        _link_into(path, texts[path])
                    except OSError as exc:
                        raise _unchanged(path, exc) from None
            try:
                for stored in sorted(carried):
                    _carry(live / stored, gen / stored)
            except OSError as exc:
                raise _unchanged(primary, exc) from None
            for path in absent:
                _step("link", path)
                try:
                    os.symlink(texts[path], path)
                except OSError as exc:
                    raise _unchanged(path, exc) from None
                made.append(path)
            for folder in dict.fromkeys(_folder(path) for path in names):
                _fsync_folder(folder)
            # A Ctrl-C or SIGTERM held so far stops the command here, before the swap: raised after it, the
            # command failed (exit 130, 143) with its new outputs in place. One that comes later is dropped:
            # the outputs are replaced, whole, and the command ends as it would have a moment later.
            held.raise_now()
            _swap(store, gen, primary)
            done = True
            _drop_links(home, store, sorted(old), set(_names(gen)))
            _collect_garbage(home, store, previous=current)  # a migration's extra generation
            held.drop()
    finally:
        if not done:
            for path in made:
                _discard(path)
            for leftover in (gen, holding):
                if leftover is not None:
                    shutil.rmtree(leftover, ignore_errors=True)
                    _discard(store / f"{leftover.name}{WRITERS_SUFFIX}")


def _linked(home: Path, store: Path, names) -> list[str]:
    """The ``names`` whose output path is still this set's link (a name whose link was removed
    or replaced by hand is not carried into the next generation)."""
    return [s for s in sorted(names) if _is_link_to(p := _target_path(home, s), _link_text(store, s, p))]


def _carry(source: Path, dest: Path) -> None:
    """A file of the current generation into the next, unchanged: a hard link (same bytes, same mtime)."""
    dest.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(source, dest, follow_symlinks=False)
    except OSError:  # an immutable file (or a copy across file systems): the same bytes, copied
        shutil.copy2(source, dest, follow_symlinks=False)


def _fsync_tree(folder: Path) -> None:
    for sub, _, _ in os.walk(folder):
        _fsync_folder(sub)


def write_file_atomically(path, data: bytes) -> None:
    """Atomically replace one plain file: a temporary beside it, flushed, renamed over it.

    A reader sees the old file or the new one, whole; a process killed first leaves a
    temporary that the next write of ``path`` removes.

    Raises
    ------
    OutputError
        The folder or the temporary cannot be written, or ``path`` cannot be replaced.
    """
    path = Path(path)
    folder = _folder(path)
    refuse_inside_store(path)
    refuse_set_link(path)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        remove_stale_temporaries(path)
        fd, made = tempfile.mkstemp(prefix=temp_prefix(path.name), suffix=TEMP_SUFFIX, dir=folder)
        tmp: str | None = made
    except OSError as exc:
        raise OutputError(f"{folder.as_posix()}: cannot write output folder ({exc.strerror})") from None
    try:
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
            os.chmod(made, 0o644)
        except OSError as exc:
            raise OutputError(f"{path.as_posix()}: cannot write ({exc.strerror})") from None
        try:
            os.replace(made, path)
        except OSError as exc:
            raise OutputError(f"{path.as_posix()}: cannot replace ({exc.strerror}); it was left as it was") from None
        tmp = None
        _fsync_folder(folder)
    finally:
        if tmp is not None:
            _discard(tmp)


@contextlib.contextmanager
def staged_folder(folder, primary=None, whole: bool = False):
    """A fresh temporary folder beside ``folder``, for a writer that is not atomic itself.

    On a clean exit every file written under it replaces its counterpart under
    ``folder`` in one all-or-nothing step (:func:`write_files_atomically`), ``primary``
    (a path relative to ``folder``, the file a build rule targets) naming the set; on an
    exception nothing under ``folder`` changes. The temporary folder is removed either
    way. Files already in ``folder`` that the writer did not produce are left alone, unless
    ``whole``: then the set's earlier files the writer did not produce are removed.

    Raises
    ------
    OutputError
        The temporary folder (beside ``folder``) or the outputs cannot be written.
    """
    folder = Path(folder)
    parent = folder.parent if str(folder.parent) else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        remove_stale_temporaries(folder)
        staging = Path(tempfile.mkdtemp(prefix=temp_prefix(folder.name), suffix=TEMP_SUFFIX, dir=parent))
    except OSError as exc:
        raise OutputError(f"{parent.as_posix()}: cannot write output folder ({exc.strerror})") from None
    try:
        yield staging
        files = {folder / p.relative_to(staging): p.read_bytes() for p in sorted(staging.rglob("*")) if p.is_file()}
        target = folder / primary if primary is not None and (folder / primary) in files else None
        write_files_atomically(files, primary=target, whole=whole)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


@contextlib.contextmanager
def scratch_folder(path):
    """A private folder beside ``path``, named as one of its temporaries, removed on exit.

    For encoders that can only write to a file of their own choosing (OpenImageIO picks
    the format from the extension): a run killed inside leaves a folder the next write of
    ``path`` recognises as stale and removes.

    Raises
    ------
    OutputError
        The folder cannot be created.
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        scratch = Path(tempfile.mkdtemp(prefix=temp_prefix(path.name), suffix=TEMP_SUFFIX, dir=parent))
    except OSError as exc:
        raise OutputError(f"{parent.as_posix()}: cannot write output folder ({exc.strerror})") from None
    try:
        yield scratch
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
