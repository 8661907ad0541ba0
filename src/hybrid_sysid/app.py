"""The Hydra application behind ``hybrid-sysid``: compose the config, check it, run ``train``, draw the run's figures.

Each job records its own failure or interruption in its run directory (Hydra skips ``on_multirun_end`` when a
job raises), so a sweep goes on and its summary lists the job. A single run's config is checked before Hydra
creates its directory (``Preflight``), so a rejected value or resume leaves nothing behind.

Under a hyperparameter search (hydra-optuna-sweeper, conf/hparams_search) a job returns one number: the
validation figure its model selection used (``best_score`` of its record: val/loss for a label-free objective,
val/rel_dev otherwise; trainer.monitor). A failed job returns None, which the sweeper cannot cast to a number:
it records a failed trial and the study goes on (a NaN would stop the whole study in optuna's ``tell``).
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
from typing import Any

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.experimental.callback import Callback
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf, open_dict, read_write

from hybrid_sysid import config
from hybrid_sysid.config import ConfigError, check_resume, validate
from hybrid_sysid.records import (CompletedRecordError, completed_record, previous_record, run_record,
                                  write_record)

log = logging.getLogger("hybrid_sysid")
_task_started = False
SIGNALS = (signal.SIGTERM, signal.SIGINT)
STOP_MARKER = ".interrupted"  # in a sweep directory: the sweep was interrupted, jobs not yet started skip
_received: int | None = None  # the first termination signal this process received
_raised = False  # whether the running job was already interrupted
_sweep_dir: Path | None = None


class Interrupted(BaseException):
    """A termination signal (SIGTERM: SLURM's time limit, ``timeout``, ``docker stop``; SIGINT: Ctrl-C) during a
    job. A BaseException, as KeyboardInterrupt is, so no ``except Exception`` on the way swallows it."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _raise_once(signum, frame):
    global _received, _raised
    _received = _received or signum
    if not _raised:  # a second signal (Ctrl-C twice) must not cut the writing of the record short
        _raised = True
        raise Interrupted(signum)


@contextmanager
def interruptible():
    """Within: SIGTERM and SIGINT raise Interrupted (Lightning, which installs its own SIGTERM handler during
    fit, calls this one after its own, then tears down and re-raises). The previous handlers return after."""
    global _raised
    _raised = False
    previous = {s: signal.getsignal(s) for s in SIGNALS}
    for s in SIGNALS:
        signal.signal(s, _raise_once)
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


def _stop_sweep(signum, frame):
    """The handler of a process between jobs (a sweep's parent): remember the signal, mark the sweep as
    interrupted so jobs not yet started skip, and pass the signal to the running jobs (parallel workers), which
    record their interruption and return; Hydra then ends the sweep with its summary."""
    global _received
    first = _received is None
    _received = _received or signum
    if first and _sweep_dir is not None and _sweep_dir.is_dir():
        (_sweep_dir / STOP_MARKER).touch()
    if first:
        for pid in _children():
            try:
                os.kill(pid, signum)
            except OSError:
                pass


def _stopped(sweep_dir: Path | None) -> bool:
    """A signal came before this job started (this process, or, through the marker, the sweep's parent)."""
    return _received is not None or (sweep_dir is not None and (sweep_dir / STOP_MARKER).exists())


def _fail(message: str, status: int = 2):
    print(f"error: {message}", file=sys.stderr)
    if os.environ.get("HYDRA_FULL_ERROR") == "1":
        traceback.print_exc()
    sys.exit(status)


def _task_config(cfg: DictConfig) -> DictConfig:
    task = copy.deepcopy(cfg)
    with read_write(task), open_dict(task):
        del task["hydra"]
    return task


class Preflight(Callback):
    """Checks that need no work, before Hydra creates a directory: a single run's values (``validate``, which
    includes the size against the memory available), its ``resume=`` directory, and a completed run in the run
    directory; a re-run sweep's overrides against those the sweep directory was made with. A refusal is one
    line and exit status 2 (a callback's exception would only be a warning to Hydra)."""

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        task = _task_config(config)
        overrides = list(config.hydra.overrides.task)
        run_dir = Path(str(config.hydra.run.dir))
        try:
            validate(task)
            if task.get("resume"):
                check_resume(Path(str(task.resume)), task)
            previous_record(run_dir, overrides)  # raises for a completed run of other overrides
        except (ConfigError, ValueError) as exc:
            _fail(str(exc))
        _make_dir(run_dir, "hydra.run.dir")

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        global _sweep_dir
        _sweep_dir = Path(str(config.hydra.sweep.dir))
        _make_dir(_sweep_dir, "hydra.sweep.dir")
        (_sweep_dir / STOP_MARKER).unlink(missing_ok=True)  # a re-run continues an interrupted sweep
        saved = _sweep_dir / "multirun.yaml"
        if not saved.is_file():
            return
        try:
            was = _sweep_of(OmegaConf.load(saved))
        except Exception:  # noqa: BLE001 - an unreadable file cannot tell: the jobs' own guards still hold
            return
        now = _sweep_of(config)
        if was != now:
            _fail(f"hydra.sweep.dir = {_sweep_dir} holds a sweep of other overrides ({' '.join(was[0])}); "
                  "re-run it with the same ones, or choose another hydra.sweep.dir")


def _sweep_of(cfg: DictConfig) -> tuple:
    """What makes a sweep's jobs: its command-line overrides and the sweeper's parameters (an experiment's)."""
    params = cfg.hydra.sweeper.get("params")
    return sorted(cfg.hydra.overrides.task), OmegaConf.to_container(params) if params is not None else {}


def _make_dir(path: Path, key: str) -> None:
    """Hydra would make it next, and print a traceback if it cannot: one line instead."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        _fail(f"{key} = {path} cannot be created: {type(exc).__name__}: {exc}")


# an option that needs an optional package -> (the module it needs, the install that brings it)
EXTRAS = {
    "hparams_search=": ("hydra_plugins.hydra_optuna_sweeper", 'pip install -e ".[search]"'),
    "hydra/sweeper=optuna": ("hydra_plugins.hydra_optuna_sweeper", 'pip install -e ".[search]"'),
    "experiment=tuned": ("optuna", 'pip install -e ".[search]"'),
    "launcher=slurm": ("hydra_plugins.hydra_submitit_launcher", 'pip install -e ".[slurm]"'),
    "launcher=submitit_local": ("hydra_plugins.hydra_submitit_launcher", 'pip install -e ".[slurm]"'),
}


def missing_extra(args) -> str | None:
    """A one-line error for the first command-line option whose optional package is not installed (Hydra
    itself would fail on it with a long message on the config search path), else None."""
    for arg in args:
        for prefix, (module, install) in EXTRAS.items():
            if arg.lstrip("+~").startswith(prefix) and not _installed(module):
                return f"{arg} needs {module.split('.')[-1].replace('_', '-')}, which is not installed: {install}"
    return None


def _installed(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:  # its parent package is missing
        return False


def search_value(record: dict) -> float | None:
    """What a job returns to a hyperparameter search: its model-selection figure, None if it has none."""
    value = record.get("best_score")
    return None if value is None else float(value)


@hydra.main(version_base="1.3", config_path=config.CONF_DIR, config_name="config")
def hydra_main(cfg: DictConfig) -> dict | float | None:
    global _task_started
    _task_started = True
    hc = HydraConfig.get()
    run_dir = Path(hc.runtime.output_dir)
    overrides = list(hc.overrides.task)
    multirun = hc.mode == RunMode.MULTIRUN
    seed = cfg.get("seed", 0)
    if multirun and threading.current_thread() is threading.main_thread():
        # a parallel worker (or the basic launcher's own process): between its jobs a signal must not kill it,
        # or the launcher drops the jobs not yet started; remembered, it makes them record their interruption
        for s in SIGNALS:
            signal.signal(s, _stop_sweep)
    searching = "optuna" in str(hc.sweeper.get("_target_", ""))
    # in a tracker, a sweep's jobs are runs of one experiment named after the sweep directory
    experiment = Path(hc.sweep.dir).name if multirun else None
    run_name = hc.job.override_dirname or None
    sweep_dir = Path(hc.sweep.dir) if multirun else None
    if _stopped(sweep_dir):  # a signal came while Hydra composed and launched: do not start
        name = signal.Signals(_received).name if _received else "the sweep's interruption"
        result = record_end(run_dir, overrides, seed, "interrupted", f"not started: interrupted by {name}")
        if not multirun:
            sys.exit(128 + _received)
        return None if searching else result
    with interruptible():
        try:
            # imported here: a sweep's parent process composes and launches jobs, and need not load torch for it
            from hybrid_sysid.train import train

            if cfg.get("transfer"):  # experiment=transfer: a chain of runs in this job's directory
                from hybrid_sysid.transfer import run_chain

                return run_chain(cfg, run_dir, overrides)
            if cfg.get("tuned"):  # experiment=tuned: a search and the runs of its default and best values
                from hybrid_sysid.tuned import run_tuned

                return run_tuned(cfg, run_dir, overrides)
            record = train(cfg, run_dir, overrides, experiment=experiment, run_name=run_name)
        except Interrupted as exc:
            result = _interrupted(run_dir, overrides, seed, exc.signum, sweep_dir)
            return None if searching else result
        except Exception as exc:  # record the failure where the sweep summary will look for it
            error = f"{type(exc).__name__}: {exc}"
            record_end(run_dir, overrides, seed, "failed", error)
            if multirun:  # let the other jobs run; the sweep summary exits non-zero
                log.error("job failed: %s", error)
                return None if searching else {"status": "failed", "error": error}
            if isinstance(exc, (ConfigError, CompletedRecordError)) and os.environ.get("HYDRA_FULL_ERROR") != "1":
                _fail(str(exc))  # a bad value: one line, no traceback
            if isinstance(exc, OSError) and os.environ.get("HYDRA_FULL_ERROR") != "1":
                _fail(f"{error} (run directory {run_dir})", status=1)  # e.g. a full disk: one line
            raise
    if record.get("rank", 0) == 0:  # with DDP, rank 0 alone has the record
        _draw_figures(run_dir)
    return search_value(record) if searching else record


def _draw_figures(run_dir: Path) -> None:
    """The run's figures, from its files; the run is complete without them, so a failure here is a warning."""
    try:
        from hybrid_sysid.report.run_figures import write_run_figures

        write_run_figures(run_dir)
    except Exception as exc:  # noqa: BLE001 - e.g. a full disk: the record already holds every number
        log.warning("run figures not drawn in %s: %s: %s", run_dir, type(exc).__name__, exc)


def record_end(run_dir: Path, overrides, seed, status: str, error: str) -> dict:
    """Record a failed or interrupted job, unless the directory holds a completed run (never replaced). A record
    that cannot be written (a full disk) is reported on one line instead."""
    if completed_record(run_dir) is None:
        try:
            run_dir.mkdir(parents=True, exist_ok=True)
            write_record(run_dir, run_record(status, overrides, seed, error=error))
        except (OSError, CompletedRecordError) as exc:
            print(f"error: could not record the {status} job in {run_dir}: {type(exc).__name__}: {exc}",
                  file=sys.stderr)
    return {"status": status, "error": error}


def _interrupted(run_dir: Path, overrides, seed, signum: int, sweep_dir: Path | None) -> dict:
    name = signal.Signals(signum).name
    result = record_end(run_dir, overrides, seed, "interrupted", f"interrupted by {name}")
    log.error("%s: interrupted by %s; continue it with resume=%s (a sweep: run the same command again)",
              run_dir, name, run_dir)
    if sweep_dir is None:
        sys.exit(128 + signum)
    if sweep_dir.is_dir():  # jobs of this sweep not yet started skip, in this process and in other workers
        (sweep_dir / STOP_MARKER).touch()
    return result


def _summarise_interrupted_sweep() -> None:
    """When a parallel sweep's launcher itself broke off (a worker killed by the signal), the summary of the
    jobs that completed, written here since Hydra's end-of-sweep callback did not run."""
    if _sweep_dir is None or not _sweep_dir.is_dir():
        return
    try:
        from hybrid_sysid.report.summary import write_summary

        write_summary(_sweep_dir)
        print(f"sweep interrupted; summary of the jobs that ended in {_sweep_dir}", file=sys.stderr)
    except Exception as exc:  # noqa: BLE001 - e.g. no job recorded anything yet
        print(f"sweep interrupted; no summary written ({type(exc).__name__}: {exc})", file=sys.stderr)


def main() -> None:
    """Console script: Hydra's app, with exit status 2 for a config that does not compose (unknown key, wrong
    type, unknown group option) or an OS error before any job (Hydra itself exits 1 for those, like for any
    failure), and 128 + the signal's number for a run or sweep ended by SIGTERM or SIGINT."""
    previous = {s: signal.getsignal(s) for s in SIGNALS}
    for s in SIGNALS:
        signal.signal(s, _stop_sweep)
    missing = missing_extra(sys.argv[1:])
    if missing:
        print(f"error: {missing}", file=sys.stderr)
        sys.exit(2)
    try:
        hydra_main()
    except SystemExit as exc:
        if _received is not None:
            sys.exit(128 + _received)
        if exc.code == 1 and not _task_started:
            sys.exit(2)
        raise
    except OSError as exc:
        if _task_started or os.environ.get("HYDRA_FULL_ERROR") == "1":
            raise
        _fail(f"{type(exc).__name__}: {exc}")
    except BaseException:
        if _received is None:
            raise
        _summarise_interrupted_sweep()
        sys.exit(128 + _received)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    if _received is not None:
        sys.exit(128 + _received)


if __name__ == "__main__":
    main()
