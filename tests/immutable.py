"""``chattr +i`` for tests of folders and files nothing may change: root only, and a file system that keeps
the flag (ext4, xfs, btrfs; not tmpfs or overlayfs). Tests skip cleanly where it cannot be set."""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
from pathlib import Path

import pytest


def chattr(path: Path, flag: str) -> bool:
    """``chattr +i``/``-i`` on ``path``; False where it cannot. chattr cannot flag a link itself: on an output
    set's link, it flags the generation's file."""
    if os.geteuid() != 0 or shutil.which("chattr") is None:
        return False
    return subprocess.run(["chattr", flag, os.path.realpath(path)], capture_output=True).returncode == 0


@contextlib.contextmanager
def immutable(path: Path):
    """``path`` immutable for the block (the test skips where it cannot be), writable again after it."""
    if not chattr(path, "+i"):
        pytest.skip("chattr +i needs root and a file system with the immutable flag")
    try:
        yield path
    finally:
        chattr(path, "-i")
