"""All-or-nothing outputs: each output path is a link into ``.X.atlasgen/current``, and a commit
is one rename of that link, so a plain reader sees one generation at every instant; a process
killed at any step leaves the primary stale or the whole new set, and the next run tidies up."""

from __future__ import annotations

import errno
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from atlasgen.errors import InputError, OutputError
from atlasgen.io import atomic
from atlasgen.io.atlas import RERUN
from atlasgen.io.atomic import (
    TEMP_SUFFIX,
    WRITERS_SUFFIX,
    remove_stale_temporaries,
    store_path,
    write_file_atomically,
    write_files_atomically,
)
from atlasgen.render.atlas_texture import read_render_atlas
from tests.immutable import chattr
from tests.plain_reader import read_plainly

ROOT = Path(__file__).resolve().parents[1]
OUTPUTS = ("atlas.dds", "atlas.json", "atlas.wgsl", "atlas.glsl", "atlas.hlsl", "atlas.timings.json", "atlas-preview.png")
#: Outputs whose bytes depend only on the inputs (timings hold measured seconds).
DETERMINISTIC = ("atlas.dds", "atlas.json", "atlas.wgsl", "atlas.glsl", "atlas.hlsl", "atlas-preview.png")

#: Runs ``atlasgen`` with a commit hook that records each step and kills the process,
#: as SIGKILL would (no clean-up, no finally), at step ATLASGEN_TEST_KILL_AT.
KILLING_ATLASGEN = """\
import os, sys
kill_at = os.environ.get("ATLASGEN_TEST_KILL_AT")
if kill_at is not None and "--cache-only" not in sys.argv:
    from atlasgen.io import atomic
    steps = []
    def hook(step, path):
        steps.append((step, str(path)))
        if len(steps) - 1 == int(kill_at):
            os._exit(137)
    atomic.commit_hook = hook
from atlasgen.cli.main import main
main()
"""


@pytest.fixture
def record_steps(monkeypatch):
    steps = []
    monkeypatch.setattr(atomic, "commit_hook", lambda step, path: steps.append((step, Path(path).name)))
    return steps


def visible(folder: Path) -> dict:
    """Every path under ``folder`` outside the set stores, as a plain reader finds it: name -> bytes (None: dangling)."""
    found = {}
    for path in sorted(folder.rglob("*")):
        rel = path.relative_to(folder).as_posix()
        if rel.split("/")[0].endswith(atomic.STORE_SUFFIX) or (path.is_dir() and not path.is_symlink()):
            continue
        found[rel] = path.read_bytes() if path.exists() else None
    return found


def test_each_output_is_a_relative_link_into_the_current_generation(tmp_path, record_steps):
    files = {tmp_path / "a.json": b"j", tmp_path / "img" / "x.png": b"x", tmp_path / "a.dds": b"d"}
    write_files_atomically(files, primary=tmp_path / "a.dds")
    assert record_steps == [("write", "a.json"), ("write", "x.png"), ("write", "a.dds"),
                            ("link", "a.json"), ("link", "x.png"), ("link", "a.dds"), ("swap", "a.dds")]  # fmt: skip
    store = tmp_path / ".a.atlasgen"
    assert os.readlink(store / "current") == "gen-1"
    assert os.readlink(tmp_path / "a.dds") == ".a.atlasgen/current/a.dds"
    assert os.readlink(tmp_path / "img" / "x.png") == "../.a.atlasgen/current/img/x.png"
    assert visible(tmp_path) == {"a.dds": b"d", "a.json": b"j", "img/x.png": b"x"}
    assert sorted(os.listdir(store)) == ["current", "gen-1", "lock"]
    # The second commit swaps `current`, keeps one previous generation, and leaves the links alone.
    links = {p: os.lstat(p).st_ino for p in files}
    record_steps.clear()
    write_files_atomically({tmp_path / "a.dds": b"d2"})
    assert record_steps == [("write", "a.dds"), ("swap", "a.dds")]  # the links are made once
    assert os.readlink(store / "current") == "gen-2" and sorted(os.listdir(store)) == ["current", "gen-1", "gen-2", "lock"]
    assert visible(tmp_path) == {"a.dds": b"d2", "a.json": b"j", "img/x.png": b"x"}  # files not written stay
    assert {p: os.lstat(p).st_ino for p in files} == links
    write_files_atomically({tmp_path / "a.dds": b"d3"})
    assert sorted(os.listdir(store)) == ["current", "gen-2", "gen-3", "lock"]


def test_an_output_outside_the_primarys_folder_is_linked_too(tmp_path):
    build, elsewhere = tmp_path / "build", tmp_path / "previews" / "p.png"
    write_files_atomically({elsewhere: b"p", build / "a.dds": b"d"}, primary=build / "a.dds")
    assert os.readlink(elsewhere) == "../build/.a.atlasgen/current/@up1/previews/p.png"
    assert elsewhere.read_bytes() == b"p"
    write_files_atomically({build / "a.dds": b"d2"}, remove=[elsewhere])
    assert not os.path.lexists(elsewhere)


@pytest.mark.parametrize("inside", [".v.atlasgen/current", ".v.atlasgen", "linked", "linked/images"])
def test_an_output_inside_a_set_s_store_is_refused_before_anything_changes(tmp_path, inside):
    """-o into another set's generations wrote into a committed generation in place: the set's own link
    (v/report.json) changed without a commit."""
    folder = tmp_path / "v"
    write_files_atomically({folder / "images" / "a.png": b"a", folder / "report.json": b"{}"},
                           primary=folder / "report.json")  # fmt: skip
    (folder / "linked").symlink_to(".v.atlasgen/current")
    before = _snapshot(tmp_path)
    for write in (lambda p: write_files_atomically({p: b"other"}), lambda p: write_file_atomically(p, b"other")):
        with pytest.raises(OutputError) as info:
            write(folder / inside / "report.json")
        assert str(info.value).endswith(": inside .v.atlasgen, the generations of an output set; expected a path "
                                        "outside atlasgen's .*.atlasgen folders; nothing was replaced")  # fmt: skip
        assert _snapshot(tmp_path) == before and (folder / "report.json").read_bytes() == b"{}"


def test_a_whole_set_leaves_no_file_of_the_previous_one(tmp_path):
    """A report re-run for other materials kept the images of the ones it no longer shows."""
    folder = tmp_path / "v"
    write_files_atomically({folder / "images" / "a.png": b"a", folder / "report.json": b"1"}, primary=folder / "report.json")
    write_files_atomically({folder / "images" / "b.png": b"b", folder / "report.json": b"2"}, primary=folder / "report.json")
    assert (folder / "images" / "a.png").read_bytes() == b"a"  # by default a set keeps what it did not rewrite
    write_files_atomically({folder / "images" / "c.png": b"c", folder / "report.json": b"3"}, primary=folder / "report.json",
                           whole=True)  # fmt: skip
    assert sorted(p.name for p in (folder / "images").iterdir()) == ["c.png"]
    assert read_plainly(folder, ["report.json", "images/a.png"]) == {"report.json": b"3", "images/a.png": None}


def _snapshot(root: Path) -> dict:
    """Every path under ``root`` (links not followed) and what it holds: a link's text, a file's bytes."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            path = Path(dirpath) / name
            out[path] = os.readlink(path) if path.is_symlink() else path.read_bytes() if path.is_file() else None
    return out


def test_default_primary_is_the_last_file_given(tmp_path):
    write_files_atomically({tmp_path / "x": b"1", tmp_path / "y": b"2"})
    assert (tmp_path / ".y.atlasgen").is_dir()
    with pytest.raises(ValueError):
        write_files_atomically({tmp_path / "x": b"1"}, primary=tmp_path / "z")


def test_a_failed_write_leaves_every_output_and_no_temporary(tmp_path, monkeypatch):
    old = {"a": b"old a", "b": b"old b"}
    write_files_atomically({tmp_path / name: data for name, data in old.items()})

    def fail_on_second_write(step, path):
        if step == "write" and Path(path).name == "b":
            raise OSError("disk full")

    monkeypatch.setattr(atomic, "commit_hook", fail_on_second_write)
    with pytest.raises(OSError):
        write_files_atomically({tmp_path / "a": b"new a", tmp_path / "b": b"new b", tmp_path / "c": b"new c"},
                               primary=tmp_path / "b")  # the same set as the first write's  # fmt: skip
    assert visible(tmp_path) == old
    assert sorted(os.listdir(tmp_path / ".b.atlasgen")) == ["current", "gen-1", "lock"]


@pytest.mark.parametrize(("step", "stops"), [("link", True), ("swap", False), ("remove", False)])
def test_a_ctrl_c_during_the_commit_stops_it_before_the_swap_or_not_at_all(tmp_path, monkeypatch, step, stops):
    """Found by a kill sweep: a Ctrl-C or SIGTERM held while the commit ran was raised after the swap, so the command
    failed (exit 130, 143) with its new outputs in place. Held before the swap, it stops the commit there and the old
    set stays; one that comes later is dropped, and the new set is the command's result."""
    import signal

    old = {"a": b"old a", "b": b"old b", "d": b"old d"}
    write_files_atomically({tmp_path / name: data for name, data in old.items()}, primary=tmp_path / "b")
    new = {"a": b"new a", "b": b"new b", "c": b"new c"}  # 'c' is linked in the commit, 'd' removed after the swap

    def interrupt(at, path):
        if at == step:
            os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(atomic, "commit_hook", interrupt)
    write = lambda: write_files_atomically({tmp_path / n: d for n, d in new.items()}, primary=tmp_path / "b",  # noqa: E731
                                           remove=[tmp_path / "d"])  # fmt: skip
    if stops:
        with pytest.raises(KeyboardInterrupt):
            write()
        assert visible(tmp_path) == old
    else:
        write()
        assert visible(tmp_path) == new


def test_a_single_file_stays_a_plain_file_replaced_by_one_rename(tmp_path):
    target = tmp_path / "cache" / "entry.bin"
    write_file_atomically(target, b"one")
    write_file_atomically(target, b"two")
    assert not target.is_symlink() and target.read_bytes() == b"two"
    assert os.listdir(target.parent) == ["entry.bin"]


def _dead_pid() -> int:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_stale_temporaries_of_dead_runs_are_removed_and_live_ones_kept(tmp_path):
    target = tmp_path / "atlas.dds"
    dead = tmp_path / f".atlas.dds.{_dead_pid()}.k2j3{TEMP_SUFFIX}"
    dead_folder = tmp_path / f".atlas.dds.{_dead_pid()}.q9x1{TEMP_SUFFIX}"
    live = tmp_path / f".atlas.dds.{os.getpid()}.a8b1{TEMP_SUFFIX}"
    other = tmp_path / f".atlas.json.{_dead_pid()}.zz11{TEMP_SUFFIX}"  # another output's
    foreign = tmp_path / ".atlas.dds.12.tmp"  # not ours: another tool's name
    for path in (dead, live, other, foreign):
        path.write_bytes(b"partial")
    dead_folder.mkdir()
    (dead_folder / "image.png").write_bytes(b"partial")
    write_files_atomically({target: b"new"})
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [target.name, live.name, other.name, foreign.name, ".atlas.atlasgen"]
    )
    assert remove_stale_temporaries(tmp_path / "atlas.json") == [other]


def test_plain_files_of_an_older_atlasgen_become_links_to_the_same_bytes_first(tmp_path, record_steps):
    """The migration: a holding generation of the old files, then each file turned into its link,
    then the swap; at every step a plain reader reads the old set."""
    names = ("a.json", "a.glsl", "a.dds")
    for name in names:
        (tmp_path / name).write_bytes(f"old {name}".encode())
    (tmp_path / "user.dds").write_bytes(b"user's")
    os.symlink("user.dds", tmp_path / "a.wgsl")  # a link of someone else's: its target's bytes are what a reader sees
    old = read_plainly(tmp_path, (*names, "a.wgsl"))
    seen = []
    atomic.commit_hook = lambda step, path: (
        record_steps.append((step, Path(path).name)),
        seen.append(read_plainly(tmp_path, old)),
    )
    try:
        write_files_atomically({tmp_path / "a.json": b"new json", tmp_path / "a.wgsl": b"new wgsl", tmp_path / "a.dds": b"new dds"},
                               primary=tmp_path / "a.dds", remove=[tmp_path / "a.glsl"])  # fmt: skip
    finally:
        atomic.commit_hook = None
    assert [s for s, _ in record_steps] == ["write"] * 3 + ["swap"] + ["migrate"] * 4 + ["swap", "remove"]
    assert all(view == old for view in seen[:-1])  # every step up to the second swap: the old set
    assert read_plainly(tmp_path, old) == {"a.json": b"new json", "a.glsl": None, "a.dds": b"new dds", "a.wgsl": b"new wgsl"}
    assert not os.path.lexists(tmp_path / "a.glsl") and (tmp_path / "user.dds").read_bytes() == b"user's"


def test_a_path_of_another_output_set_is_refused_and_nothing_changes(tmp_path):
    """Two commands pointed at one folder (``report library -o out`` then ``validate -o out``) share
    index.html: the second took it over, and the first set's pages were left beside the second's index,
    a mixed folder. It is refused on one line naming the path, before anything is written; a path of
    the same set written through another folder's name is not."""
    out = tmp_path / "out"
    write_files_atomically({out / "index.html": b"library", out / "img" / "gold.png": b"png"}, primary=out / "index.html")
    before = read_plainly(out, ("index.html", "img/gold.png", "report.json"))
    with pytest.raises(OutputError) as caught:
        write_files_atomically({out / "index.html": b"validation", out / "report.json": b"{}"}, primary=out / "report.json")
    message = str(caught.value)
    assert message.startswith(f"{(out / 'index.html').as_posix()}: ") and ".index.atlasgen" in message and "\n" not in message
    assert read_plainly(out, before) == before and not os.path.lexists(out / "report.json")
    # Refused before the lock, which makes the set's store: a refusal under it left an empty store behind.
    assert not os.path.lexists(out / ".report.atlasgen")
    os.symlink("out", tmp_path / "alias")  # the same set, through a linked folder: its own link, rewritten
    write_files_atomically({tmp_path / "alias" / "index.html": b"library 2"}, primary=tmp_path / "alias" / "index.html")
    assert (out / "index.html").read_bytes() == b"library 2" and (out / "img" / "gold.png").read_bytes() == b"png"


def test_a_single_file_write_refuses_an_output_set_s_link(tmp_path):
    """`preview -o report/cost-vs-error.png` replaced the library report's link with a plain PNG (exit 0): the
    set's folder held one file of no generation. A plain file's write refuses any set's link, on one line; a
    user's own link, or a plain file, it replaces as before."""
    from atlasgen.io.atomic import write_file_atomically

    out = tmp_path / "out"
    write_files_atomically({out / "index.html": b"library", out / "chart.png": b"chart"}, primary=out / "index.html")
    before = read_plainly(out, ("index.html", "chart.png"))
    with pytest.raises(OutputError) as caught:
        write_file_atomically(out / "chart.png", b"preview")
    message = str(caught.value)
    assert message.startswith(f"{(out / 'chart.png').as_posix()}: already written by another command's outputs")
    assert read_plainly(out, before) == before and os.path.islink(out / "chart.png")
    (tmp_path / "mine.png").write_bytes(b"mine")
    os.symlink("mine.png", tmp_path / "link.png")
    write_file_atomically(tmp_path / "link.png", b"preview")
    write_file_atomically(tmp_path / "plain.png", b"preview")
    assert (tmp_path / "link.png").read_bytes() == (tmp_path / "plain.png").read_bytes() == b"preview"


def test_a_reader_holding_a_file_open_keeps_its_generation(tmp_path):
    write_files_atomically({tmp_path / "a.json": b"old json", tmp_path / "a.dds": b"old dds"})
    with open(tmp_path / "a.dds", "rb") as held:
        write_files_atomically({tmp_path / "a.json": b"new json", tmp_path / "a.dds": b"new dds"})
        write_files_atomically({tmp_path / "a.json": b"newer json", tmp_path / "a.dds": b"newer dds"})  # the old one collected
        assert held.read() == b"old dds"


def test_make_sees_a_new_mtime_and_a_copied_folder_still_reads(tmp_path):
    out = tmp_path / "out"
    write_files_atomically({out / "a.json": b"j", out / "img" / "x.png": b"x", out / "a.dds": b"d"})
    past = 1_700_000_000
    os.utime(out / "a.dds", (past, past))  # follows the link, as make's stat does
    write_files_atomically({out / "a.dds": b"d2"})
    assert os.stat(out / "a.dds").st_mtime > past + 1000
    shutil.copytree(out, tmp_path / "copy", symlinks=True)  # cp -r, rsync -a: links copied as links
    subprocess.run(["cp", "-r", str(out), str(tmp_path / "cp")], check=True)
    for copy in ("copy", "cp"):
        assert visible(tmp_path / copy) == {"a.dds": b"d2", "a.json": b"j", "img/x.png": b"x"}, copy
    shutil.rmtree(out)
    assert visible(tmp_path / "copy") == {"a.dds": b"d2", "a.json": b"j", "img/x.png": b"x"}  # relative: not into `out`


@pytest.mark.parametrize("current", ["a folder", "a link to 'elsewhere'"])
def test_a_store_whose_current_is_no_generation_link_is_refused_and_nothing_changes(tmp_path, current):
    """A hostile sweep's: after `cp -rL` made a folder of `current`, a commit read the store as holding no generation,
    removed every output's link and the generation, and then failed on the folder, saying "every output was left as
    it was"."""
    out = tmp_path / "out"
    write_files_atomically({out / "a.json": b"j", out / "a.dds": b"d"})
    store = store_path(out / "a.dds")
    link = store / "current"
    if current == "a folder":
        shutil.copytree(link, store / "copy")  # what cp -rL leaves: the generation's files in a folder of its name
        link.unlink()
        (store / "copy").rename(link)
    else:
        link.unlink()
        link.symlink_to("elsewhere")
    before = {p.relative_to(tmp_path).as_posix(): (p.is_symlink(), p.read_bytes() if p.is_file() else None)
              for p in tmp_path.rglob("*")}  # fmt: skip
    with pytest.raises(OutputError) as info:
        write_files_atomically({out / "a.json": b"j2", out / "a.dds": b"d2"})
    assert str(info.value).startswith(f"{link.as_posix()}: expected the link to the generation that a.dds's set reads "
                                      f"(gen-<n>), got {current}; nothing was changed")  # fmt: skip
    after = {p.relative_to(tmp_path).as_posix(): (p.is_symlink(), p.read_bytes() if p.is_file() else None)
             for p in tmp_path.rglob("*")}  # fmt: skip
    assert after == before


def _library(tmp_path: Path, colour: str) -> Path:
    folder = tmp_path / "materials"
    folder.mkdir(exist_ok=True)
    (folder / "clay.toml").write_text(f'type = "lambert"\ncolour = {colour}\n')
    (folder / "snow.toml").write_text('type = "lambert"\nid = 9\n')
    return folder


def _bake_command(library: Path, build: Path) -> list[str]:
    return [sys.executable, "-c", KILLING_ATLASGEN, "bake", str(library), "-o", str(build / "atlas.dds"),
            "--preview", str(build / "atlas-preview.png"), "-q"]  # fmt: skip


def _snapshot(build: Path) -> dict:
    return {name: (build / name).read_bytes() for name in OUTPUTS if (build / name).exists()}


def _leftovers(build: Path) -> list[str]:
    """Temporaries beside the outputs, and anything in the store but the lock, ``current`` and two generations (each
    with its record of writers, ``gen-<n>.writers``); a record whose generation is gone is a leftover too."""
    store = build / ".atlas.atlasgen"
    current = os.readlink(store / "current")
    extra = sorted(set(os.listdir(store)) - {"lock", "current", current, f"{current}{WRITERS_SUFFIX}"})
    previous = [name for name in extra if not name.endswith(WRITERS_SUFFIX)][:1]
    extra = [name for name in extra if name not in previous and name not in {f"{g}{WRITERS_SUFFIX}" for g in previous}]
    return [p.name for p in build.iterdir() if p.name.endswith(TEMP_SUFFIX)] + extra


#: The files a reader uses together: texture, manifest, include.
PAIRED = ("atlas.dds", "atlas.json", "atlas.wgsl")


def _read_as_the_renderer(build: Path, old: dict, new: dict) -> str:
    """What a reader makes of ``build`` now: ``"ok"`` only for the texture, manifest and
    include of one bake; otherwise a one-line refusal that says to re-run the bake."""
    try:
        read_render_atlas(build / "atlas.dds")
    except InputError as exc:
        assert "\n" not in str(exc) and str(exc).endswith(RERUN), str(exc)
        return "refused"
    now = [(build / name).read_bytes() for name in PAIRED]
    assert now in ([old[n] for n in PAIRED], [new[n] for n in PAIRED]), "a mismatched generation was accepted"
    return "ok"


def _restore(saved: Path, build: Path) -> None:
    shutil.rmtree(build)
    shutil.copytree(saved, build, symlinks=True)


@pytest.mark.slow
@pytest.mark.parametrize("before", ["links", "plain files"])
def test_a_bake_killed_at_each_step_leaves_one_generation_for_a_plain_reader(tmp_path, before):
    """``links``: the old set is a previous bake's; ``plain files``: an older atlasgen's, migrated first."""
    library = _library(tmp_path, "[0.2, 0.3, 0.4]")
    build, saved = tmp_path / "build", tmp_path / "saved"
    subprocess.run(_bake_command(library, build), check=True)
    old = _snapshot(build)
    if before == "plain files":
        shutil.rmtree(build)
        build.mkdir()
        for name, data in old.items():
            (build / name).write_bytes(data)
    shutil.copytree(build, saved, symlinks=True)
    _library(tmp_path, "[0.7, 0.5, 0.3]")
    reference = tmp_path / "reference"
    subprocess.run(_bake_command(library, reference), check=True)
    new = _snapshot(reference)
    assert old["atlas.dds"] != new["atlas.dds"] and old["atlas.json"] != new["atlas.json"]
    # Seven writes, then (plain files) the holding swap and seven migrations, then the swap.
    steps = len(OUTPUTS) + (1 + len(OUTPUTS) if before == "plain files" else 0) + 1
    for k in range(steps):
        killed = subprocess.run(_bake_command(library, build), env={**os.environ, "ATLASGEN_TEST_KILL_AT": str(k)},
                                capture_output=True)  # fmt: skip
        assert killed.returncode == 137, (k, killed.stderr)
        now = _snapshot(build)
        # Every file is whole and of one generation: the old one, since the swap is the last step.
        assert {name: now[name] for name in DETERMINISTIC} == {name: old[name] for name in DETERMINISTIC}, k
        assert _read_as_the_renderer(build, old, new) == "ok", k
        subprocess.run(_bake_command(library, build), check=True)  # finds what the kill left, and tidies it
        repaired = _snapshot(build)
        assert {n_: repaired[n_] for n_ in DETERMINISTIC} == {n_: new[n_] for n_ in DETERMINISTIC}, k
        assert _leftovers(build) == [], k
        _restore(saved, build)
    done = subprocess.run(_bake_command(library, build), env={**os.environ, "ATLASGEN_TEST_KILL_AT": str(steps)})
    assert done.returncode == 0  # there is no step after the swap
    assert {n_: (build / n_).read_bytes() for n_ in DETERMINISTIC} == {n_: new[n_] for n_ in DETERMINISTIC}


MAKE_ATLASGEN = "#!{python}\n" + KILLING_ATLASGEN
T0 = 1_700_000_000


def _make(root: Path, *args: str, kill_at: int | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "MAKEFLAGS": "", "MAKELEVEL": ""}
    if kill_at is not None:
        env["ATLASGEN_TEST_KILL_AT"] = str(kill_at)
    return subprocess.run(["make", "--no-print-directory", *args], cwd=root, env=env, capture_output=True, text=True,
                          timeout=120)  # fmt: skip


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("make") is None, reason="GNU make is not installed")
def test_make_atlas_reruns_a_bake_killed_at_any_step(tmp_path):
    """The real Makefile: after a kill, ``make -q atlas`` says out of date, and ``make atlas``
    leaves the files a clean bake writes."""
    root = tmp_path / "tree"
    root.mkdir()
    shutil.copy(ROOT / "Makefile", root)
    shutil.copytree(ROOT / "atlasgen", root / "atlasgen", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    (root / "pyproject.toml").write_text("")
    venv_bin = root / ".venv" / "bin"
    venv_bin.mkdir(parents=True)
    (venv_bin / "atlasgen").write_text(MAKE_ATLASGEN.format(python=sys.executable))
    (venv_bin / "atlasgen").chmod(0o755)
    (root / ".venv" / ".stamp").write_text("")
    library = _library(root, "[0.2, 0.3, 0.4]")
    build = root / "build"
    assert _make(root, "atlas").returncode == 0
    old = _snapshot(build)
    # Sources, then outputs, in the past; then an edit of a material: make must re-bake
    # it and re-assemble the atlas.
    for path in root.rglob("*"):
        if path.is_file():
            os.utime(path, (T0, T0))
    for path in [*build.rglob("*"), root / ".venv" / ".stamp"]:
        if path.exists():
            os.utime(path, (T0 + 100, T0 + 100))
    saved = tmp_path / "saved"
    shutil.copytree(build, saved, symlinks=True)
    (library / "clay.toml").write_text('type = "lambert"\ncolour = [0.7, 0.5, 0.3]\n')
    for k in (0, len(OUTPUTS) - 1, len(OUTPUTS)):  # first write, the DDS's write, the swap
        failed = _make(root, "atlas", kill_at=k)
        assert failed.returncode != 0, k
        assert _snapshot(build)["atlas.dds"] == old["atlas.dds"], k
        assert _make(root, "-q", "atlas").returncode == 1, k  # out of date: make will bake again
        _restore(saved, build)
    done = _make(root, "atlas")
    assert done.returncode == 0, done.stderr
    assert _make(root, "-q", "atlas").returncode == 0
    new = _snapshot(build)
    assert new["atlas.dds"] != old["atlas.dds"] and new["atlas.json"] != old["atlas.json"]
    assert _leftovers(build) == []
    manifest = (build / "atlas.json").read_text()
    assert '"colour": [0.7, 0.5, 0.3]' in manifest


# ---- checked before anything changes, nothing replaced on a failure, tidied after a kill, locked ----


def _three(folder: Path, tag: str) -> dict:
    return {folder / name: f"{tag} {name}".encode() for name in ("a.json", "a.wgsl", "a.dds")}


def _old_set(folder: Path, before: str) -> dict:
    """:func:`_three` "old" files in ``folder``, committed as this module's links or written as plain files."""
    old = _three(folder, "old")
    if before == "links":
        write_files_atomically(old, primary=folder / "a.dds")
    else:
        for path, data in old.items():
            path.write_bytes(data)
    return old


@pytest.mark.parametrize("before", ["links", "plain files"])
@pytest.mark.parametrize("stuck", ["a.json", "a.wgsl", "a.dds"])
def test_an_immutable_target_refuses_the_commit_before_anything_changes(tmp_path, stuck, before):
    old = _old_set(tmp_path, before)
    state = {p.name: (os.readlink(p) if p.is_symlink() else None) for p in old}
    if not chattr(tmp_path / stuck, "+i"):  # on a link: its file in the generation
        pytest.skip("chattr +i needs root and a file system with the immutable flag")
    try:
        with pytest.raises(OutputError, match=rf"{stuck}: cannot replace \(Operation not permitted\); nothing was replaced"):
            write_files_atomically(_three(tmp_path, "new"), primary=tmp_path / "a.dds")
    finally:
        chattr(tmp_path / stuck, "-i")
    assert visible(tmp_path) == {p.name: d for p, d in old.items()}
    assert {p.name: (os.readlink(p) if p.is_symlink() else None) for p in old} == state  # not even migrated
    assert sorted(os.listdir(tmp_path / ".a.atlasgen")) == (["current", "gen-1", "lock"] if before == "links" else ["lock"])


@pytest.mark.parametrize("before", ["links", "plain files"])
def test_a_store_that_cannot_take_a_generation_refuses_the_commit(tmp_path, monkeypatch, before):
    """The store read-only or marked immutable (``chattr +i``): one OutputError, nothing replaced."""
    old = _old_set(tmp_path, before)
    real_mkdir = Path.mkdir

    def mkdir(self, *args, **kwargs):
        if self.name.startswith("gen-"):
            raise PermissionError(errno.EPERM, os.strerror(errno.EPERM), str(self))
        return real_mkdir(self, *args, **kwargs)

    monkeypatch.setattr(Path, "mkdir", mkdir)
    with pytest.raises(OutputError, match=r"\.a\.atlasgen: cannot write \(Operation not permitted\); nothing was replaced"):
        write_files_atomically(_three(tmp_path, "new"), primary=tmp_path / "a.dds")
    assert visible(tmp_path) == {p.name: d for p, d in old.items()}


@pytest.mark.parametrize("before", ["links", "plain files"])
def test_a_rename_or_link_that_fails_leaves_what_a_reader_sees(tmp_path, monkeypatch, before):
    """Fail each rename or symlink of a commit in turn (the holding swap, a migration, a new name's link, the swap)."""
    new_names = ("a.json", "a.wgsl", "a.dds", "a.glsl")  # a.glsl did not exist
    for failing in range(100):
        folder = tmp_path / str(failing)
        folder.mkdir()
        old = _three(folder, "old")
        if before == "links":
            write_files_atomically(old, primary=folder / "a.dds")
        else:
            for path, data in old.items():
                path.write_bytes(data)
        (folder / "a.separable.bin").write_bytes(b"stale")  # a plain file in every case: migrated, then removed
        new = {**_three(folder, "new"), folder / "a.glsl": b"new a.glsl"}
        calls = []

        def failing_call(real):
            def call(*args, **kwargs):
                calls.append(args[1])
                if len(calls) == failing + 1:
                    raise OSError(5, "Input/output error")
                return real(*args, **kwargs)

            return call

        monkeypatch.setattr(atomic.os, "replace", failing_call(os.replace))
        monkeypatch.setattr(atomic.os, "symlink", failing_call(os.symlink))
        try:
            write_files_atomically(new, primary=folder / "a.dds", remove=[folder / "a.separable.bin"])
        except OutputError as exc:
            assert str(exc).endswith("cannot replace (Input/output error); every output was left as it was"), str(exc)
        else:
            break
        finally:
            monkeypatch.undo()
        assert visible(folder) == {p.name: d for p, d in old.items()} | {"a.separable.bin": b"stale"}, failing
        assert not [p for p in folder.iterdir() if p.name.endswith(TEMP_SUFFIX)], failing
        write_files_atomically(new, primary=folder / "a.dds", remove=[folder / "a.separable.bin"])
        assert visible(folder) == {p.name: d for p, d in new.items()}, failing
    assert visible(folder) == {name: f"new {name}".encode() for name in new_names}
    # Holding swap (2 calls), 1 + 3 migrations (2 each: none in the second case), a.glsl's link, the swap (2).
    assert failing == (2 + 2 * 4 + 1 + 2 if before == "plain files" else 2 + 2 + 1 + 2)


def test_a_commit_killed_after_its_swap_is_tidied_by_the_next(tmp_path):
    """The swap done, the stale links not yet removed: they resolve to nothing (absent to a
    reader), and the next commit removes them with the generation that held them."""
    write_files_atomically({tmp_path / "a.separable.bin": b"side", **_three(tmp_path, "old")}, primary=tmp_path / "a.dds")

    class Killed(BaseException):
        pass

    def hook(step, path):
        if step == "remove":
            raise Killed

    atomic.commit_hook = hook
    try:
        with pytest.raises(Killed):
            write_files_atomically(_three(tmp_path, "new"), primary=tmp_path / "a.dds", remove=[tmp_path / "a.separable.bin"])
    finally:
        atomic.commit_hook = None
    assert visible(tmp_path) == {**{p.name: d for p, d in _three(tmp_path, "new").items()}, "a.separable.bin": None}
    write_files_atomically({tmp_path / "a.dds": b"newer"})
    assert not os.path.lexists(tmp_path / "a.separable.bin")
    assert sorted(os.listdir(tmp_path / ".a.atlasgen")) == ["current", "gen-2", "gen-3", "lock"]


def test_a_killed_commits_generation_and_dangling_links_are_removed_by_the_next(tmp_path):
    write_files_atomically(_three(tmp_path, "old"), primary=tmp_path / "a.dds")

    class Killed(BaseException):
        pass

    def hook(step, path):
        if step == "swap":
            raise Killed

    atomic.commit_hook = hook
    real_rmtree, real_discard = atomic.shutil.rmtree, atomic._discard
    try:
        atomic.shutil.rmtree = atomic._discard = lambda *a, **k: None  # a kill runs no clean-up
        with pytest.raises(Killed):
            write_files_atomically({tmp_path / "a.glsl": b"new glsl", **_three(tmp_path, "new")}, primary=tmp_path / "a.dds")
    finally:
        atomic.commit_hook = None
        atomic.shutil.rmtree, atomic._discard = real_rmtree, real_discard
    assert visible(tmp_path) == {"a.glsl": None, **{p.name: d for p, d in _three(tmp_path, "old").items()}}
    write_files_atomically({tmp_path / "a.dds": b"newer"})
    assert not os.path.lexists(tmp_path / "a.glsl")
    assert sorted(os.listdir(tmp_path / ".a.atlasgen")) == ["current", "gen-1", "gen-2", "lock"]
    assert atomic._names(tmp_path / ".a.atlasgen" / "gen-2") == ["a.dds", "a.json", "a.wgsl"]  # the killed one's gone


def test_a_second_writer_waits_for_the_lock_then_refuses_with_one_line(tmp_path):
    with atomic.output_lock(tmp_path, "a") as lock:
        assert lock == tmp_path / ".a.atlasgen" / "lock"
        with pytest.raises(OutputError) as refused:
            with atomic.output_lock(tmp_path, "a", timeout=0.2):
                pass
        assert str(refused.value) == (f"{lock.as_posix()}: another atlasgen process is writing this output set "
                                      "(waited 0.2 s); expected one writer at a time")  # fmt: skip
        with atomic.output_lock(tmp_path, "b", timeout=0):  # another set's lock is free
            pass
    with atomic.output_lock(tmp_path, "a", timeout=0):
        pass


def test_removed_siblings_go_in_the_same_commit(tmp_path):
    write_files_atomically({tmp_path / "a.glsl": b"old", tmp_path / "a.dds": b"old"})
    (tmp_path / "a.ktx2").write_bytes(b"plain")
    write_files_atomically({tmp_path / "a.dds": b"new"}, remove=[tmp_path / "a.glsl", tmp_path / "a.ktx2", tmp_path / "gone"])
    assert visible(tmp_path) == {"a.dds": b"new"}


def test_an_immutable_file_the_commit_keeps_is_carried_as_a_copy(tmp_path):
    write_files_atomically({tmp_path / "a.hlsl": b"kept", tmp_path / "a.dds": b"old"})
    if not chattr(tmp_path / "a.hlsl", "+i"):
        pytest.skip("chattr +i needs root and a file system with the immutable flag")
    try:
        write_files_atomically({tmp_path / "a.dds": b"new"})
        write_files_atomically({tmp_path / "a.dds": b"newer"})  # gen-1's immutable file cannot be collected: it stays
    finally:
        chattr(tmp_path / ".a.atlasgen" / "gen-1" / "a.hlsl", "-i")
    assert visible(tmp_path) == {"a.dds": b"newer", "a.hlsl": b"kept"}


def test_a_writer_may_not_replace_another_writer_s_file_of_a_shared_set(tmp_path):
    """A scene's bake (X.dds, its depfile X.d) and render (X.exr, X.png) share the set .X.atlasgen: render --depfile
    X.d replaced the bake's depfile with its own, exit 0. Each commit that names its writer is refused another's."""
    bake = {tmp_path / "x.dds": b"atlas", tmp_path / "x.d": b"bake's rule"}
    write_files_atomically(bake, primary=tmp_path / "x.dds", writer="bake")
    with pytest.raises(OutputError) as info:
        write_files_atomically({tmp_path / "x.png": b"image", tmp_path / "x.d": b"render's rule"}, primary=tmp_path / "x.png",
                               writer="render")  # fmt: skip
    assert str(info.value) == (f"{(tmp_path / 'x.d').as_posix()}: already written by `atlasgen bake` into the same "
                               "output set (.x.atlasgen); expected a name of its own; nothing was replaced")  # fmt: skip
    assert (tmp_path / "x.d").read_bytes() == b"bake's rule" and not (tmp_path / "x.png").exists()
    # Its own names are the render's to write; the bake's files stay as they were, beside them.
    write_files_atomically({tmp_path / "x.png": b"image", tmp_path / "x.png.d": b"render's rule"}, primary=tmp_path / "x.png",
                           writer="render")  # fmt: skip
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if not p.name.startswith(".")} == {
        "x.dds": b"atlas", "x.d": b"bake's rule", "x.png": b"image", "x.png.d": b"render's rule"}  # fmt: skip


def test_a_set_replaced_whole_keeps_another_writer_s_files_by_refusing(tmp_path):
    """A hostile sweep: `report library -o ix` (index.html, a report's set replaced whole) into a folder holding a bake's
    ix/index.dds (the same key, index) removed the atlas and its side files, exit 0. Both the check before the work
    and the commit refuse it; files no writer named (the report's own earlier ones) are still dropped."""
    from atlasgen.io.atomic import refuse_other_writers

    write_files_atomically({tmp_path / "index.dds": b"atlas", tmp_path / "index.json": b"{}"}, primary=tmp_path / "index.dds",
                           writer="bake -o index.dds/.ktx2")  # fmt: skip
    expected = (f"{(tmp_path / 'index.dds').as_posix()}: written by `atlasgen bake -o index.dds/.ktx2` into the output set "
                "(.index.atlasgen) this command replaces whole; expected a folder of its own for each command's outputs; "
                "nothing was replaced")  # fmt: skip
    with pytest.raises(OutputError) as early:
        refuse_other_writers(tmp_path / "index.html")
    with pytest.raises(OutputError) as late:
        write_files_atomically({tmp_path / "index.html": b"page"}, primary=tmp_path / "index.html", whole=True)
    assert str(early.value) == str(late.value) == expected
    assert visible(tmp_path) == {"index.dds": b"atlas", "index.json": b"{}"}
    other = tmp_path / "other"
    write_files_atomically({other / "index.html": b"one", other / "a.png": b"img"}, primary=other / "index.html", whole=True)
    refuse_other_writers(other / "index.html")
    write_files_atomically({other / "index.html": b"two"}, primary=other / "index.html", whole=True)
    assert visible(other) == {"index.html": b"two"}


def test_a_writer_s_earlier_file_that_it_no_longer_writes_leaves_the_set(tmp_path):
    """A render with --depfile, then one without: the first one's depfile stayed beside an image that no longer read
    what it named. A writer's own earlier files are not carried over; another writer's, and files no writer named
    (an older atlasgen's), are."""
    write_files_atomically({tmp_path / "x.dds": b"atlas"}, primary=tmp_path / "x.dds", writer="bake")
    write_files_atomically({tmp_path / "x.old": b"unnamed"}, primary=tmp_path / "x.old")
    write_files_atomically({tmp_path / "x.png": b"one", tmp_path / "x.png.d": b"rule"}, primary=tmp_path / "x.png",
                           writer="render")  # fmt: skip
    write_files_atomically({tmp_path / "x.png": b"two"}, primary=tmp_path / "x.png", writer="render")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if not p.name.startswith(".")} == {
        "x.dds": b"atlas", "x.old": b"unnamed", "x.png": b"two"}  # fmt: skip
    assert not os.path.lexists(tmp_path / "x.png.d")


def test_a_file_in_the_store_s_place_is_named_with_what_was_expected(tmp_path):
    """A hostile sweep: a file named .o.atlasgen beside -o o.exr gave "lock: cannot open the output set's lock file
    (File exists)", naming neither the file in the way nor what was expected."""
    (tmp_path / ".o.atlasgen").write_text("mine")
    with pytest.raises(OutputError) as info:
        write_files_atomically({tmp_path / "o.exr": b"image"})
    assert str(info.value) == (f"{(tmp_path / '.o.atlasgen').as_posix()}: expected the folder atlasgen keeps this output "
                               "set's files in, got a file; move it away (the name is atlasgen's)")  # fmt: skip
    assert sorted(p.name for p in tmp_path.iterdir()) == [".o.atlasgen"] and (tmp_path / ".o.atlasgen").read_text() == "mine"


def test_a_named_writer_may_not_share_a_set_a_report_replaces_whole(tmp_path):
    """A hostile sweep: `bake -o L1/index.dds` beside `report library -o L1` committed into the page's set (exit 0), and
    the report's next run was refused. A whole commit records its files as a report's; a named writer is refused
    them, before its work and at its commit, and the report replaces its own set again."""
    from atlasgen.io.atomic import WHOLE_WRITER, refuse_another_sets

    page = {tmp_path / "index.html": b"page", tmp_path / "slices" / "a.png": b"img"}
    write_files_atomically(page, primary=tmp_path / "index.html", whole=True)
    expected = (f"{(tmp_path / 'index.html').as_posix()}: written by a report into the output set (.index.atlasgen) it "
                "replaces whole; expected a folder of its own for each command's outputs; nothing was replaced")  # fmt: skip
    with pytest.raises(OutputError) as early:
        refuse_another_sets([tmp_path / "index.dds"], tmp_path / "index.dds", "bake")
    with pytest.raises(OutputError) as late:
        write_files_atomically({tmp_path / "index.dds": b"atlas"}, primary=tmp_path / "index.dds", writer="bake")
    assert str(early.value) == str(late.value) == expected
    assert visible(tmp_path) == {"index.html": b"page", "slices/a.png": b"img"}
    write_files_atomically({tmp_path / "index.html": b"page 2"}, primary=tmp_path / "index.html", whole=True)
    assert visible(tmp_path) == {"index.html": b"page 2"}
    store = tmp_path / ".index.atlasgen"
    record = store / f"{os.readlink(store / 'current')}{WRITERS_SUFFIX}"
    assert json.loads(record.read_text()) == {"index.html": WHOLE_WRITER}


def test_a_failed_commit_removes_the_folders_it_made(tmp_path):
    """A hostile sweep: a validation report refused at its commit (index.html was a folder) left a new, empty images/
    folder in the report folder. The folders a commit makes go again when it fails; those that were there stay."""
    (tmp_path / "index.html").mkdir()
    with pytest.raises(OutputError, match="cannot replace"):
        write_files_atomically({tmp_path / "images" / "deep" / "a.png": b"img", tmp_path / "index.html": b"page"},
                               primary=tmp_path / "index.html", whole=True)  # fmt: skip
    assert not (tmp_path / "images").exists() and (tmp_path / "index.html").is_dir()
