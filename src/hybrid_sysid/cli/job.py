"""One job of a command (a run, an evaluation, a trial): ``run_job`` wraps its work with signals, interruption and
failure records.

A job records its own failure or interruption in its run directory (Hydra skips ``on_multirun_end`` when a job
raises), so a sweep goes on and its summary lists the job. Exit statuses: hybrid_sysid.cli.process.
"""

from __future__ import annotations

import copy
import logging
import os
import signal
import sys
import threading
from pathlib import Path
from typing import Any, Callable

from omegaconf import DictConfig, open_dict, read_write

from hybrid_sysid.cli.console import job_running, quiet_libraries
from hybrid_sysid.cli.orphans import exit_with_parent, job_in_progress
from hybrid_sysid.cli.process import PROCESS, SIGNALS, fail, interruptible, stop_sweep
from hybrid_sysid.core import stop
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.core.stop import Interrupted
from hybrid_sysid.runs import locks
from hybrid_sysid.runs.layout import STOP_MARKER
from hybrid_sysid.runs.records import CompletedRecordError
from hybrid_sysid.runs.rundir import RunDir

log = logging.getLogger("hybrid_sysid")


def run_job(
    work: Callable[[], Any],
    run_dir: Path,
    overrides: list[str],
    seed: int,
    *,
    multirun: bool,
    sweep_dir: Path | None = None,
    again: str = "run the same command again",
) -> Any:
    """Run one job's ``work()`` and return what it returns. A signal before or during it records the job as
    interrupted in ``run_dir`` (a single job then exits 128 + the signal; a sweep's job returns its record so
    the sweep goes on to its summary, and marks the sweep so jobs not yet started skip). An exception records
    the job as failed: a sweep's job returns {"status": "failed", ...}; a single job's refused value or full
    disk ends in one line, anything else in its traceback. ``again``: how to continue an interrupted job."""
    with job_in_progress():  # a parallel worker whose parent is gone waits for the record (orphans.py)
        PROCESS.job_started = True
        run = RunDir(run_dir)
        if multirun and threading.current_thread() is threading.main_thread():
            # a parallel worker (or the basic launcher's own process): between its jobs a signal must not kill it,
            # or the launcher drops the jobs not yet started; remembered, it makes them record their interruption
            for s in SIGNALS:
                signal.signal(s, stop_sweep)
            exit_with_parent()  # a parallel worker ends when the sweep's parent is gone (a no-op in other processes)
        received = stop.received()
        if received is not None or (sweep_dir is not None and (sweep_dir / STOP_MARKER).exists()):
            # a signal came while Hydra composed and launched: do not start
            name = signal.Signals(received).name if received else "the sweep's interruption"
            result = run.record_end(overrides, seed, "interrupted", f"not started: interrupted by {name}")
            if not multirun:
                sys.exit(128 + received)
            return result
        mine = multirun and not locks.holds(run_dir)  # a single job's preflight holds it already
        if mine:
            try:
                run_dir.mkdir(parents=True, exist_ok=True)
                locks.hold(run_dir, "the job's directory")
            except (ConfigError, OSError) as exc:  # another process writes there: its files are not ours to touch
                log.error("job not run: %s", exc)
                return {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}
        try:
            with interruptible(), job_running():
                quiet_libraries()  # Lightning's messages once, through the job's logging (hybrid_sysid.cli.console)
                try:
                    return work()
                except SystemExit:  # e.g. Lightning's SIGTERMException, raised at its own safe points
                    if stop.requested() is None:
                        raise
                    raise Interrupted(stop.requested()) from None
        except Interrupted as exc:
            name = signal.Signals(exc.signum).name
            result = run.record_end(overrides, seed, "interrupted", f"interrupted by {name}")
            log.error("%s: interrupted by %s; %s", run_dir, name, again)
            if not multirun:
                sys.exit(128 + exc.signum)
            if sweep_dir is not None and sweep_dir.is_dir():  # jobs not yet started skip, here and in other workers
                (sweep_dir / STOP_MARKER).touch()
            return result
        except Exception as exc:  # record the failure where the sweep summary will look for it
            error = f"{type(exc).__name__}: {exc}"
            run.record_end(overrides, seed, "failed", error)
            if multirun:  # let the other jobs run; the sweep summary exits non-zero
                log.error("job failed: %s", error)
                return {"status": "failed", "error": error}
            if os.environ.get("HYDRA_FULL_ERROR") != "1":
                if isinstance(exc, (ConfigError, CompletedRecordError)):
                    fail(str(exc))  # a bad value: one line, no traceback
                if isinstance(exc, OSError):
                    fail(f"{error} (run directory {run_dir})", status=1)  # e.g. a full disk: one line
            raise
        finally:
            if mine:  # a worker runs several jobs: each job's directory is free again once it ends
                locks.release(run_dir)


def draws_figures(setting, multirun: bool) -> bool:
    """run_figures: true or false as given; auto: a single run draws its figures, a sweep's job does not (about
    2 s of CPU a job for figures few open; the sweep draws its own, and hybrid-sysid-report run_figures=true
    draws the runs' later)."""
    return setting if isinstance(setting, bool) else not multirun


def task_config(cfg: DictConfig) -> DictConfig:
    """The job's config without Hydra's own section."""
    task = copy.deepcopy(cfg)
    with read_write(task), open_dict(task):
        del task["hydra"]
    return task
