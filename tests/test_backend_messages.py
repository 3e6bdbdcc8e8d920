"""Dr.Jit's own stderr lines, held to errors where ``-q`` asks for errors only: in the process, in its bake
workers and through the command line, with HOME unset (where Dr.Jit warns on every start)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

from atlasgen.backend_messages import REQUEST_VARIABLE, _stderr_held_back
from atlasgen.bake import workers

pytestmark = pytest.mark.skipif(importlib.util.find_spec("drjit") is None, reason="Dr.Jit is not installed")

ROOT = Path(__file__).resolve().parents[1]
#: What Dr.Jit prints at start without HOME (its kernel cache has no folder).
NO_HOME = "HOME environment variable is not set"
START_DRJIT = "import mitsuba as mi; mi.set_variant('llvm_ad_rgb'); print(mi.Float([1, 2]) + 1)"


def _without_home(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("HOME", "DRJIT_CACHE_DIR", REQUEST_VARIABLE)}
    return {**env, **extra}


def _python(code: str, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120, cwd=ROOT)


@pytest.fixture(scope="module")
def drjit_warns_without_home():
    """Skip where this Dr.Jit prints nothing without HOME: the tests below would hold nothing back."""
    run = _python(START_DRJIT, _without_home())
    assert run.returncode == 0, run.stderr
    if NO_HOME not in run.stderr:
        pytest.skip("this Dr.Jit prints nothing at start without HOME")


@pytest.mark.slow
def test_a_requested_level_silences_drjit_from_its_first_line(drjit_warns_without_home):
    """Both of Dr.Jit's start lines: the one its extension prints while it is imported, and the later one."""
    code = f"from atlasgen.backend_messages import apply_requested_backend_level as a; a(); {START_DRJIT}"
    run = _python(code, _without_home(**{REQUEST_VARIABLE: "1"}))
    assert run.returncode == 0 and run.stdout.strip() == "[2, 3]" and run.stderr == ""


@pytest.mark.slow
def test_a_probe_for_drjit_before_its_import_leaves_the_request_in_place(drjit_warns_without_home):
    """``importlib.util.find_spec("drjit")`` (how a module asks whether Dr.Jit is installed) finds it
    without importing it: the import that follows is still held back."""
    code = ("import importlib.util; from atlasgen.backend_messages import apply_requested_backend_level as a; a(); "
            f"assert importlib.util.find_spec('drjit') is not None; {START_DRJIT}")  # fmt: skip
    run = _python(code, _without_home(**{REQUEST_VARIABLE: "1"}))
    assert run.returncode == 0 and run.stdout.strip() == "[2, 3]" and run.stderr == ""


@pytest.mark.slow
def test_without_the_request_drjit_keeps_its_lines(drjit_warns_without_home):
    code = f"from atlasgen.backend_messages import apply_requested_backend_level as a; a(); {START_DRJIT}"
    assert NO_HOME in _python(code, _without_home()).stderr


@pytest.mark.slow
def test_quiet_bake_prints_nothing_without_home(drjit_warns_without_home, tmp_path):
    """``bake -q`` of a material fitted through Mitsuba: "print only errors", and Dr.Jit's lines are none."""
    material = tmp_path / "plastic.toml"
    material.write_text((ROOT / "materials" / "red-plastic.toml").read_text())
    command = [sys.executable, "-m", "atlasgen", "bake", "-q", str(material), "-o", str(tmp_path / "x.dds"),
               "--cache", str(tmp_path / "cache")]  # fmt: skip
    run = subprocess.run(command, env=_without_home(), capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert run.returncode == 0 and run.stderr == "", run.stderr
    assert (tmp_path / "x.dds").is_file()


def _drjit_started(_=None):
    import drjit

    return drjit.log_level().name


@pytest.mark.slow
def test_bake_workers_take_the_requested_level(drjit_warns_without_home, monkeypatch, capfd):
    """A spawned worker imports Dr.Jit afresh: it holds its lines back as its caller asked."""
    monkeypatch.delenv("HOME")
    monkeypatch.setenv(REQUEST_VARIABLE, "1")
    with workers.worker_pool(1) as pool:
        level = next(pool.map(_drjit_started, [None]))
    assert level == "Error"
    assert NO_HOME not in capfd.readouterr().err


def test_held_back_stderr_is_dropped_when_the_block_ends_well(capfd):
    with _stderr_held_back():
        os.write(2, b"held\n")
    os.write(2, b"after\n")
    assert capfd.readouterr().err == "after\n"


def test_held_back_stderr_is_written_out_when_the_block_raises(capfd):
    """A failed import's own lines are what explains it: they are given back, then the error."""
    with pytest.raises(ImportError), _stderr_held_back():
        os.write(2, b"why it failed\n")
        raise ImportError("no")
    os.write(2, b"after\n")
    assert capfd.readouterr().err == "why it failed\nafter\n"
