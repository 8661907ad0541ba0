"""A termination signal as the work sees it: a request that safe points check, and ``Interrupted``, which they
raise.

The command-line entry points' signal handler (hybrid_sysid.cli.process) only ``request``s the stop: an exception
raised from a signal handler would land in whatever code runs at that moment, and a few places swallow it (a
finaliser, a weak-reference callback, a library's broad handler), so the work would go on as if no signal had
come. The work raises Interrupted itself, at its safe points (``check``): after every training and validation
batch (training.callbacks.StopAtSafePoints), after every evaluation batch, while waiting for the dataset cache's
lock, before a run scores its model and before it writes its record; a sweep checks between its jobs.
"""

from __future__ import annotations

import signal

_signal: dict[str, int | None] = {"requested": None, "received": None, "requeue": None}


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


def clear() -> None:
    """A new piece of work starts: a stop requested for an earlier one no longer applies to it."""
    _signal["requested"] = None


def reset() -> None:
    """As a new process starts (a test that runs several commands in one process)."""
    _signal.update(requested=None, received=None)


def requested() -> int | None:
    """The signal whose stop was requested for the work under way, None if none was."""
    return _signal["requested"]


def received() -> int | None:
    """The first termination signal this process received, None if none came."""
    return _signal["received"]


def requeue_on(signum: int | None) -> None:
    """The signal after which the job runs again by itself (SLURM's time limit, through submitit:
    hybrid_sysid.cli.slurm): an interruption by it is recorded, but it does not stop the sweep."""
    _signal["requeue"] = signum


def requeues(signum: int) -> bool:
    """Whether an interruption by ``signum`` is followed by the job's requeue (``requeue_on``)."""
    return signum is not None and signum == _signal["requeue"]


def check() -> None:
    """A safe point: raise Interrupted if a termination signal was requested and has not ended the work yet."""
    if _signal["requested"] is not None:
        raise Interrupted(_signal["requested"])
