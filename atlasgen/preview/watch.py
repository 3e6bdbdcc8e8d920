"""``atlasgen preview --watch``: re-bake and re-render on every save, on a renderer that stays warm.

The folders holding the material files (and the files they name) are watched with watchfiles,
not the files themselves: editors that save by writing a new file and renaming it over the old
one (vim, most IDEs) replace the file a watch on it would follow, while the folder sees the
new one arrive. Events are kept only for the files the preview reads (a folder given as a
source: its material files, :func:`~atlasgen.materials.material.is_material_file_name`), so the
PNG's own writes, editors' swap files, lock links and backups never trigger an update. A batch of
events (watchfiles groups those STEP_MS apart) is one update. An update that fails (a bad edit)
reports its error on one line and leaves the last good picture in place; the watch goes on.
"""

from __future__ import annotations

import copy
import os
import stat
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from atlasgen.errors import AtlasgenError, BackendError
from atlasgen.interrupts import as_received
from atlasgen.io.atomic import write_file_atomically
from atlasgen.io.images import encode_png
from atlasgen.materials.material import is_material_file_name
from atlasgen.preview.label import error_text
from atlasgen.preview.previewer import (
    DEFAULT_CACHE_DIR,
    PNG_COMPRESSION,
    Preview,
    Previewer,
    check_preview_output,
    compose_picture,
)
from atlasgen.preview.reference import MAX_SPP, load_reference_mitsuba, refine_reference

__all__ = ["Update", "watch_preview", "describe_update", "describe_label"]

#: watchfiles' wait for further events before it reports a batch, ms: an editor's write and rename,
#: microseconds apart, land in one. watchfiles reports a batch after one quiet step, checking every
#: step, so noticing a save takes 1 to 2 steps (bench/preview.py's "noticing the save"); a shorter
#: step costs no measurable idle CPU. A save split by more than a step (a slow in-place write) shows
#: its first half's one-line error, and the next batch its picture.
STEP_MS = 5
#: How often the watch wakes with nothing to report, ms: to start, and to see ``stop`` without events.
IDLE_MS = 100
#: Most seconds the end of a watch waits for a reference thread to finish its pass (a pass at the cap's samples
#: takes seconds on the CPU); one still running after it is left, as a daemon.
REFERENCE_JOIN_S = 60.0


@dataclass
class Update:
    """One picture the watch made or failed to make."""

    #: The files whose change caused it, as the user named them; empty for the first picture.
    changed: list[str]
    #: The preview, or None when it failed (then ``error`` holds why).
    preview: Preview | None
    error: AtlasgenError | None = None
    #: The time of each step (:attr:`Preview.timings`) and ``total``, s.
    timings: dict = field(default_factory=dict)


def picture_kept(output) -> str:
    """What a failed update leaves at ``output``: the last picture, or none where the watch has drawn none yet (a
    material broken from the start said "kept the last picture" of a picture that did not exist, and of a folder or a
    link put in its place)."""
    return "kept the last picture" if os.path.isfile(output) and not os.path.islink(output) else "no picture yet"


def describe_update(update: Update, output, steps: bool = True) -> str:
    """The line printed for an update: what changed and how long the PNG took, e.g.
    ``materials/clay.toml changed: build/preview/clay.png in 0.412 s``, with ``steps`` followed by
    ``(read 0.001, bake 0.061, upload 0.009, ...)``; for a failed one, its error."""
    what = f"{', '.join(update.changed)} changed" if update.changed else "first picture"
    if update.preview is None:
        return f"{what}: {picture_kept(output)} ({update.error})"
    line = f"{what}: {Path(output).as_posix()} in {update.timings['total']:.3f} s"
    if not steps:
        return line
    detail = ", ".join(f"{k} {v:.3f}" for k, v in update.timings.items() if k != "total")
    return line + f" ({detail}{'; lighting shader compiled' if update.preview.compiled else ''})"


def describe_label(preview: Preview, error: AtlasgenError | None = None) -> str:
    """The line printed once a draft's picture has its error figures (:meth:`Previewer.complete`), e.g.
    ``gold: error: 1.92% +- 0.03% relative RMS of f cos (8-bit) (measured in 0.215 s)``; or why not."""
    if error is not None:
        return f"error figures: not measured, the picture keeps its label ({error})"
    shown = "; ".join(f"{shot.name}: {error_text(shot.entry) or 'exact'}" for shot in preview.shots)
    timing = f"measured in {sum(preview.label_timings.values()):.3f} s"
    return f"{shown} ({timing})" if shown else f"error figures {timing}"


def _folder_identity(folder: str) -> tuple | None:
    """The folder's device and inode, or None where no folder stands there."""
    try:
        st = os.stat(folder)
    except (OSError, ValueError):
        return None
    return (st.st_dev, st.st_ino) if stat.S_ISDIR(st.st_mode) else None


def _keys(path) -> list[str]:
    """The paths a save of ``path`` is reported at: its own, and where it is a symbolic link, its target's (an editor
    saves the target, in the target's folder: a watch of the link's folder saw nothing)."""
    own, real = os.path.abspath(path), os.path.realpath(path)
    return [own] if real == own else [own, real]


class _Sources:
    """The files a preview reads, by absolute path (and a link's target's), and the folders to watch for them."""

    def __init__(self, paths):
        self.given = [Path(p) for p in paths]
        self.folders_given = {os.path.abspath(p) for p in self.given if p.is_dir()}
        self.shown = {key: p.as_posix() for p in self.given if not p.is_dir() for key in _keys(p)}
        self.referenced: set[str] = set()

    def learn(self, preview: Preview) -> None:
        """Watch the files ``preview`` was made from too (a folder's materials, the files they name)."""
        for path in preview.inputs:
            for key in _keys(path):
                self.shown.setdefault(key, Path(path).as_posix())
                if path not in self.given and not is_material_file_name(Path(path).name):
                    self.referenced.add(key)

    def folders(self) -> list[str]:
        return sorted(self.folders_given | {os.path.dirname(k) for k in self.shown})

    def wants(self, path: str) -> bool:
        key = os.path.abspath(path)
        return key in self.shown or (os.path.dirname(key) in self.folders_given and is_material_file_name(os.path.basename(key)))

    def name(self, path: str) -> str:
        key = os.path.abspath(path)
        return self.shown.get(key) or os.path.relpath(key)


def watch_preview(
    paths,
    output,
    cache_dir=DEFAULT_CACHE_DIR,
    *,
    stop: threading.Event | None = None,
    max_updates: int | None = None,
    echo: Callable[[str], None] | None = None,
    on_update: Callable[[Update], None] | None = None,
    previewer: Previewer | None = None,
    reference: bool = False,
    max_spp: int | None = None,
    on_reference: Callable[[str, object], None] | None = None,
    on_label: Callable[[Preview, AtlasgenError | None], None] | None = None,
) -> int:
    """Write ``output``'s preview of ``paths``, then again on every change to what it reads, until stopped.

    Parameters
    ----------
    paths, output, cache_dir
        As :meth:`Previewer.write <atlasgen.preview.previewer.Previewer.write>`.
    stop
        Set it (from another thread) to end the watch; it ends within :data:`IDLE_MS` of it, or
        after the update under way.
    max_updates
        End after this many updates caused by changes (the first picture is not one).
    echo
        Called with one line per update (:func:`describe_update`); errors are lines too.
    on_update
        Called with each :class:`Update`, the first picture's included.
    previewer
        The warm state to use (a test's, a benchmark's); a new one on ``cache_dir`` by default.
    on_label
        Called once a picture drawn from a draft has its error figures, with the preview
        (``on_label(preview, None)``), or with the error that stopped them.
    reference, max_spp, on_reference
        Show each material's physical reference beside it (:mod:`atlasgen.preview.reference`). The atlas
        picture is written first, its reference labelled ``reference: rendering``; a background thread
        then renders the reference at low spp and refines it, each pass rewriting the PNG with the
        current atlas picture (``on_reference(name, shot)`` after each; ``on_reference(None, error)`` if
        it cannot render). An edit stops the thread's
        refinement (after the pass under way) and starts one for the new picture.

    Every picture is drawn first from a draft bake where a model has one (a separable material: the
    SVD and the choice of K, without the report sample's error figures,
    :meth:`~atlasgen.models.base.Model.bake_draft`), its label saying the error is being measured;
    then the figures are measured (:meth:`Previewer.complete <atlasgen.preview.previewer.Previewer.complete>`,
    which also fills the bake cache) and the PNG rewritten with the label a full bake gives, before
    the watch looks for the next change: a save made meanwhile waits for it.

    Returns the number of updates caused by changes. The output is checked before anything
    starts (:func:`~atlasgen.preview.previewer.check_preview_output`). Ctrl-C raises
    :class:`KeyboardInterrupt` out of the watch (between updates or in one: the PNG is
    replaced whole or not at all).
    """
    try:
        import watchfiles
    except ImportError:
        raise BackendError("--watch needs the Python package watchfiles (pip install 'atlasgen[render]')") from None

    check_preview_output(output, paths, cache_dir if previewer is None else None)  # one handed in (a test's) brings its own
    previewer = previewer or Previewer(cache_dir)
    stop = stop or threading.Event()
    sources = _Sources(paths)
    done, first = 0, True
    refiners: list[tuple[threading.Event, threading.Thread]] = []  # each reference thread still running, and its cancel
    drawn: Preview | None = None  # the picture at the output, whose references a failed update must not leave unrendered
    write_lock = threading.Lock()

    def refine(preview: Preview, cancel: threading.Event) -> None:
        references: dict = {}
        try:
            mi = load_reference_mitsuba()
            for shot in preview.shots:
                for ref in refine_reference(mi, shot.scene, shot.entry, preview.manifest, shot.radiance, shot.aovs or {},
                                            max_spp=max_spp or MAX_SPP, stop=cancel):  # fmt: skip
                    references[shot.name] = ref
                    png = encode_png(compose_picture(preview.shots, references), compression=PNG_COMPRESSION)
                    with write_lock:
                        if cancel.is_set():
                            return
                        write_file_atomically(output, png)
                    if on_reference is not None:
                        on_reference(shot.name, ref)
        except AtlasgenError as exc:  # no Mitsuba: said once, and the watch goes on without references
            if echo is not None:
                echo(f"reference: {exc}")
            if on_reference is not None:
                on_reference(None, exc)

    def update(changed: list[str], use_cache: bool = True) -> None:
        nonlocal drawn
        for cancel, _ in refiners:
            cancel.set()
        try:
            with write_lock:
                if reference:
                    # The atlas picture first, its references shown as rendering: the thread refines them.
                    check_preview_output(output, paths)
                    preview = previewer.preview(paths, use_cache, aovs=True, drafts=True, output=output)
                    preview.png = encode_png(compose_picture(preview.shots, {}), compression=PNG_COMPRESSION)
                    write_file_atomically(output, preview.png)
                else:
                    preview = previewer.write(paths, output, use_cache, drafts=True)
        except AtlasgenError as exc:
            result = Update(changed, None, exc)
            if reference and drawn is not None:
                # The references of the picture kept were cancelled above: it said "reference: rendering" for good.
                start_refining(drawn)
        else:
            sources.learn(preview)
            # A copy: the label's completion below rebinds the preview's fields, and a caller
            # reading this update from another thread must see the picture as it was reported.
            result = Update(changed, copy.copy(preview), None, {**preview.timings, "total": preview.seconds})
        if echo is not None:
            echo(describe_update(result, output))
        if on_update is not None:
            on_update(result)
        if result.preview is None:
            return
        if preview.pending:
            label_error = None
            try:
                with write_lock:
                    previewer.complete(preview, {} if reference else None)
                    write_file_atomically(output, preview.png)
            except AtlasgenError as exc:  # the picture stands; only its figures are missing
                label_error = exc
            if echo is not None:
                echo(describe_label(preview, label_error))
            if on_label is not None:
                on_label(preview, label_error)
        if reference:
            drawn = preview
            start_refining(preview)

    def start_refining(preview: Preview) -> None:
        cancel = threading.Event()
        thread = threading.Thread(target=refine, args=(preview, cancel), name="atlasgen-reference", daemon=True)
        refiners[:] = [(c, t) for c, t in refiners if t.is_alive()] + [(cancel, thread)]
        thread.start()

    try:
        revived: list[str] = []
        known: dict[str, tuple | None] = {}  # each folder as it stood when last watched
        while not stop.is_set():
            folders = sources.folders()
            # A folder removed (rm -rf, a checkout) takes its watch with it, and one that is not there cannot be
            # watched: each is watched while it stands, and the watch starts again where one goes or comes back (the
            # watch went silent for good after its folder was removed and made again). A folder made again is read
            # afresh: what it holds was saved unwatched.
            standing = {folder: _folder_identity(folder) for folder in folders}
            revived += [sources.name(f) for f in folders if f in known and standing[f] not in (None, known[f])]
            known.update(standing)
            watched = [folder for folder, identity in standing.items() if identity is not None]
            if not watched:
                if revived:  # no folder to watch, so no save to miss: said now
                    update(sorted(set(revived)), use_cache=False)
                    revived = []
                    done += 1
                    if max_updates is not None and done >= max_updates:
                        return done
                stop.wait(IDLE_MS / 1000)
                continue
            # A watched folder's own removal is reported too: one made again at once may take the same inode.
            folder_set = set(watched)
            changes = watchfiles.watch(*watched, watch_filter=lambda _, path: sources.wants(path) or path in folder_set,
                                       step=STEP_MS, stop_event=stop, rust_timeout=IDLE_MS, yield_on_timeout=True,
                                       recursive=False)  # fmt: skip
            try:
                for batch in changes:
                    removed = {path for _, path in batch if path in folder_set}
                    batch = {(change, path) for change, path in batch if path not in folder_set}
                    if first:
                        # The watch is running by now, so no save made while the first picture renders is lost.
                        first = False
                        update([])
                    elif batch or revived:
                        changed = sorted({sources.name(path) for _, path in batch} | set(revived))
                        # The bake cache's key is the material file alone: a file it names changed under it (or may
                        # have, in a folder made again while it was not watched).
                        update(changed, use_cache=not revived and not any(os.path.abspath(path) in sources.referenced
                                                                          for _, path in batch))  # fmt: skip
                        revived = []
                        done += 1
                        if max_updates is not None and done >= max_updates:
                            return done
                    if sources.folders() != folders:
                        break  # a material names a file in another folder now: watch that one too
                    now = {folder: _folder_identity(folder) for folder in standing}
                    if removed or now != standing:
                        # A folder found gone before its removal was reported (the watch ends with its events
                        # unread): its files are said to have changed, as the removal's events would have.
                        revived += [sources.name(f) for f, identity in now.items() if identity is None and f not in removed]
                        known.update(dict.fromkeys(removed))
                        break
            except KeyboardInterrupt as exc:
                # watchfiles' Rust wait checks for signals and raises a plain KeyboardInterrupt for any: a SIGTERM's
                # Terminated (exit 143) would have ended the watch as a Ctrl-C does, with success.
                received = as_received(exc)
                if received is exc:
                    raise
                raise received from None
            finally:
                changes.close()
    finally:
        # A reference thread still inside Mitsuba when the interpreter ends aborted the process (Ctrl-C or SIGTERM
        # ended it with "Fatal Python error: PyGILState_Release", exit 134): each is stopped at its next pass and
        # waited for.
        for cancel, _ in refiners:
            cancel.set()
        for _, thread in refiners:
            thread.join(REFERENCE_JOIN_S)
    return done
