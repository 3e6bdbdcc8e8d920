"""OpenImageIO's import holds Ctrl-C until it is done: raised inside its nanobind start-up, it aborted the process."""

from __future__ import annotations

import subprocess
import sys

# A finder that sends this process SIGINT as the import of OpenImageIO begins, then lets the import go on: the
# interrupt must come out after the module is whole, not inside its start-up.
PROGRAM = """
import importlib.abc, os, signal, sys

class Interrupting(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "OpenImageIO":
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.SIGINT)
        return None

sys.meta_path.insert(0, Interrupting())
from atlasgen.io.oiio import import_oiio
try:
    import_oiio()
except KeyboardInterrupt:
    print("interrupted after the import:", "OpenImageIO" in sys.modules and hasattr(sys.modules["OpenImageIO"], "ImageBuf"))
"""


def test_a_ctrl_c_during_the_import_is_raised_once_it_is_done():
    run = subprocess.run([sys.executable, "-c", PROGRAM], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "interrupted after the import: True", run.stdout + run.stderr
