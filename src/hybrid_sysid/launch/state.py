"""A command's process state, in one object (``PROCESS``): what the process knows of itself beyond its signals
(core.stop) and its writer locks (runs.locks). Each field says who writes it; ``reset`` is for a test that runs
several commands in one process."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from pathlib import Path

from hybrid_sysid.core import stop


def _idle() -> threading.Event:
    event = threading.Event()
    event.set()
    return event


@dataclass
class CommandProcess:
    """The sweep it runs, and whether a job has started in it (a failure before one is a refusal, exit status 2);
    then what lives as long as the process (a parallel worker runs several jobs): how many jobs it started, whether
    one runs now, and the watcher of its parent (launch.orphans)."""

    sweep_dir: Path | None = None  # a sweep's parent: set by the preflight, read by the signal handler
    job_started: bool = False
    summarised: bool = False  # the sweep's end (launch.sweep) has run: no summary is written here after it
    completed: Path | None = None  # a single job's directory, once its completed record is written
    jobs: int = 0  # the jobs this process has started: its first pays the imports (launch.progress: time left)
    job_running: bool = False  # within a job's own work: its INFO messages stay off a sweep's console
    watched: int | None = None  # the pid whose parent-watcher runs (a forked child inherits it, not the thread)
    idle: threading.Event = field(default_factory=_idle)  # set while no job runs (a job's record included)
    lock: threading.Lock = field(default_factory=threading.Lock)  # one watcher is started, whatever the threads

    def reset(self) -> None:
        """As a new process starts (a test that runs several commands in one process)."""
        self.sweep_dir, self.job_started, self.summarised, self.completed = None, False, False, None
        stop.reset()


PROCESS = CommandProcess()
