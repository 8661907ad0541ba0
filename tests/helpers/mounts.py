"""A small tmpfs, where a full disk can be made for real (root only), unmounted after."""

import os
import subprocess
from contextlib import contextmanager

import pytest


@contextmanager
def small_tmpfs(mnt, size: str = "1m"):
    """Mount a tmpfs of ``size`` at the new directory ``mnt``; the test skips, saying why, where that cannot be."""
    if os.geteuid() != 0:
        pytest.skip("mounting a small filesystem needs root; without it no disk can be made to fill up")
    mnt.mkdir()
    if subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mnt)], capture_output=True
    ).returncode:
        pytest.skip("this platform does not allow mounting a tmpfs")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", str(mnt)], check=True)
