"""One writer per run or sweep directory: an advisory lock on a file inside it, held by the one process that
writes there and released when that process releases it or ends, however it ends."""

from __future__ import annotations

import fcntl  # filelock's lock on POSIX is flock(2), which a shared flock request meets (Linux only)
import os
from pathlib import Path

from filelock import FileLock, Timeout

from hybrid_sysid.core.checks import Shown, bad
from hybrid_sysid.core.ranks import is_global_zero
from hybrid_sysid.runs.layout import WRITER_LOCK

_held: dict[str, object] = {}  # this process's locks, by directory: a lock is the process's, as its files are


def hold_for_writing(path: Path, key: str):
    """Take the one-writer lock of a run or sweep directory and return it; ConfigError naming ``key`` when another
    process holds it. The directory must exist."""
    lock = FileLock(str(Path(path) / WRITER_LOCK), timeout=0)
    try:
        lock.acquire()
    except Timeout:
        bad(
            key,
            Shown(str(path)),
            "another process is writing there (a run or sweep of hybrid-sysid); wait until it ends, or choose "
            f"another {key}",
        )
    return lock


def hold(path: Path, key: str) -> None:
    """This process's lock of a run or sweep directory, kept until the process ends (or ``release``). A DDP rank
    above the global rank 0 (on this node or another, its directory perhaps the same on a shared file system)
    shares rank 0's directory, which rank 0 alone holds and writes (hybrid_sysid.core.ranks)."""
    if not is_global_zero():
        return
    if str(path) not in _held:
        _held[str(path)] = hold_for_writing(path, key)


def holds(path: Path) -> bool:
    return str(path) in _held


def held_elsewhere(path: Path) -> bool:
    """Whether another process holds the writer lock of ``path`` now (a run still training, say), without taking
    it: a shared lock is asked for and at once given back, on a descriptor opened read-only, so a directory a
    reader may not write (a received run) can be asked too. A lock file that is missing or cannot be opened is no
    writer's."""
    if holds(path):
        return False
    try:
        fd = os.open(Path(path) / WRITER_LOCK, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:  # a file system without flock: filelock would not have held it either
        return False
    finally:
        os.close(fd)  # gives back the shared lock too
    return False


def release(path: Path) -> None:
    lock = _held.pop(str(path), None)
    if lock is not None:
        lock.release()


def release_all() -> None:
    """Every lock this process holds (tests that run several commands in one process)."""
    for path in list(_held):
        release(Path(path))
