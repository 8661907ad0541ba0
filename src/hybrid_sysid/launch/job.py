"""One job of a command (a run, an evaluation, a trial): the checks before Hydra makes its directory
(``Preflight``), and ``run_job``, which wraps its work with signals, interruption and failure records.

The preflight is a Hydra callback that checks what needs no work before Hydra creates a directory (Hydra writes
.hydra/ there first): a single job's own checks (``check``, which each command's subclass gives) and no completed
run of other overrides in its run directory; a sweep's packages for every swept choice, and a re-run sweep against
the one its directory was made by (runs.sweepdir). A refusal is one line and exit status 2 (a callback's exception
would only be a warning to Hydra).

A job records its own failure or interruption in its run directory (Hydra skips ``on_multirun_end`` when a job
raises), so a sweep goes on and its summary lists the job. Exit statuses: hybrid_sysid.launch.process.
"""

from __future__ import annotations

import copy
import logging
import os
import signal
import sys
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf, open_dict, read_write

from hybrid_sysid.config.paths import check_paths
from hybrid_sysid.core import ranks, stop
from hybrid_sysid.core.checks import ConfigError, Shown, bad
from hybrid_sysid.core.stop import Interrupted
from hybrid_sysid.launch.choices import check_choices
from hybrid_sysid.launch.console import job_running, quiet_libraries
from hybrid_sysid.launch.orphans import exit_with_parent, job_in_progress
from hybrid_sysid.launch.process import (
    SIGNALS,
    fail,
    full_error,
    interruptible,
    missing_extra_of_sweep,
    stop_sweep,
)
from hybrid_sysid.launch.slurm import check_request
from hybrid_sysid.launch.state import PROCESS
from hybrid_sysid.runs import locks
from hybrid_sysid.runs.rundir import CompletedRecordError, RunDir
from hybrid_sysid.runs.sweepdir import SweepDir, first_difference

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
        if received is not None or (sweep_dir is not None and SweepDir(sweep_dir).stopped()):
            # a signal came while Hydra composed and launched: do not start
            name = signal.Signals(received).name if received else "the sweep's interruption"
            result = run.record_end(overrides, seed, "interrupted", f"not started: interrupted by {name}")
            if not multirun:
                sys.exit(128 + received)
            return result
        if not ranks.is_global_zero():  # a DDP rank above 0: global rank 0 records the run, this one writes nothing
            with interruptible(), job_running(), stop.watched(_deaf(None, run_dir, overrides, seed, again)):
                quiet_libraries()
                return work()
        mine = multirun and not locks.holds(run_dir)  # a single job's preflight holds it already
        if mine:
            try:
                run_dir.mkdir(parents=True, exist_ok=True)
                locks.hold(run_dir, "the job's directory")
            except (ConfigError, OSError) as exc:  # another process writes there: its files are not ours to touch
                log.error("job not run: %s", exc)
                return {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}
        try:
            with interruptible(), job_running(), stop.watched(_deaf(run, run_dir, overrides, seed, again)):
                quiet_libraries()  # Lightning's messages once, through the job's logging (hybrid_sysid.launch.console)
                try:
                    result = work()
                    if not multirun and isinstance(result, dict) and result.get("status") == "completed":
                        PROCESS.completed = run_dir  # a signal from here on stops nothing: exit status 0
                    return result
                except SystemExit:  # e.g. Lightning's SIGTERMException, raised at its own safe points
                    if stop.requested() is None:
                        raise
                    raise Interrupted(stop.requested()) from None
        except Interrupted as exc:
            name = signal.Signals(exc.signum).name
            requeued = stop.requeues(exc.signum)  # SLURM's time limit: the job runs again and resumes by itself
            why = f"interrupted by {name}" + (" (SLURM's time limit; the job is requeued)" if requeued else "")
            result = run.record_end(overrides, seed, "interrupted", why)
            log.error("%s: %s; %s", run_dir, why, "it resumes from its last checkpoint" if requeued else again)
            if not multirun:
                sys.exit(128 + exc.signum)
            if not requeued and sweep_dir is not None:  # jobs not yet started skip
                SweepDir(sweep_dir).mark_stopped()
            return result
        except Exception as exc:  # record the failure where the sweep summary will look for it
            error = f"{type(exc).__name__}: {exc}"
            run.record_end(overrides, seed, "failed", error)
            if multirun:  # let the other jobs run; the sweep summary exits non-zero
                log.error("job failed: %s", error)
                return {"status": "failed", "error": error}
            if not full_error():
                if isinstance(exc, (ConfigError, CompletedRecordError)):
                    fail(str(exc))  # a bad value: one line, no traceback
                if isinstance(exc, OSError):
                    fail(f"{error} (run directory {run_dir})", status=1)  # e.g. a full disk: one line
                if isinstance(exc, FloatingPointError):  # a NaN loss: the record says why, no traceback adds to it
                    fail(f"{error} (recorded in {run_dir})", status=1)
            raise
        finally:
            if mine:  # a worker runs several jobs: each job's directory is free again once it ends
                locks.release(run_dir)


def _deaf(run: RunDir | None, run_dir: Path, overrides: list[str], seed: int, again: str):
    """What ends a job whose main thread does not take a signal (core.stop.watched): its record says interrupted
    (rank 0 alone writes one), one line says where it waited, and the process ends with 128 + the signal."""

    def end(signum: int) -> None:
        name = signal.Signals(signum).name
        why = f"interrupted by {name} during a wait that no signal reaches (a rendezvous with nodes not started?)"
        if run is not None:
            run.try_record_end(overrides, seed, "interrupted", why)
        print(f"error: {run_dir}: {why}; {again}", file=sys.stderr, flush=True)
        os._exit(128 + signum)

    return end


def draws_figures(setting, multirun: bool) -> bool:
    """run_figures: true or false as given; auto: a single run draws its figures, a sweep's job does not (seconds
    of CPU a job for figures few open: benchmarks/README.md; the sweep draws its own, and hybrid-sysid-report
    run_figures=true draws the runs' later)."""
    return setting if isinstance(setting, bool) else not multirun


def draw_run_figures(run_dir: Path) -> None:
    """A run's or an evaluation's figures, from its files; it is complete without them, so a failure here is a
    warning."""
    try:
        from hybrid_sysid.report.run_figures import write_run_figures  # deferred

        write_run_figures(run_dir)
    except Exception as exc:  # noqa: BLE001 - e.g. a full disk: the record already holds every number
        log.warning("run figures not drawn in %s: %s: %s", run_dir, type(exc).__name__, exc)


def task_config(cfg: DictConfig) -> DictConfig:
    """The job's config without Hydra's own section."""
    task = copy.deepcopy(cfg)
    with read_write(task), open_dict(task):
        del task["hydra"]
    return task


SEARCH_SWEEPER = "hydra_plugins.hybrid_sysid_search.StudySweeper"  # conf/hydra/sweeper/study.yaml
SLURM_LAUNCHER = "hydra_plugins.hybrid_sysid_slurm.SlurmLauncher"  # conf/launcher/slurm.yaml
JOBLIB_LAUNCHER = "hydra_plugins.hydra_joblib_launcher.joblib_launcher.JoblibLauncher"  # conf/launcher/joblib.yaml


class Preflight(Callback):
    """The checks of a job before Hydra makes its directory (the module's docstring). ``saves_task_config``: the
    job's saved config is the one Hydra composed (a training run's; an evaluation saves the evaluated run's)."""

    saves_task_config = False

    def check(self, cfg: DictConfig, overrides: list[str]) -> None:
        """The command's checks of a single job's config (without Hydra's section); raise ConfigError."""

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        with checks_complete():
            self._run_start(config)

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        with checks_complete():
            self._multirun_start(config)

    def _run_start(self, config: DictConfig) -> None:
        run_dir, overrides = Path(str(config.hydra.run.dir)), list(config.hydra.overrides.task)
        check_choices(config)
        self.check(task_config(config), overrides)
        make_dir(run_dir, "hydra.run.dir")
        locks.hold(run_dir, "hydra.run.dir")  # before Hydra writes .hydra/ there: one writer per directory
        done = RunDir(run_dir).previous_record(overrides)  # a completed run of other overrides: refused
        if done is not None and self.saves_task_config:
            same_config(RunDir(run_dir), config)
        if not ranks.is_global_zero():
            writes_nothing(config)

    def _multirun_start(self, config: DictConfig) -> None:
        check_paths(task_config(config))  # an empty paths.root would make the sweep's directory at the root
        sweep_dir = PROCESS.sweep_dir = Path(str(config.hydra.sweep.dir))
        check_choices(config)
        # a swept choice's package: one line here, not every job failing
        missing = missing_extra_of_sweep(config.hydra.overrides.task, task_config(config))
        if missing:
            fail(missing)
        if is_search(config):  # a search: its space and settings before any trial
            from hybrid_sysid.experiments.search import study_settings  # deferred

            study_settings(task_config(config), config.hydra.sweeper, config.hydra.overrides.task)
        check_joblib(config.hydra.launcher)
        if str(config.hydra.launcher.get("_target_", "")) == SLURM_LAUNCHER:  # the request against the partition
            check_request(config.hydra.launcher)
        make_dir(sweep_dir, "hydra.sweep.dir")
        locks.hold(sweep_dir, "hydra.sweep.dir")  # one sweep per directory at a time
        SweepDir(sweep_dir).check_rerun(config)  # a re-run is the same sweep, or nothing is touched
        SweepDir(sweep_dir).clear_stopped()  # a re-run continues an interrupted sweep


@contextmanager
def checks_complete():
    """Within: a preflight's checks. Hydra would turn any exception of a callback into a warning and run the job
    anyway, without the checks, the lock or the completed-run guard; so a refusal, and any check that cannot
    complete (a damaged saved config, a value its check cannot hold in memory), ends the command here in one line,
    exit status 2, before Hydra makes a directory. A signal (BaseException) passes."""
    try:
        yield
    except ValueError as exc:  # a refused value (ConfigError), a damaged cache: their own words
        fail(" ".join(str(exc).split()))
    except Exception as exc:  # noqa: BLE001 - whatever a check raises, the command must not go on unchecked
        fail(f"the checks before the job could not complete: {type(exc).__name__}: {' '.join(str(exc).split())}")


def same_config(run: RunDir, config: DictConfig) -> None:
    """A completed run of the same overrides is skipped (Hydra saves nothing over it: config/resolvers.py's
    hydra_subdir); made with another config (a file of the user's --config-dir changed), it is refused, since its
    record does not hold what this command asks. A saved config that cannot be read tells nothing: skipped."""
    saved = run.saved_values()
    if not saved:
        return
    now = OmegaConf.to_container(task_config(config), resolve=False)
    change = first_difference(*({k: v for k, v in c.items() if k != "resume"} for c in (saved, now)))
    if change is not None:
        key, there, here = change
        bad(
            "hydra.run.dir",
            Shown(str(run.path)),
            f"it holds a completed run made with another config ({key}: {there} there, {here} here: a config file "
            "changed, or the run's saved one is damaged); choose another hydra.run.dir",
        )


def writes_nothing(config: DictConfig) -> None:
    """A DDP rank above global rank 0 shares rank 0's run directory (on a shared file system, from another node
    too): Hydra writes neither its .hydra/ nor the rank's log file there. Its messages still reach its console."""
    with read_write(config), open_dict(config):
        config.hydra.output_subdir = None
        logging_cfg = config.hydra.job_logging
        logging_cfg.handlers.pop("file", None)
        logging_cfg.root.handlers = [h for h in logging_cfg.root.get("handlers", []) if h != "file"]


def check_joblib(launcher: DictConfig) -> None:
    """joblib's own refusal of n_jobs = 0 comes as a traceback after the sweep directory is made."""
    if str(launcher.get("_target_", "")) != JOBLIB_LAUNCHER:
        return
    n_jobs = launcher.get("n_jobs")
    if n_jobs is not None and (isinstance(n_jobs, bool) or not isinstance(n_jobs, int) or n_jobs == 0):
        bad("hydra.launcher.n_jobs", n_jobs, "a whole number of workers, >= 1 (or < 0: all cores but n_jobs + 1)")


def is_search(config: DictConfig) -> bool:
    """Whether the sweep is a hyperparameter search (the study sweeper, hybrid_sysid.launch.search)."""
    return str(config.hydra.sweeper.get("_target_", "")) == SEARCH_SWEEPER


def make_dir(path: Path, key: str) -> None:
    """Hydra would make it next, and print a traceback if it cannot: one line instead."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        fail(f"{key} = {path} cannot be created: {type(exc).__name__}: {exc}")
