"""What every command-line entry point shares: one job wrapper (``run_job``) for signals, interruption and failure
records, the Preflight callback, the optional-extras check, and the exit statuses (``console_main``).

A job records its own failure or interruption in its run directory (Hydra skips ``on_multirun_end`` when a job
raises), so a sweep goes on and its summary lists the job. A single run's config is checked before Hydra creates
its directory (``Preflight``), so a rejected value or resume leaves nothing behind, and no command writes into a
directory that holds a completed run of other overrides.

Exit statuses: 0 done; 1 a failure during the work; 2 a value refused (one line on stderr), a config that does
not compose or an OS error before any job; 128 + the signal's number for a job or sweep ended by SIGTERM or SIGINT.
"""

from __future__ import annotations

import copy
import importlib.util
import logging
import os
import signal
import sys
import threading
import traceback
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf, open_dict, read_write

from hybrid_sysid.cli.console import job_running, quiet_libraries
from hybrid_sysid.cli.orphans import exit_with_parent, job_in_progress
from hybrid_sysid.core import stop
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.core.install import install_command
from hybrid_sysid.core.stop import Interrupted
from hybrid_sysid.runs.records import CompletedRecordError
from hybrid_sysid.runs.rundir import RunDir, hold_for_writing

log = logging.getLogger("hybrid_sysid")
SIGNALS = (signal.SIGTERM, signal.SIGINT)
SEARCH_SWEEPER = "hydra_plugins.hybrid_sysid_search.StudySweeper"  # conf/hydra/sweeper/study.yaml
STOP_MARKER = ".interrupted"  # in a sweep directory: the sweep was interrupted, jobs not yet started skip
# one process runs one command: what its signal handlers and its jobs share
_state = {"received": None, "sweep_dir": None, "task_started": False, "locks": {}}


def _request_stop(signum, frame):
    """Within a job: remember the signal; the work raises Interrupted at its next safe point (core.stop)."""
    _state["received"] = _state["received"] or signum
    stop.request(signum)


@contextmanager
def interruptible():
    """Within: SIGTERM and SIGINT request a stop that the work's safe points turn into Interrupted (Lightning, which
    installs its own SIGTERM handler during fit, calls this one after its own). The previous handlers return
    after."""
    stop.clear()
    previous = {s: signal.getsignal(s) for s in SIGNALS}
    for s in SIGNALS:
        signal.signal(s, _request_stop)
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _children() -> list[int]:
    """This process's child processes (a parallel sweep's workers), from /proc; [] where there is none."""
    me, found = str(os.getpid()), []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if fields[1] == me:
            found.append(int(stat.parent.name))
    return found


def stop_sweep(signum, frame):
    """The handler of a process between jobs (a sweep's parent): remember the signal, mark the sweep as
    interrupted so jobs not yet started skip, and pass the signal to the running jobs (parallel workers), which
    record their interruption and return; Hydra then ends the sweep with its summary."""
    first = _state["received"] is None
    _state["received"] = _state["received"] or signum
    sweep_dir = _state["sweep_dir"]
    if first and sweep_dir is not None and sweep_dir.is_dir():
        (sweep_dir / STOP_MARKER).touch()
    if first:
        for pid in _children():
            try:
                os.kill(pid, signum)
            except OSError:
                pass


def fail(message: str, status: int = 2):
    print(f"error: {message}", file=sys.stderr)
    if os.environ.get("HYDRA_FULL_ERROR") == "1":
        traceback.print_exc()
    sys.exit(status)


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
        _state["task_started"] = True
        run = RunDir(run_dir)
        if multirun and threading.current_thread() is threading.main_thread():
            # a parallel worker (or the basic launcher's own process): between its jobs a signal must not kill it,
            # or the launcher drops the jobs not yet started; remembered, it makes them record their interruption
            for s in SIGNALS:
                signal.signal(s, stop_sweep)
            exit_with_parent()  # a parallel worker ends when the sweep's parent is gone (a no-op in other processes)
        received = _state["received"]
        if received is not None or (sweep_dir is not None and (sweep_dir / STOP_MARKER).exists()):
            # a signal came while Hydra composed and launched: do not start
            name = signal.Signals(received).name if received else "the sweep's interruption"
            result = run.record_end(overrides, seed, "interrupted", f"not started: interrupted by {name}")
            if not multirun:
                sys.exit(128 + received)
            return result
        mine = multirun and str(run_dir) not in _state["locks"]  # a single job's preflight holds it already
        if mine:
            try:
                run_dir.mkdir(parents=True, exist_ok=True)
                hold(run_dir, "the job's directory")
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
                release(run_dir)


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


class Preflight(Callback):
    """Checks that need no work, before Hydra creates a directory (Hydra writes .hydra/ there first): a single
    job's own checks (``check``, which each command's subclass gives) and no completed run of other overrides in
    its run directory; a re-run sweep's overrides against those the sweep directory was made with. A refusal is
    one line and exit status 2 (a callback's exception would only be a warning to Hydra)."""

    def check(self, cfg: DictConfig, overrides: list[str]) -> None:
        """The command's checks of a single job's config (without Hydra's section); raise ConfigError."""

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        run_dir, overrides = Path(str(config.hydra.run.dir)), list(config.hydra.overrides.task)
        try:
            self.check(task_config(config), overrides)
            make_dir(run_dir, "hydra.run.dir")
            hold(run_dir, "hydra.run.dir")  # before Hydra writes .hydra/ there: one writer per directory
            RunDir(run_dir).previous_record(overrides)  # a completed run of other overrides
        except (ConfigError, ValueError) as exc:
            fail(str(exc))

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = _state["sweep_dir"] = Path(str(config.hydra.sweep.dir))
        try:
            if is_search(config):  # a search: its space and settings before any trial
                from hybrid_sysid.experiments.search import study_settings

                study_settings(task_config(config), config.hydra.sweeper, config.hydra.overrides.task)
            make_dir(sweep_dir, "hydra.sweep.dir")
            hold(sweep_dir, "hydra.sweep.dir")  # one sweep per directory at a time
        except ConfigError as exc:
            fail(str(exc))
        (sweep_dir / STOP_MARKER).unlink(missing_ok=True)  # a re-run continues an interrupted sweep
        saved = sweep_dir / "multirun.yaml"
        if not saved.is_file():
            return
        try:
            was = _sweep_of(OmegaConf.load(saved))
        except Exception:  # noqa: BLE001 - an unreadable file cannot tell: the jobs' own guards still hold
            return
        if was != _sweep_of(config):
            fail(
                f"hydra.sweep.dir = {sweep_dir} holds a sweep of other overrides ({' '.join(was[0])}); "
                "re-run it with the same ones, or choose another hydra.sweep.dir"
            )


def is_search(config: DictConfig) -> bool:
    """Whether the sweep is a hyperparameter search (the study sweeper, hybrid_sysid.cli.search)."""
    return str(config.hydra.sweeper.get("_target_", "")) == SEARCH_SWEEPER


def sweep_stopped(sweep_dir: Path) -> bool:
    """Whether a signal has come, to this process or (the sweep's mark) to any of the sweep's processes."""
    return _state["received"] is not None or (sweep_dir / STOP_MARKER).exists()


def _sweep_of(cfg: DictConfig) -> tuple:
    """What makes a sweep's jobs: its command-line overrides and the sweeper's parameters (an experiment's)."""
    params = cfg.hydra.sweeper.get("params")
    return sorted(cfg.hydra.overrides.task), OmegaConf.to_container(params) if params is not None else {}


def hold(path: Path, key: str) -> None:
    """This process's one-writer lock of a run or sweep directory, kept until the process ends (or ``release``).
    A DDP rank above 0 (Lightning starts it with the same command, LOCAL_RANK set) shares its rank 0's directory,
    which rank 0 holds."""
    if os.environ.get("LOCAL_RANK", "0") != "0":
        return
    if str(path) not in _state["locks"]:
        _state["locks"][str(path)] = hold_for_writing(path, key)


def release(path: Path) -> None:
    lock = _state["locks"].pop(str(path), None)
    if lock is not None:
        lock.release()


def make_dir(path: Path, key: str) -> None:
    """Hydra would make it next, and print a traceback if it cannot: one line instead."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        fail(f"{key} = {path} cannot be created: {type(exc).__name__}: {exc}")


# an option that needs an optional package -> (the module it needs, the extra that brings it)
EXTRAS = {
    "hparams_search=": ("optuna", "search"),
    "hydra/sweeper=study": ("optuna", "search"),
    "experiment=tuned": ("optuna", "search"),
    "callbacks=rich_progress_bar": ("rich", "rich"),
    "launcher=slurm": ("hydra_plugins.hydra_submitit_launcher", "slurm"),
    "launcher=submitit_local": ("hydra_plugins.hydra_submitit_launcher", "slurm"),
}


def missing_extra(args) -> str | None:
    """A one-line error for the first command-line option whose optional package is not installed (Hydra
    itself would fail on it with a long message on the config search path), else None. The install command
    fits the install: ``pip install -e ".[search]"`` in an editable checkout, ``pip install
    "hybrid-sysid[search]"`` for a wheel (hybrid_sysid.core.install)."""
    for arg in args:
        for prefix, (module, extra) in EXTRAS.items():
            if arg.lstrip("+~").startswith(prefix) and not installed(module):
                name = module.split(".")[-1].replace("_", "-")
                return f"{arg} needs {name}, which is not installed: {install_command(extra)}"
    return None


def installed(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:  # its parent package is missing
        return False


def _summarise_interrupted_sweep() -> None:
    """When a parallel sweep's launcher itself broke off (a worker killed by the signal), the summary of the
    jobs that completed, written here since Hydra's end-of-sweep callback did not run."""
    sweep_dir = _state["sweep_dir"]
    if sweep_dir is None or not sweep_dir.is_dir():
        return
    try:
        from hybrid_sysid.report.summary import write_summary

        write_summary(sweep_dir)
        print(f"sweep interrupted; summary of the jobs that ended in {sweep_dir}", file=sys.stderr)
    except Exception as exc:  # noqa: BLE001 - e.g. no job recorded anything yet
        print(f"sweep interrupted; no summary written ({type(exc).__name__}: {exc})", file=sys.stderr)


def console_main(hydra_main: Callable[[], Any], args: list[str]) -> None:
    """A console script around a Hydra app: exit status 2 for a config that does not compose (unknown key, wrong
    type, unknown group option), a missing optional package or an OS error before any job (Hydra itself exits 1
    for those, like for any failure), and 128 + the signal's number for a job or sweep ended by SIGTERM or
    SIGINT (a sweep's parent passes the signal to its running jobs, which record it)."""
    previous = {s: signal.getsignal(s) for s in SIGNALS}
    for s in SIGNALS:
        signal.signal(s, stop_sweep)
    missing = missing_extra(args)
    if missing:
        fail(missing)
    received = None
    try:
        hydra_main()
    except SystemExit as exc:
        received = _state["received"]
        if received is None and exc.code == 1 and not _state["task_started"]:
            sys.exit(2)
        if received is None:
            raise
    except OSError as exc:
        if _state["task_started"] or os.environ.get("HYDRA_FULL_ERROR") == "1":
            raise
        fail(f"{type(exc).__name__}: {exc}")
    except BaseException:
        if _state["received"] is None:
            raise
        _summarise_interrupted_sweep()
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    received = _state["received"]
    if received is not None:
        sys.exit(128 + received)
