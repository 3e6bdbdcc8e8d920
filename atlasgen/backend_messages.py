"""Dr.Jit's own lines on stderr, held to errors where the caller asked for errors only (``-q``).

Dr.Jit writes its warnings straight to stderr, past Python's ``warnings``: with HOME unset, every
process that starts its LLVM backend prints "jit_init(): the HOME environment variable is not
set, disabling the kernel cache..." twice, which ``atlasgen bake -q`` ("print only errors")
printed too. The first of the two comes from the extension module's own start, before Python can
set Dr.Jit's level, so that import runs with stderr held back (and given back if the import fails);
the level, lowered as soon as the module exists, keeps the later ones away. Dr.Jit is imported
lazily, in whichever function first needs it (so that a LUT bake never loads it):
:func:`keep_backend_messages_to_errors` does this at that import, in this process and, through the
environment, in the worker processes it spawns (:func:`apply_requested_backend_level`, which every
worker runs first).
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import sys
import tempfile

__all__ = [
    "REQUEST_VARIABLE",
    "keep_backend_messages_to_errors",
    "apply_requested_backend_level",
    "native_lines_of_a_failure_dropped",
]

#: Set to 1 by :func:`keep_backend_messages_to_errors`; spawned processes inherit it.
REQUEST_VARIABLE = "ATLASGEN_BACKEND_ERRORS_ONLY"


def keep_backend_messages_to_errors() -> None:
    """From now on, in this process and the processes it starts, Dr.Jit prints errors only."""
    os.environ[REQUEST_VARIABLE] = "1"
    apply_requested_backend_level()


def apply_requested_backend_level() -> None:
    """Hold Dr.Jit to errors if :data:`REQUEST_VARIABLE` asks for it: now if it is imported, else as it is."""
    if os.environ.get(REQUEST_VARIABLE) != "1":
        return
    drjit = sys.modules.get("drjit")
    if drjit is not None:
        _errors_only(drjit)
    elif not any(isinstance(finder, _OnDrjitImport) for finder in sys.meta_path):
        sys.meta_path.insert(0, _OnDrjitImport())


@contextlib.contextmanager
def _stderr_held_back(written_out_on: str = "failure"):
    """Run the block with file descriptor 2 sent to a temporary file, written out only where the block raises
    (``written_out_on = "failure"``), or only where it does not (``"success"``).

    At the descriptor, not ``sys.stderr``: Dr.Jit's and Mitsuba's C++ (and the libraries they load) write to it
    directly.
    """
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as held:
        os.dup2(held.fileno(), 2)
        failed = False
        try:
            yield
        except BaseException:
            failed = True
            raise
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            if failed == (written_out_on == "failure"):
                held.seek(0)
                os.write(2, held.read())


def native_lines_of_a_failure_dropped():
    """A context whose block's lines on file descriptor 2 are written out where it succeeds and dropped where it
    raises: the caller's one-line error then says what failed. Mitsuba's ``load_dict`` printed libpng's "libpng
    error: ... bad header" or nanobind's "implicit conversion ... failed!" before the refusal that quotes it."""
    return _stderr_held_back("success")


def _errors_only(drjit) -> None:
    drjit.set_log_level(drjit.LogLevel.Error)


class _OnDrjitImport:
    """Finds ``drjit`` as the other finders do, and lowers its level once its module has run (a meta path finder:
    ``find_spec`` is all the import system asks of one, and importlib.abc cost the command line's start 2 ms).

    It stays in place until the module has run: a probe (``importlib.util.find_spec("drjit")``)
    finds a spec without importing it, and the import that follows must find this finder again.
    """

    def __init__(self) -> None:
        self._finding = False

    def find_spec(self, name, path=None, target=None):
        if name != "drjit" or self._finding:
            return None
        self._finding = True
        try:
            spec = importlib.util.find_spec(name)  # by the other finders
        finally:
            self._finding = False
        if spec is None or spec.loader is None:
            return spec
        run_module = spec.loader.exec_module

        def exec_module(module) -> None:
            with _stderr_held_back():
                run_module(module)
            _errors_only(module)
            if self in sys.meta_path:  # the level stays set for the life of the process
                sys.meta_path.remove(self)

        spec.loader.exec_module = exec_module
        return spec
