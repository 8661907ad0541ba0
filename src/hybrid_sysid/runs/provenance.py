"""What made a run's numbers, read once per process: the code's git checkout and the processor. A run's record
holds both side by side (``git_commit``, ``git_dirty``, ``cpu``); the last digits of a run's numbers depend on the
kind of CPU (docs/reliability/reproducibility.md)."""

from __future__ import annotations

import platform
import subprocess
from functools import lru_cache
from pathlib import Path


@lru_cache(maxsize=1)
def git_state() -> tuple[str, bool] | None:
    """(commit, whether tracked files differ from it) of the git checkout this code runs from; None outside a
    checkout, without git, or when git does not answer within seconds."""
    here = Path(__file__).resolve().parent
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, timeout=5)
        commit = head.stdout.strip()
        if head.returncode != 0 or len(commit) != 40:
            return None
        diff = subprocess.run(["git", "diff", "--quiet", "HEAD", "--"], cwd=here, capture_output=True, timeout=10)
        return commit, diff.returncode != 0
    except Exception:  # noqa: BLE001 - no git, a timeout, ...: the run is recorded without its commit
        return None


@lru_cache(maxsize=1)
def cpu_model() -> str | None:
    """The processor's model name, as /proc/cpuinfo's "model name" (Linux) or else platform.processor() gives it;
    None when neither names it."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                key, sep, value = line.partition(":")
                if sep and key.strip() == "model name" and value.strip():
                    return " ".join(value.split())
    except OSError:  # not Linux
        pass
    return platform.processor().strip() or None


def provenance_fields() -> dict:
    """The record's fields that name this process's code and processor."""
    commit, dirty = git_state() or (None, None)
    return {"git_commit": commit, "git_dirty": dirty, "cpu": cpu_model()}
