"""A job's optimiser steps as its training reports them, to whoever listens: a sweep's worker listens for the job
it runs (hybrid_sysid.launch.sweep), so the time left can time a kind of job long before one of its jobs ends
(hybrid_sysid.launch.time_left). The training (training.callbacks.StepReports) calls ``report``; nothing listens
outside a sweep, and then a report costs one check."""

from __future__ import annotations

from typing import Callable

PARTS = 20  # reports a job makes: at its first step and at each twentieth of its steps
_listener: dict[str, Callable[[int, int], None] | None] = {"now": None}


def listen(listener: Callable[[int, int], None] | None) -> None:
    """``listener(done, total)`` hears the steps of the job that starts now; None: nobody listens any more."""
    _listener["now"] = listener


def listening() -> bool:
    return _listener["now"] is not None


def report(done: int, total: int) -> None:
    """``done`` of ``total`` steps are done. A listener's failure is its own: the training goes on."""
    listener = _listener["now"]
    if listener is not None:
        try:
            listener(done, total)
        except Exception:  # noqa: BLE001 - a progress file that cannot be written must not end a run
            pass
