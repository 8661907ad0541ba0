"""One command's process: how it takes termination signals, and its exit status.

Exit statuses: 0 done; 1 a failure during the work; 2 a value refused (one line on stderr), a config that does
not compose or an OS error before any job; 128 + the signal's number for a job or sweep ended by SIGTERM or SIGINT.

Within a job, SIGTERM and SIGINT only request a stop that the work's safe points raise (core.stop); between jobs
(a sweep's parent, a parallel worker) they mark the sweep interrupted, so jobs not yet started skip, and pass the
signal to the running jobs, which record their interruption. An option whose optional package is missing is one
line before Hydra starts (``missing_extra``).
"""

from __future__ import annotations

import importlib.util
import os
import signal
import sys
import traceback
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable

from hydra.core.override_parser.overrides_parser import OverridesParser

from hybrid_sysid.config.composition import composition_error
from hybrid_sysid.config.loggers import validate_callbacks, validate_loggers
from hybrid_sysid.core import stop
from hybrid_sysid.core.install import install_command
from hybrid_sysid.core.overrides import parse_override
from hybrid_sysid.launch.console import tolerant_streams
from hybrid_sysid.launch.overrides import quoted_overrides
from hybrid_sysid.launch.state import PROCESS
from hybrid_sysid.runs.sweepdir import SweepDir

SIGNALS = (signal.SIGTERM, signal.SIGINT)


# an option that needs an optional package -> (the module it needs, or modules any one of which will do, and the
# extra that brings it)
EXTRAS = {
    "logger=mlflow": ("mlflow", "loggers"),
    "logger=tensorboard": (("tensorboard", "tensorboardX"), "loggers"),
    "hparams_search=": ("optuna", "search"),
    "hydra/sweeper=study": ("optuna", "search"),
    "experiment=tuned": ("optuna", "search"),
    "callbacks=rich_progress_bar": ("rich", "rich"),
    "launcher=slurm": ("hydra_plugins.hydra_submitit_launcher", "slurm"),
    "launcher=submitit_local": ("hydra_plugins.hydra_submitit_launcher", "slurm"),
}


def missing_extra(args) -> str | None:
    """A one-line error for the first command-line option whose optional package is not installed (Hydra itself
    would fail on it with a long message on the config search path), else None. The pip command fits the user's
    own install: ``pip install -e ".[search]"`` in an editable checkout, ``pip install "hybrid-sysid[search]"``
    for a wheel (hybrid_sysid.core.install)."""
    for arg in args:
        for prefix, (modules, extra) in EXTRAS.items():
            modules = (modules,) if isinstance(modules, str) else modules
            if parse_override(arg).unprefixed.startswith(prefix) and not any(installed(m) for m in modules):
                name = modules[0].split(".")[-1].replace("_", "-")
                return f"{arg} needs {name}, which is not installed: {install_command(extra)}"
    return None


def missing_extra_of_sweep(overrides, task) -> str | None:
    """``missing_extra`` for every value of a swept choice among the sweep's command-line ``overrides``
    (``logger=csv,mlflow`` is ``logger=csv`` and ``logger=mlflow``), and the packages of the loggers and callbacks
    its config ``task`` (without Hydra's section) holds where those groups are not swept: so a sweep missing one
    is one line before any job starts, not every job failing."""
    args, swept = [], set()
    for override in OverridesParser.create().parse_overrides(list(overrides)):
        key = override.get_key_element()
        if not override.is_sweep_override():
            args.append(override.input_line)
            continue
        swept.add(parse_override(key).group)
        try:
            args += [f"{key}={value}" for value in override.sweep_string_iterator()]
        except Exception:  # noqa: BLE001 - a range or interval of numbers: no choice of a package there
            continue
    missing = missing_extra(args)
    if missing:
        return missing
    for group, check in (("logger", validate_loggers), ("callbacks", validate_callbacks)):
        if group not in swept:  # a swept group's default, which no job uses, is not checked
            try:
                check(task)
            except ValueError as exc:
                return str(exc)
    return None


def installed(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:  # its parent package is missing
        return False


def _request_stop(signum, frame):
    """Within a job: remember the signal; the work raises Interrupted at its next safe point (core.stop)."""
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


def children() -> list[int]:
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


def catches_sigterm(pid: int) -> bool:
    """Whether the process has a handler of its own for SIGTERM (/proc's SigCgt mask): a parallel worker has one
    from its first job on (``run_job``), not while it still starts up and imports."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("SigCgt:"):
                return bool(int(line.split()[1], 16) >> (signal.SIGTERM - 1) & 1)
    except (OSError, ValueError, IndexError):
        pass
    return False


def stop_sweep(signum, frame):
    """The handler of a process between jobs (a sweep's parent, a parallel worker): remember the signal, mark the
    sweep as interrupted so jobs not yet started skip, and pass the signal to the running jobs (parallel workers),
    which record their interruption and return; Hydra then ends the sweep with its summary. A worker still
    starting up gets no signal, which would kill it (joblib would then break off the sweep with a traceback and
    no job record): it finds the mark at its first job, which records its interruption without running. The mark
    is made first, so a worker is either signalled or finds it."""
    first = stop.received() is None
    stop.note(signum)
    if first and PROCESS.sweep_dir is not None:
        SweepDir(PROCESS.sweep_dir).mark_stopped()
    if first:
        for pid in children():
            if not catches_sigterm(pid):
                continue
            try:
                os.kill(pid, signum)
            except OSError:
                pass


def sweep_stopped(sweep_dir: Path) -> bool:
    """Whether a signal has come, to this process or (the sweep's mark) to any of the sweep's processes."""
    return stop.received() is not None or SweepDir(sweep_dir).stopped()


# set beside HYDRA_FULL_ERROR by composition_in_one_line, so its own setting (inherited by a sweep's workers too)
# is not taken for a user's request for full tracebacks
SET_HERE = "HYBRID_SYSID_SET_FULL_ERROR"


def full_error() -> bool:
    """Whether the user asked for Hydra's full tracebacks (HYDRA_FULL_ERROR=1)."""
    return os.environ.get("HYDRA_FULL_ERROR") == "1" and os.environ.get(SET_HERE) != "1"


def fail(message: str, status: int = 2):
    print(f"error: {message}", file=sys.stderr)
    if full_error():
        traceback.print_exc()
    sys.exit(status)


def _summarise_interrupted_sweep() -> None:
    """When a parallel sweep's launcher itself broke off (a worker killed by the signal), the summary of the
    jobs that completed, written here since Hydra's end-of-sweep callback did not run."""
    sweep_dir = PROCESS.sweep_dir
    if sweep_dir is None or not sweep_dir.is_dir() or PROCESS.summarised:
        return
    try:
        from hybrid_sysid.report.summary import write_summary  # deferred

        write_summary(sweep_dir)
        print(f"sweep interrupted; summary of the jobs that ended in {sweep_dir}", file=sys.stderr)
    except Exception as exc:  # noqa: BLE001 - e.g. no job recorded anything yet
        print(f"sweep interrupted; no summary written ({type(exc).__name__}: {exc})", file=sys.stderr)


@contextmanager
def composition_in_one_line():
    """Within: a config that does not compose (an unknown option, a wrong type, an unknown key) is one line naming
    its key, exit status 2 (config/composition.py), not Hydra's lines of options and search path. Hydra re-raises
    its app's exceptions instead of printing them where HYDRA_FULL_ERROR=1 (its documented switch), so it is set
    here and the exceptions reach this block; any other exception is printed with its traceback, exit 1, as Hydra
    would. A user's own HYDRA_FULL_ERROR=1 keeps every exception as it is."""
    users = os.environ.get("HYDRA_FULL_ERROR")
    if users != "1":
        os.environ.update({"HYDRA_FULL_ERROR": "1", SET_HERE: "1"})
    try:
        yield
    except Exception as exc:
        if users == "1":
            raise
        error = None if PROCESS.job_started else composition_error(exc)
        if error is not None:
            fail(str(error))
        if isinstance(exc, OSError):  # console_main's own line (an OS error before any job)
            raise
        traceback.print_exception(exc)
        sys.exit(1)
    finally:
        if users != "1":
            os.environ.pop(SET_HERE, None)
            if users is None:
                os.environ.pop("HYDRA_FULL_ERROR", None)
            else:
                os.environ["HYDRA_FULL_ERROR"] = users


def console_main(hydra_main: Callable[[], Any], args: list[str]) -> None:
    """A console script around a Hydra app: exit status 2 for a config that does not compose (unknown key, wrong
    type, unknown group option), a missing optional package or an OS error before any job (Hydra itself exits 1
    for those, like for any failure), and 128 + the signal's number for a job or sweep ended by SIGTERM or
    SIGINT (a sweep's parent passes the signal to its running jobs, which record it)."""
    tolerant_streams()
    sys.argv[1:] = quoted_overrides(sys.argv[1:])  # Hydra reads sys.argv: a path outside ASCII, quoted
    previous = {s: signal.getsignal(s) for s in SIGNALS}
    for s in SIGNALS:
        signal.signal(s, stop_sweep)
    missing = missing_extra(args)
    if missing:
        fail(missing)
    try:
        with composition_in_one_line():
            hydra_main()
    except SystemExit as exc:
        if stop.received() is None and exc.code == 1 and not PROCESS.job_started:
            sys.exit(2)
        if stop.received() is None:
            raise
        _summarise_interrupted_sweep()  # unless the sweep's end wrote it: Hydra broke off before (a worker killed)
    except OSError as exc:
        if PROCESS.job_started or full_error():
            raise
        fail(f"{type(exc).__name__}: {exc}")
    except BaseException:
        if stop.received() is None:
            raise
        _summarise_interrupted_sweep()
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    received = stop.received()
    if received is not None and PROCESS.completed is not None:
        # the work it would have stopped is done and recorded: the status says so, not the signal
        name = signal.Signals(received).name
        print(f"{name} received after the run completed; its record in {PROCESS.completed} is whole", file=sys.stderr)
        return
    if received is not None:
        sys.exit(128 + received)
