"""One writer per run or sweep directory: an advisory lock on a file inside it, held by the one process that
writes there and released when that process releases it or ends, however it ends."""

from __future__ import annotations

from pathlib import Path

from hybrid_sysid.core.checks import Shown, bad
from hybrid_sysid.core.ranks import is_global_zero
from hybrid_sysid.runs.layout import WRITER_LOCK

_held: dict[str, object] = {}  # this process's locks, by directory: a lock is the process's, as its files are


def hold_for_writing(path: Path, key: str):
    """Take the one-writer lock of a run or sweep directory and return it; ConfigError naming ``key`` when another
    process holds it. The directory must exist."""
    from filelock import FileLock, Timeout

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


def release(path: Path) -> None:
    lock = _held.pop(str(path), None)
    if lock is not None:
        lock.release()


def release_all() -> None:
    """Every lock this process holds (tests that run several commands in one process)."""
    for path in list(_held):
        release(Path(path))
