"""A termination signal as the work sees it: ``Interrupted``, and the request that safe points check.

The command-line entry points (hybrid_sysid.cli.job) raise Interrupted from their signal handler, at once, and
also ``request`` the stop here. An exception raised from a signal handler lands in whatever code runs at that
moment, and a few places swallow it (a finaliser, a library's broad handler), so the work would go on; the safe
points (``check``: before a run scores its model and before it writes its record) raise it again there.
"""

from __future__ import annotations

import signal

_requested: dict[str, int | None] = {"signum": None}


class Interrupted(BaseException):
    """A termination signal (SIGTERM: SLURM's time limit, ``timeout``, ``docker stop``; SIGINT: Ctrl-C) during a
    job. A BaseException, as KeyboardInterrupt is, so no ``except Exception`` on the way swallows it."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def request(signum: int) -> None:
    """Remember a termination signal for the safe points (the first one counts)."""
    _requested["signum"] = _requested["signum"] or signum


def clear() -> None:
    _requested["signum"] = None


def check() -> None:
    """A safe point: raise Interrupted if a termination signal was requested and has not ended the work yet."""
    if _requested["signum"] is not None:
        raise Interrupted(_requested["signum"])
