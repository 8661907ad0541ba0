"""A termination signal as the work sees it: a request that safe points check, and ``Interrupted``, which they
raise.

The command-line entry points' signal handler (hybrid_sysid.launch.process) only ``request``s the stop: an exception
raised from a signal handler would land in whatever code runs at that moment, and a few places swallow it (a
finaliser, a weak-reference callback, a library's broad handler), so the work would go on as if no signal had
come. The work raises Interrupted itself, at its safe points (``check``): after every training and validation
batch (training.callbacks.StopAtSafePoints), after every evaluation batch, while waiting for the dataset cache's
lock, before a run scores its model and before it writes its record; a sweep checks between its jobs.

A wait in C code that never runs Python's handlers (torch's rendezvous, waiting for nodes nobody started) would
never reach a safe point: ``watched`` ends such a wait from a thread (docs/reliability/resume.md).
"""

from __future__ import annotations

import os
import signal
import threading
import time
from contextlib import contextmanager
from typing import Callable, Iterator

_signal: dict[str, int | None] = {"requested": None, "received": None, "requeue": None, "taken": 0}
GRACE = 2.0  # seconds the main thread has to take a signal before ``watched`` decides it is deaf


class Interrupted(BaseException):
    """A termination signal (SIGTERM: SLURM's time limit, ``timeout``, ``docker stop``; SIGINT: Ctrl-C) during a
    job. A BaseException, as KeyboardInterrupt is, so no ``except Exception`` on the way swallows it."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def request(signum: int) -> None:
    """Remember a termination signal for the safe points of the work under way (the first one counts)."""
    _signal["requested"] = _signal["requested"] or signum
    note(signum)


def note(signum: int) -> None:
    """Remember that the process received a termination signal (between jobs too): its exit status says so."""
    _signal["received"] = _signal["received"] or signum
    _signal["taken"] += 1


def clear() -> None:
    """A new piece of work starts: a stop requested for an earlier one no longer applies to it."""
    _signal["requested"] = None


def reset() -> None:
    """As a new process starts (a test that runs several commands in one process)."""
    _signal.update(requested=None, received=None, taken=0)


def requested() -> int | None:
    """The signal whose stop was requested for the work under way, None if none was."""
    return _signal["requested"]


def received() -> int | None:
    """The first termination signal this process received, None if none came."""
    return _signal["received"]


def requeue_on(signum: int | None) -> None:
    """The signal after which the job runs again by itself (SLURM's time limit, through submitit:
    hybrid_sysid.launch.slurm): an interruption by it is recorded, but it does not stop the sweep."""
    _signal["requeue"] = signum


def requeues(signum: int) -> bool:
    """Whether an interruption by ``signum`` is followed by the job's requeue (``requeue_on``)."""
    return signum is not None and signum == _signal["requeue"]


def check() -> None:
    """A safe point: raise Interrupted if a termination signal was requested and has not ended the work yet."""
    if _signal["requested"] is not None:
        raise Interrupted(_signal["requested"])


@contextmanager
def watched(on_deaf: Callable[[int], None], grace: float = GRACE) -> Iterator[None]:
    """Within, in the main thread: a SIGTERM or SIGINT that no Python handler takes (``note``) within ``grace``
    seconds calls ``on_deaf(signum)`` from a watcher thread, which must end the process (``os._exit``).

    Why a thread: the main thread may be blocked in C code that runs no Python handler until it returns, and
    torch's rendezvous with nodes that never start returns only at its timeout (30 minutes). The signal still
    reaches the pipe of ``signal.set_wakeup_fd``, which Python's own C handler writes to; the thread reads it
    there. A main thread that is merely busy takes the signal within the grace, and the thread does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    r, w = os.pipe()
    os.set_blocking(w, False)
    previous = signal.set_wakeup_fd(w, warn_on_full_buffer=False)
    done = threading.Event()

    def watch() -> None:
        expected = _signal["taken"]
        while not done.is_set():
            try:
                data = os.read(r, 64)
            except OSError:
                return
            for signum in data:
                if signum not in (signal.SIGTERM, signal.SIGINT):
                    continue
                expected += 1
                deadline = time.monotonic() + grace
                while _signal["taken"] < expected and time.monotonic() < deadline and not done.is_set():
                    time.sleep(0.05)
                if _signal["taken"] < expected and not done.is_set():
                    on_deaf(signum)
                    return
                expected = max(expected, _signal["taken"])

    thread = threading.Thread(target=watch, name="hybrid-sysid-signal-watch", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        signal.set_wakeup_fd(previous)
        try:
            os.write(w, b"\0")  # wakes the thread, which sees done and returns
        except BlockingIOError:  # a full pipe wakes it as well
            pass
        thread.join()
        os.close(r)
        os.close(w)
