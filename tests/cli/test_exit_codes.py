"""Every documented exit status is reached, each with one line on stderr and no traceback
(unless asked for); the table in docs/cli.md is generated from the same list."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from atlasgen.cli.main import app
from atlasgen.errors import EXIT_CODES, Terminated
from tests.terminal import as_in_a_terminal


@pytest.fixture
def library(write_material, tmp_path):
    write_material("clay", 'type = "lambert"\n')
    return tmp_path / "materials"


def _boom(*args, **kwargs):
    raise ZeroDivisionError("a bug\nover two lines")


def _interrupt(*args, **kwargs):
    raise KeyboardInterrupt


def _terminate(*args, **kwargs):
    raise Terminated  # what atlasgen.interrupts.raise_terminated raises on SIGTERM


def _run(tmp_path, library, monkeypatch, code):
    """Reach exit status ``code`` through the CLI; return the click result."""
    out = str(tmp_path / "a.dds")
    args = ["bake", str(library), "-o", out]
    if code == 1:
        monkeypatch.setattr("atlasgen.cli.main.bake_atlas", _boom)
    elif code == 2:
        args = ["bake", str(library), "--layout", "spiral"]
    elif code == 3:
        (library / "bad.toml").write_text('type = "lambert"\ncolour = [2, 0, 0]\n')
    elif code == 4:  # an output folder that is a file (a wrong extension is a usage error, 2)
        (tmp_path / "a-file").write_text("not a folder")
        args = ["bake", str(library), "-o", str(tmp_path / "a-file" / "a.dds")]
    elif code == 5:
        from atlasgen.errors import BackendError

        def no_adapter(*a, **k):
            raise BackendError("no WebGPU adapter")

        monkeypatch.setattr("atlasgen.render.renderer.get_device", no_adapter)
        (tmp_path / "s.toml").write_text("[camera]\nposition = [0, 0, 5]\ntarget = [0, 0, 0]\n")
        assert CliRunner().invoke(app, args).exit_code == 0
        args = ["render", str(tmp_path / "s.toml"), "--atlas", out, "-o", str(tmp_path / "r.exr")]
    elif code == 6:
        # The merge of earlier runs, here a stand-in whose report misses a goal; the real
        # strict runs are in tests/cli/test_validate_cmd.py (they need Mitsuba).
        written = {"data": {"materials": []}, "html": str(tmp_path / "v" / "index.html")}
        monkeypatch.setattr("atlasgen.cli.validate_cmd.merge_validation_reports", lambda *a, **k: written)
        monkeypatch.setattr("atlasgen.cli.validate_cmd.describe_materials", lambda data: [])
        monkeypatch.setattr("atlasgen.cli.validate_cmd.summary_line", lambda data, html: "summary")
        monkeypatch.setattr("atlasgen.cli.validate_cmd.missed_goals", lambda data: ["clay: PSNR 40 dB < 45 dB"])
        args = ["validate", "--merge", str(tmp_path), "-o", str(tmp_path / "v"), "--strict"]
    elif code == 7:
        # A material that warns; the real ones (Mitsuba-backed) are in tests/cli/test_bake_warnings.py.
        from atlasgen.bake.quality import MaterialWarning

        warning = MaterialWarning("clay.toml", "clay", "unreachable fit", 0.5, "relative RMS error 50.0% of its fit > 20%")
        monkeypatch.setattr("atlasgen.bake.pipeline.assess_material", lambda material, extra: [warning])
        args = ["bake", str(library), "-o", out, "--strict"]
    elif code == 130:
        monkeypatch.setattr("atlasgen.cli.main.read_materials", _interrupt)
    elif code == 143:
        monkeypatch.setattr("atlasgen.cli.main.read_materials", _terminate)
    return CliRunner().invoke(app, args)


@pytest.mark.parametrize("code", [code for code, _ in EXIT_CODES])
def test_every_documented_exit_code_is_reached_with_one_line(tmp_path, library, monkeypatch, code):
    res = _run(tmp_path, library, monkeypatch, code)
    assert res.exit_code == code, res.output
    lines = res.stderr.splitlines()
    assert "Traceback" not in res.stderr
    if code == 0:
        assert lines == []
        return
    assert len(lines) == 1, res.stderr
    expected = {1: "atlasgen: internal error (ZeroDivisionError: a bug; over two lines); this is a bug",
                130: "atlasgen: interrupted", 143: "atlasgen: terminated"}.get(code, "atlasgen: error: ")  # fmt: skip
    assert lines[0].startswith(expected), lines[0]


@pytest.mark.parametrize(("interrupt", "code", "line"), [(KeyboardInterrupt, 130, "atlasgen: interrupted"),
                                                         (Terminated, 143, "atlasgen: terminated")])  # fmt: skip
def test_an_interrupt_a_library_wraps_in_its_own_error_is_still_the_interrupt(tmp_path, library, monkeypatch, interrupt,
                                                                              code, line):  # fmt: skip
    """Dr.Jit raises a Ctrl-C or SIGTERM that lands in a Python callback (a Mitsuba BSDF, mid-render) as a RuntimeError
    from it: ``validate`` interrupted there ended "internal error ... this is a bug", exit 1 (a kill sweep, about one
    try in 12 between 2 and 3.6 s)."""

    def wrapped(*args, **kwargs):
        try:
            raise interrupt
        except KeyboardInterrupt as exc:
            raise RuntimeError("drjit.custom(<mitsuba.python.util._RenderOp>): error while performing a custom "
                               "differentiable operation. (see above).") from exc  # fmt: skip

    monkeypatch.setattr("atlasgen.cli.main.bake_atlas", wrapped)
    res = CliRunner().invoke(app, ["bake", str(library), "-o", str(tmp_path / "a.dds")])
    assert (res.exit_code, res.stderr.splitlines()) == (code, [line]), res.stderr


def test_debug_shows_the_traceback_of_an_internal_error(tmp_path, library, monkeypatch):
    monkeypatch.setattr("atlasgen.cli.main.bake_atlas", _boom)
    args = ["bake", str(library), "-o", str(tmp_path / "a.dds")]
    for extra, env in ((["--debug"], {}), ([], {"ATLASGEN_DEBUG": "1"})):
        res = CliRunner(env=env).invoke(app, extra + args)
        assert res.exit_code == 1
        assert "Traceback (most recent call last)" in res.stderr and "ZeroDivisionError: a bug" in res.stderr
        assert res.stderr.splitlines()[-1].startswith("atlasgen: internal error (ZeroDivisionError")
    res = CliRunner(env={"ATLASGEN_DEBUG": "0"}).invoke(app, args)
    assert res.exit_code == 1 and "Traceback" not in res.stderr


def test_the_exit_code_table_is_generated_from_errors():
    from atlasgen.cli.docgen import render_exit_codes

    table = render_exit_codes()
    for code, meaning in EXIT_CODES:
        assert f"| {code} | {meaning} |" in table


@pytest.mark.slow
def test_usage_errors_outside_a_command_are_one_line():
    code = "from atlasgen.cli.main import main; main(['--no-such-option'])"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 2
    assert result.stderr.splitlines() == ["atlasgen: error: No such option '--no-such-option'. (see 'atlasgen --help')"]


@pytest.mark.slow
@pytest.mark.mitsuba
@pytest.mark.parametrize("delay", [0.3, 0.5, 0.7, 0.9, 1.2])
def test_ctrl_c_while_mitsuba_starts_is_an_interruption(tmp_path, mitsuba_llvm, delay):
    """SIGINT at several moments of a Mitsuba-backed bake (Mitsuba's import, its LLVM
    start-up, the bake): exit 130 and one line, never a "variant unavailable" backend
    error, an internal error or a crash, whichever moment it lands at."""
    folder = tmp_path / "m"
    folder.mkdir()
    for i in range(1, 8):  # seconds of baking: the signal lands before the end
        (folder / f"metal{i}.toml").write_text('type = "separable"\nsource = "mitsuba"\nterms = 8\n'
                                              f'bsdf = {{ type = "roughconductor", alpha = 0.{i} }}\n')  # fmt: skip
    code = ("import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler)\n"
            "print('started', flush=True)\n"
            "from atlasgen.cli.main import main\n"
            f"main(['bake', {str(folder)!r}, '-o', {str(tmp_path / 'a.dds')!r}, '-q'])\n")  # fmt: skip
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=os.environ)  # fmt: skip
    # The delay counts from the child's first line of code: counted from its start, a loaded machine landed the
    # signal in Python's own start-up (importing site), before any code of atlasgen's runs.
    assert child.stdout.readline() == "started\n"
    time.sleep(delay)  # where the signal lands; the outcome must not depend on it
    child.send_signal(signal.SIGINT)
    _, stderr = child.communicate(timeout=300)
    if child.returncode == 0:  # after the bake's end
        pytest.skip(f"the signal missed the bake (exit {child.returncode})")
    assert child.returncode == 130, stderr
    assert stderr.splitlines() == ["atlasgen: interrupted"], stderr


def _signal_while_finding(module: str, signum: int) -> str:
    """Code that sends ``signum`` to its own process at the instant Python looks ``module`` up (a finder put
    first on ``sys.meta_path``): a signal landing at one exact instant of start-up, every time."""
    return f"""
import os, sys

class SignalWhileFinding:
    def find_spec(self, name, path=None, target=None):
        if name == {module!r}:
            os.kill(os.getpid(), {int(signum)})
        return None

sys.meta_path.insert(0, SignalWhileFinding())
"""


@pytest.mark.parametrize("entry", ["import runpy; runpy._run_module_as_main('atlasgen')", "import atlasgen.cli"],
                         ids=["python -m atlasgen", "the installed script"])  # fmt: skip
def test_ctrl_c_while_the_start_up_handler_is_imported_is_one_line(entry):
    """CI's stop 43: a SIGINT 20 ms into ``python -m atlasgen`` landed while start_up.py itself
    was found and read, and printed a traceback through atlasgen/__main__.py. Landing there
    (made certain by a finder that sends it) is one line and 130, by either way in."""
    # Ctrl-C at the instant Python looks for start_up.py: the one instant no handler can cover.
    child = subprocess.run([sys.executable, "-c", _signal_while_finding("atlasgen.start_up", signal.SIGINT) + entry],
                           stderr=subprocess.PIPE, text=True, preexec_fn=as_in_a_terminal, timeout=60)  # fmt: skip
    assert (child.returncode, child.stderr.splitlines()) == (130, ["atlasgen: interrupted"]), child.stderr


@pytest.mark.parametrize("entry", ["import runpy; runpy._run_module_as_main('atlasgen')",
                                   "import atlasgen.cli.main as m; m.main()"],
                         ids=["python -m atlasgen", "the installed script"])  # fmt: skip
def test_sigterm_during_start_up_is_one_line_and_143(entry):
    """Python's own SIGTERM ends a process silently; atlasgen's start-up says why it ended, as for Ctrl-C."""
    # SIGTERM (a `kill`) while the command line imports click: after the start-up handler, before the library.
    child = subprocess.run([sys.executable, "-c", _signal_while_finding("click", signal.SIGTERM) + entry, "--help"],
                           capture_output=True, text=True, timeout=60)  # fmt: skip
    assert (child.returncode, child.stderr.splitlines(), child.stdout) == (143, ["atlasgen: terminated"], ""), child.stderr


@pytest.mark.parametrize(("signum", "status", "line"), [(signal.SIGINT, 130, "atlasgen: interrupted"),
                                                        (signal.SIGTERM, 143, "atlasgen: terminated")],
                         ids=["Ctrl-C", "SIGTERM"])  # fmt: skip
def test_a_signal_while_the_top_level_arguments_are_parsed_is_one_line(signum, status, line):
    """The suite's start-up sweep once read an empty line before 'atlasgen: interrupted': click's own main
    catches a KeyboardInterrupt raised while it parses the top level's arguments, outside the commands'
    guard, and echoes a newline before its Abort. Here the signal is made to land there."""
    code = ("import os, click\n"
            "parse = click.Group.parse_args\n"
            "def landing(self, ctx, args):\n"
            f"    os.kill(os.getpid(), {int(signum)})\n"
            "    return parse(self, ctx, args)\n"
            "click.Group.parse_args = landing\n"
            "import runpy, sys; sys.argv = ['atlasgen', '--help']; runpy._run_module_as_main('atlasgen')\n")  # fmt: skip
    child = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, preexec_fn=as_in_a_terminal,
                           timeout=60)  # fmt: skip
    assert (child.returncode, child.stderr, child.stdout) == (status, line + "\n", ""), child.stderr


@pytest.mark.slow
def test_sigterm_during_a_command_is_one_line_and_143_and_leaves_the_old_atlas(tmp_path):
    """Once the command runs, SIGTERM is raised as :class:`~atlasgen.errors.Terminated` (its clean-up runs);
    a bake of a slow material killed in its fit leaves the old set whole."""
    pytest.importorskip("MaterialX")
    pytest.importorskip("moderngl")
    showcase = Path(__file__).resolve().parents[2] / "materials" / "materialx-showcase.mtlx"
    out = tmp_path / "build" / "atlas.dds"
    (tmp_path / "clay.toml").write_text('type = "lambert"\n')
    assert (
        subprocess.run([sys.executable, "-m", "atlasgen", "bake", str(tmp_path / "clay.toml"), "-o", str(out), "-q"]).returncode
        == 0
    )
    old = {p.name: p.read_bytes() for p in out.parent.iterdir() if p.is_file()}
    child = subprocess.Popen([sys.executable, "-m", "atlasgen", "bake", str(showcase), "-o", str(out), "-j", "1", "-q"],
                             stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        time.sleep(3.0)  # inside the first material's fit (the four take 10 s or more)
        child.send_signal(signal.SIGTERM)
        _, stderr = child.communicate(timeout=120)
    finally:
        child.kill()
    assert (child.returncode, stderr) == (143, "atlasgen: terminated\n"), stderr
    assert {p.name: p.read_bytes() for p in out.parent.iterdir() if p.is_file()} == old


def _frames_in(stderr: str, roots) -> list[str]:
    return [line for line in stderr.splitlines() if line.strip().startswith("File ") and any(str(r) in line for r in roots)]


@pytest.mark.slow
def test_ctrl_c_at_any_instant_of_start_up_is_one_line_and_130(tmp_path):
    """Issue 24: Ctrl-C in the first second printed a 19-26-line traceback from cli/main.py's
    imports. SIGINT at many delays from the process's start: once atlasgen's first module
    runs (atlasgen/cli/__init__.py, before click, NumPy or the library), one line and 130.
    Before it, in Python's own start-up (site and its .pth files), Python decides; such a
    landing is counted apart, and none of its frames may be atlasgen's."""
    import atlasgen
    from atlasgen.io.atlas import read_atlas

    package = Path(atlasgen.__file__).parent
    roots = (package, package.parent / "cli")
    folder = tmp_path / "m"
    folder.mkdir()
    (folder / "clay.toml").write_text('type = "lambert"\n')
    out = tmp_path / "build" / "atlas.dds"
    started = time.perf_counter()
    assert subprocess.run([sys.executable, "-m", "atlasgen", "bake", str(folder), "-o", str(out), "-q"]).returncode == 0
    whole = time.perf_counter() - started
    old = {p.name: p.read_bytes() for p in out.parent.iterdir() if p.is_file()}  # through the outputs' links
    (folder / "clay.toml").write_text('type = "lambert"\ncolour = [0.1, 0.2, 0.3]\n')
    outcomes = {}
    # Spread over the whole run as this machine takes it (a fixed list ran past a fast machine's bake).
    for delay in (0.02, *(round(whole * f, 3) for f in (0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.75, 0.9))):
        child = subprocess.Popen([sys.executable, "-m", "atlasgen", "bake", str(folder), "-o", str(out), "-q"],
                                 stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"},
                                 preexec_fn=as_in_a_terminal)  # fmt: skip
        time.sleep(delay)
        child.send_signal(signal.SIGINT)
        _, stderr = child.communicate(timeout=120)
        assert not _frames_in(stderr, roots), (delay, stderr)
        if child.returncode == 130:
            assert stderr.splitlines() == ["atlasgen: interrupted"], (delay, stderr)
            outcomes[delay] = "atlasgen"
        elif child.returncode == 0:
            outcomes[delay] = "done"
        else:  # before atlasgen's first line: killed by the signal, or site's KeyboardInterrupt
            assert child.returncode in (-signal.SIGINT, 1) and "atlasgen:" not in stderr, (delay, child.returncode, stderr)
            outcomes[delay] = "python start-up"
        read_atlas(out)  # whole: the old set or the new one, never a mix
        now = {p.name: p.read_bytes() for p in out.parent.iterdir() if p.is_file()}
        if child.returncode != 0:  # untouched, or (Ctrl-C held during the renames) the whole new set
            assert now == old or (sorted(now) == sorted(old) and now["atlas.json"] != old["atlas.json"]), delay
        for name, data in old.items():
            (out.parent / name).write_bytes(data)
    assert list(outcomes.values()).count("atlasgen") >= 3, outcomes


LATE_CTRL_C = """
import atexit, os, runpy, signal, sys
atexit.register(lambda: os.kill(os.getpid(), signal.SIGINT))  # a Ctrl-C as the interpreter shuts down
sys.argv = ["atlasgen", *sys.argv[1:]]
runpy.run_module("atlasgen", run_name="__main__", alter_sys=True)  # as `python -m atlasgen`
"""


@pytest.mark.slow
def test_a_ctrl_c_after_the_command_ended_changes_nothing(tmp_path):
    """A bake that had committed and exited 0 printed Python's KeyboardInterrupt traceback from its shutdown
    (or died by SIGINT: exit 130, no line). Once the command has ended, Ctrl-C is ignored."""
    (tmp_path / "clay.toml").write_text('type = "lambert"\n')
    out = tmp_path / "build" / "atlas.dds"
    done = subprocess.run([sys.executable, "-c", LATE_CTRL_C, "bake", str(tmp_path / "clay.toml"), "-o", str(out), "-q"],
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert (done.returncode, done.stdout, done.stderr) == (0, "", "")
    assert out.is_file()
