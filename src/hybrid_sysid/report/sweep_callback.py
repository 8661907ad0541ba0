"""Hydra callback that ends every sweep with its comparison table.

Hydra skips on_multirun_end when a job raised, and with the joblib launcher job callbacks run in worker
processes; so jobs record their own failure and return normally (see hybrid_sysid.cli.train), and the summary here is
built from the run records on disk alone. A sweep with a failed job still exits non-zero.

Options, set under hydra.callbacks.sweep_summary: ``reproduction: true`` (conf/experiment/paper.yaml) also
writes reproduction.md, the paper's figures beside ours; ``compare``: the row key the table's marks compare
(default: objective when swept); ``transfer_figure: true`` (conf/experiment/transfer.yaml) also draws
figures/transfer.png; ``exclude``: glob patterns of run names the table leaves out
(conf/experiment/tuned.yaml: its search trials); ``tuning_table: true`` also writes tuning.md, each search's
result, and figures/tuning.png. Other splits, metrics and the LaTeX table are one
``hybrid-sysid-report`` away.

The sweep's console: a line at its start (how many jobs, how many at a time), then one line per finished job
(``on_job_end``, which runs in the job's own process, a parallel worker included): its number of the total, its
swept values, its headline error (test split, the lowest noise level and K, p1 and p2), its time, the sweep's
elapsed time and an estimate of the time left (elapsed / done x remaining). The jobs count themselves in
``.progress`` in the sweep directory. What a job logs goes to its own log file (hybrid_sysid.cli.console).
"""

from __future__ import annotations

import fcntl
import importlib
import json
import logging
import math
import threading
import time
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.core.files import write_atomic

log = logging.getLogger("hybrid_sysid")
# what the sweep's end needs (scipy.stats, matplotlib, pandas: about 2 s of imports). The parent loads them in a
# thread while the jobs run, after its launcher is under way, so the end does not wait for them: about 1% of the
# main job (benchmarks/README.md). A sweep that ends first cancels the load and imports them itself.
REPORT_MODULES = (
    "hybrid_sysid.report.paper",
    "hybrid_sysid.report.summary",
    "hybrid_sysid.report.sweep_figures",
    "hybrid_sysid.report.tables",
    "hybrid_sysid.report.tuning",
    "hybrid_sysid.training.tracking",
)
PRELOAD_AFTER = 5.0  # seconds: Hydra's launcher has imported its own modules and started the jobs by then
_preload: dict = {}  # the thread and its cancel event; module state, as the callback itself is pickled to workers


def _load_report_modules(cancel: threading.Event) -> None:
    if cancel.wait(PRELOAD_AFTER):
        return
    try:
        for name in REPORT_MODULES:
            importlib.import_module(name)
    except Exception:  # noqa: BLE001 - imported again at the sweep's end, where its error is reported
        pass


class SweepSummary(Callback):
    def __init__(
        self,
        reproduction: bool = False,
        compare: str | None = None,
        transfer_figure: bool = False,
        exclude=(),
        tuning_table: bool = False,
    ):
        self.reproduction = reproduction
        self.compare = compare
        self.transfer_figure = transfer_figure
        self.exclude = list(exclude)
        self.tuning_table = tuning_table

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(config.hydra.sweep.dir)
        jobs, swept = sweep_jobs(config)
        try:
            sweep_dir.mkdir(parents=True, exist_ok=True)
            header = {"jobs": jobs, "swept": swept, "start": time.time()}
            (sweep_dir / PROGRESS).write_text(json.dumps(header) + "\n", encoding="utf-8")
        except OSError:  # no progress lines then; the sweep itself reports the directory's problem
            pass
        print(start_line(config, jobs, sweep_dir), flush=True)
        cancel = threading.Event()
        thread = threading.Thread(target=_load_report_modules, args=(cancel,), daemon=True)
        thread.start()
        _preload.update(thread=thread, cancel=cancel)

    def on_job_start(self, config: DictConfig, **kwargs: Any) -> None:
        self._job_start = time.time()

    def on_job_end(self, config: DictConfig, job_return: Any = None, **kwargs: Any) -> None:
        if config.hydra.mode != RunMode.MULTIRUN:
            return
        try:
            header, done = count_done(Path(config.hydra.sweep.dir) / PROGRESS, config.hydra.job.num)
            seconds = time.time() - getattr(self, "_job_start", time.time())
            line = job_line(header, done, config.hydra.job.num, job_return, seconds)
        except Exception as exc:  # noqa: BLE001 - e.g. no .progress (a sweep started elsewhere): the job is done
            log.info("no progress line: %s: %s", type(exc).__name__, exc)
            return
        print(line, flush=True)

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        # imported here: every parallel worker unpickles this callback for on_job_end and needs none of them
        # (scipy.stats and matplotlib, about a second of CPU per worker: benchmarks/README.md); the loading
        # thread is done first, so no module is imported by two threads at once
        if _preload:  # emptied here, so a later sweep of this process starts without it
            _preload.pop("cancel").set()
            _preload.pop("thread").join()
        from hybrid_sysid.report.paper import write_reproduction
        from hybrid_sysid.report.summary import threads_warning, write_summary
        from hybrid_sysid.report.sweep_figures import transfer_figure, tuning_figure
        from hybrid_sysid.report.tables import to_markdown
        from hybrid_sysid.report.tuning import tuning_markdown
        from hybrid_sysid.training.tracking import log_sweep

        sweep_dir = Path(config.hydra.sweep.dir)

        def show(df, table) -> None:  # the table as soon as it is written; the sweep's figures after it
            print(f"\nmean relative deviation on the test split [%], mean ± std over seeds ({sweep_dir}):\n")
            print(to_markdown(table, compare=self.compare), flush=True)
            warning = threads_warning(df)
            if warning:
                log.warning(warning)

        try:
            df, table = write_summary(sweep_dir, compare=self.compare, exclude=self.exclude, on_table=show)
        except Exception as exc:  # Hydra would turn it into a warning and exit 0: the sweep must fail instead
            log.error("sweep summary not written: %s: %s", type(exc).__name__, exc)
            raise SystemExit(f"no summary written in {sweep_dir} ({type(exc).__name__}: {exc})") from exc
        if self.transfer_figure and "scenario" in table.index.names:
            write_atomic(sweep_dir / "figures" / "transfer.png", lambda p: transfer_figure(table, p))
        if self.tuning_table:
            text = tuning_markdown(sweep_dir)
            write_atomic(sweep_dir / "tuning.md", lambda p: p.write_text(text, encoding="utf-8"))
            print(f"\n{text}")
            if "tuning" in table.index.names:
                write_atomic(sweep_dir / "figures" / "tuning.png", lambda p: tuning_figure(table, p))
        if self.reproduction:
            print(write_reproduction(sweep_dir))
            print(f"(written to {sweep_dir / 'reproduction.md'})")
        log_sweep(config, sweep_dir)  # logger=mlflow: the summary and figures into the sweep's experiment
        failed = df[df.status != "completed"].drop_duplicates("run")
        if len(failed):
            for _, row in failed.iterrows():
                log.error("job %s %s: %s", row["run"], row["status"], row["error"])
            raise SystemExit(
                f"{len(failed)} of {df.run.nunique()} jobs failed or were interrupted; summary in {sweep_dir}"
            )


PROGRESS = ".progress"  # in a sweep directory: a JSON line (jobs, swept keys, start), then one line per ended job


def sweep_jobs(config: DictConfig) -> tuple[int | None, list[str]]:
    """The number of jobs of the sweep (None where it cannot be told) and the keys it sweeps: a search's
    n_trials and parameters, else the product of the command line's and hydra.sweeper.params' value lists."""
    sweeper = config.hydra.sweeper
    params = sweeper.get("params")
    params = OmegaConf.to_container(params) if isinstance(params, DictConfig) else dict(params or {})
    if sweeper.get("n_trials") is not None:  # a search (conf/hydra/sweeper/study.yaml)
        return int(sweeper.n_trials), list(params)
    try:
        from hydra.core.override_parser.overrides_parser import OverridesParser

        given = [f"{k}={v}" for k, v in params.items()] + list(config.hydra.overrides.task)
        sizes = {}
        for override in OverridesParser.create().parse_overrides(given):
            key = override.get_key_element()
            sizes[key] = len(list(override.sweep_string_iterator())) if override.is_sweep_override() else 1
    except Exception:  # noqa: BLE001 - e.g. a glob over a config group: no count, the lines say so
        return None, []
    return math.prod(sizes.values()), [k for k, n in sizes.items() if n > 1]


def start_line(config: DictConfig, jobs: int | None, sweep_dir: Path) -> str:
    """The sweep's first line: so the console is never silent while the first jobs train."""
    launcher = config.hydra.launcher
    at_once = launcher.get("n_jobs") if "joblib" in str(launcher.get("_target_", "")) else None
    if at_once is None and "BasicLauncher" in str(launcher.get("_target_", "")):
        at_once = 1
    threads = OmegaConf.select(config, "trainer.threads")
    parts = [f"{jobs} jobs" if jobs else "jobs"]
    if at_once:
        parts.append(f"{at_once} at a time")
    if threads:
        parts.append(f"{threads} torch thread{'s' * (threads != 1)} each")
    return (
        f"sweep: {', '.join(parts)} into {sweep_dir}; a line as each job ends (its messages: train.log in its "
        "directory), then the table"
    )


def count_done(path: Path, num) -> tuple[dict, int]:
    """Append job ``num`` to the progress file and return its header and how many jobs have ended (one lock:
    parallel workers count in turn)."""
    with open(path, "a+", encoding="utf-8") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            f.write(f"{num}\n")
            f.flush()
            f.seek(0)
            lines = f.read().splitlines()
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)
    header = json.loads(lines[0])
    if not isinstance(header, dict):
        raise ValueError(f"{path} has no header")
    return header, len(set(lines[1:]))


def _clock(seconds: float) -> str:
    m, s = divmod(int(round(seconds)), 60)
    return f"{m // 60}:{m % 60:02d}:{s:02d}" if m >= 60 else f"{m}:{s:02d}"


def _short(value: str) -> str:
    try:
        number = float(value)
    except ValueError:
        return value
    return f"{number:.3g}" if len(value) > 8 else value


def job_line(header: dict, done: int, num, job_return: Any, seconds: float) -> str:
    """``[done/jobs] #num key=value ...: p1 .. %, p2 .. % (test, noise .., K=..) in .. s; sweep m:ss, about m:ss
    left``; a failed or interrupted job says so with its error."""
    jobs = header.get("jobs")
    overrides = dict(o.split("=", 1) for o in (getattr(job_return, "overrides", None) or []) if "=" in o)
    swept = header.get("swept") or [k for k in ("objective", "seed") if k in overrides]
    which = " ".join(f"{k}={_short(overrides[k])}" for k in swept if k in overrides)
    record = getattr(job_return, "return_value", None)
    if isinstance(record, BaseException):
        outcome = f"failed ({type(record).__name__}: {record})"
    elif not isinstance(record, dict):
        outcome = "ended"
    elif record.get("status", "completed") != "completed":
        outcome = f"{record['status']} ({record.get('error') or 'no error recorded'})"
    else:
        outcome = headline(record.get("results")) or "completed"
    elapsed = time.time() - float(header.get("start", time.time()))
    count = f"{done}/{jobs}" if jobs else str(done)
    left = ""
    if jobs and done < jobs:
        left = f", about {_clock(elapsed / done * (jobs - done))} left"
    outcome = outcome.splitlines()[0][:160]
    return f"[{count}] #{num} {which}: {outcome} in {seconds:.0f} s; sweep {_clock(elapsed)}{left}"


def headline(results) -> str | None:
    """A record's headline error: mean relative deviation of p1 and p2 on the test split, at its lowest noise
    level and K."""
    rows = [r for r in results or [] if r.get("split") == "test" and "mean_rel_dev" in r]
    if not rows:
        return None
    noise = min(r.get("noise_std", 0) for r in rows)
    k = min(r.get("windows", 1) for r in rows if r.get("noise_std", 0) == noise)
    first = [r for r in rows if r.get("noise_std", 0) == noise and r.get("windows", 1) == k]
    cells = {r["parameter"]: r["mean_rel_dev"] for r in first}
    text = ", ".join(f"{p} {100 * v:.2f} %" for p, v in sorted(cells.items()))
    return f"{text} (test, noise {noise:g}, K={k})"
