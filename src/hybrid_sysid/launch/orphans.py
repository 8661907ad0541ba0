"""A parallel sweep's workers end with their parent. Killed with SIGKILL, a sweep's parent cannot pass anything on,
and its joblib (loky) workers, which keep ``stop_sweep`` as their handler between jobs so that a signal does not
drop the jobs not yet started, would go on running the remaining jobs into the dead sweep and then idle for good.

``exit_with_parent`` starts, once per worker process, a daemon thread that watches the parent: when it is gone,
the thread sends this process SIGTERM once (a running job records its interruption, as for a SIGTERM the parent
passed on), waits until no job runs in the process (``job_in_progress``: until the job's record is written) and
ends the process with 128 + SIGTERM: at once if it was idle, at the latest ``GRACE_SECONDS`` after the SIGTERM. The
bound is generous because a job may be slow to reach its first safe point: a job that has just started imports
torch and Lightning, several seconds of CPU on a loaded machine, and the record is the point of the wait.

Why a polling thread and not Linux's prctl(PR_SET_PDEATHSIG): the death signal fires when the *thread* that
started the worker ends, not its process (loky starts replacement workers from its executor-manager thread); set
from the worker once it runs a job, it misses a parent that died before, so ``os.getppid`` would have to be
checked anyway; it only delivers a signal, and SIGTERM between jobs is recorded, not fatal, so a thread would still
be needed to bound the exit; and it is Linux-only. One thread that polls ``os.getppid`` does all of it, everywhere,
at the cost of up to ``POLL_SECONDS`` of delay.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import signal
import threading
import time

from hybrid_sysid.launch.state import PROCESS

log = logging.getLogger("hybrid_sysid")
POLL_SECONDS = 0.5  # how often the parent is checked
GRACE_SECONDS = 30.0  # at most, from the SIGTERM to the exit: time for the running job to record its interruption


@contextlib.contextmanager
def job_in_progress():
    """Within: a job runs in this process, up to and including the writing of its record. A worker whose parent
    is gone exits once no job is in progress (see the module's docstring)."""
    PROCESS.idle.clear()
    try:
        yield
    finally:
        PROCESS.idle.set()


def exit_with_parent(poll: float = POLL_SECONDS, grace: float = GRACE_SECONDS) -> bool:
    """In a process that ``multiprocessing`` (or loky, which joblib uses) started, start the thread that ends it
    when its parent is gone; True if it was started now. A no-op, returning False, in a process started otherwise
    (a single run, or a sweep's parent with the basic launcher, whose own parent is a shell or a scheduler and
    must not end it) and in a process whose thread is already running."""
    parent = multiprocessing.parent_process()
    if parent is None or parent.pid is None:
        return False
    with PROCESS.lock:
        if PROCESS.watched == os.getpid():
            return False
        PROCESS.watched = os.getpid()
    # the parent's pid as the worker was started (not os.getppid() now): a parent that died before this call,
    # the worker already adopted by init or a subreaper, is noticed at the first check
    watcher = threading.Thread(target=_watch, args=(parent.pid, poll, grace), name="exit-with-parent", daemon=True)
    watcher.start()
    return True


def _watch(parent_pid: int, poll: float, grace: float) -> None:
    while os.getppid() == parent_pid:
        time.sleep(poll)
    log.error(
        "the sweep's parent (pid %d) is gone: worker %d ends its job and exits within %.0f s",
        parent_pid,
        os.getpid(),
        grace,
    )
    # the main thread's handler runs: a stop request within a job (recorded at its next safe point), stop_sweep
    # between jobs (remembered)
    os.kill(os.getpid(), signal.SIGTERM)
    PROCESS.idle.wait(grace)
    os._exit(128 + signal.SIGTERM)
