"""The Hydra callback that ends every sweep with its comparison table, and prints its progress on the way.

Hydra skips on_multirun_end when a job raised, and with the joblib launcher job callbacks run in worker
processes; so jobs record their own failure and return normally (hybrid_sysid.launch.job), and the summary here is
built from the run records on disk alone (hybrid_sysid.report.summary). A sweep with a failed job still exits
non-zero. What an experiment adds to its table (figures, a table of its searches) comes with the summary
(hybrid_sysid.report.extras).

Options, set under hydra.callbacks.sweep_summary: ``reproduction: true`` (conf/experiment/paper.yaml) also
writes reproduction.md, the paper's figures beside ours; ``compare``: the row key the table's marks compare
(default: objective when swept); ``exclude``: glob patterns of run names the table leaves out
(conf/experiment/tuned.yaml: its search trials). Other splits, metrics and the LaTeX table are one
``hybrid-sysid-report`` away. What a job logs goes to its own log file (hybrid_sysid.launch.console).
"""

from __future__ import annotations

import importlib
import logging
import os
import threading
import time
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from hydra.types import RunMode
from omegaconf import DictConfig

from hybrid_sysid.core import steps
from hybrid_sysid.core.words import count
from hybrid_sysid.launch.progress import (
    count_done,
    header_of,
    job_line,
    mark_start,
    mark_steps,
    record_of,
    start_line,
)
from hybrid_sysid.launch.state import PROCESS
from hybrid_sysid.launch.time_left import work_cpu, work_seconds
from hybrid_sysid.runs.sweepdir import SweepDir
from hybrid_sysid.training.tracking.mlflow_store import log_sweep

log = logging.getLogger("hybrid_sysid")
# what the sweep's end needs (scipy.stats, matplotlib, pandas: seconds of imports). The parent loads them in a
# thread while the jobs run, after its launcher is under way, so the end does not wait for them. A sweep that ends
# first cancels the load and imports them itself.
REPORT_MODULES = (
    "hybrid_sysid.report.paper",
    "hybrid_sysid.report.summary",
    "hybrid_sysid.report.terminal",
    "hybrid_sysid.training.tracking.mlflow_store",
)
PRELOAD_AFTER = 5.0  # seconds: Hydra's launcher has imported its own modules and started the jobs by then


def _load_report_modules(cancel: threading.Event) -> None:
    if cancel.wait(PRELOAD_AFTER):
        return
    try:
        for name in REPORT_MODULES:
            importlib.import_module(name)
    except Exception:  # noqa: BLE001 - imported again at the sweep's end, where its error is reported
        pass


class SweepSummary(Callback):
    def __init__(self, reproduction: bool = False, compare: str | None = None, exclude=()):
        self.reproduction = reproduction
        self.compare = compare
        self.exclude = list(exclude)
        self._preload: tuple[threading.Thread, threading.Event] | None = None  # the parent's, not pickled state

    def __getstate__(self):  # a parallel worker unpickles the callback for on_job_end: no thread goes with it
        return {**self.__dict__, "_preload": None}

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(config.hydra.sweep.dir)
        header = header_of(config, time.time())
        try:
            SweepDir(sweep_dir).start_progress(header)
        except OSError:  # no progress lines then; the sweep itself reports the directory's problem
            pass
        print(start_line(config, header["jobs"], sweep_dir), flush=True)
        cancel = threading.Event()
        thread = threading.Thread(target=_load_report_modules, args=(cancel,), daemon=True)
        thread.start()
        self._preload = (thread, cancel)

    def on_job_start(self, config: DictConfig, **kwargs: Any) -> None:
        self._job_start = time.time()
        self._cold = not PROCESS.jobs  # this process's first job pays its imports (progress: time_left)
        PROCESS.jobs += 1
        if config.hydra.mode == RunMode.MULTIRUN:
            sweep_dir, num = Path(config.hydra.sweep.dir), config.hydra.job.num
            try:
                mark_start(sweep_dir, num, self._job_start, os.getpid())
            except Exception as exc:  # noqa: BLE001 - the estimate then counts the job as not started
                log.info("no progress start: %s: %s", type(exc).__name__, exc)
            given, start = list(config.hydra.overrides.task), self._job_start

            def heard(done: int, total: int) -> None:  # the job's training reports its steps (core.steps)
                line = mark_steps(sweep_dir, num, given, done, total, start, time.time())
                if line:
                    print(line, flush=True)

            steps.listen(heard)

    def on_job_end(self, config: DictConfig, job_return: Any = None, **kwargs: Any) -> None:
        steps.listen(None)
        if config.hydra.mode != RunMode.MULTIRUN:
            return
        try:
            now = time.time()
            seconds = now - getattr(self, "_job_start", now)
            record = record_of(job_return)
            ok = isinstance(record, dict) and record.get("status", "completed") == "completed"
            entry = {"t": now, "seconds": seconds, "cold": getattr(self, "_cold", True), "pid": os.getpid()}
            entry.update(work=work_seconds(record), cpu=work_cpu(record), ok=ok)
            entry.update(trained=bool(ok and record.get("steps")))
            header, done = count_done(Path(config.hydra.sweep.dir), config.hydra.job.num, entry)
            line = job_line(header, done, config.hydra.job.num, job_return, seconds, now)
        except Exception as exc:  # noqa: BLE001 - e.g. no .progress (a sweep started elsewhere): the job is done
            log.info("no progress line: %s: %s", type(exc).__name__, exc)
            return
        print(line, flush=True)

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        # imported here: every parallel worker unpickles this callback for on_job_end and needs none of them; the
        # loading thread is done first, so no module is imported by two threads at once
        PROCESS.summarised = True  # written here or failing here: the process writes no other summary after
        if self._preload is not None:
            thread, cancel = self._preload
            self._preload = None
            cancel.set()
            thread.join()
        from hybrid_sysid.report.paper import write_reproduction  # deferred
        from hybrid_sysid.report.summary import reference_note, threads_warning, write_summary  # deferred
        from hybrid_sysid.report.terminal import to_console  # deferred

        sweep_dir = Path(config.hydra.sweep.dir)

        def show(df, table) -> None:  # the table as soon as it is written; the sweep's figures after it
            # in blocks a terminal shows whole (report.terminal); summary.md has the same cells in one wide table
            print("\nmean relative deviation on the test split [%], mean ± std over seeds [95% t interval]")
            print(f"(the whole table in one: {sweep_dir / 'summary.md'})\n")
            print(to_console(table, compare=self.compare, bound=table.attrs.get("bound")), flush=True)
            for line in reference_note(df, "test")[:1]:
                print(line.replace("`", ""), flush=True)
            warning = threads_warning(df)
            if warning:
                log.warning(warning)

        try:
            df, table = write_summary(sweep_dir, compare=self.compare, exclude=self.exclude, on_table=show)
        except Exception as exc:  # Hydra would turn it into a warning and exit 0: the sweep must fail instead
            log.error("sweep summary not written: %s: %s", type(exc).__name__, exc)
            raise SystemExit(f"no summary written in {sweep_dir} ({type(exc).__name__}: {exc})") from exc
        for text in table.attrs.get("sections", []):  # what an experiment adds in words (experiment=tuned's searches)
            print(f"\n{text}")
        if self.reproduction:
            print(write_reproduction(sweep_dir))
            print(f"(written to {sweep_dir / 'reproduction.md'})")
        log_sweep(config, sweep_dir)  # logger=mlflow: the summary and figures into the sweep's experiment
        failed = df[df.status != "completed"].drop_duplicates("run")
        if len(failed):
            for _, row in failed.iterrows():
                log.error("job %s %s: %s", row["run"], row["status"], row["error"])
            raise SystemExit(
                f"{len(failed)} of {count(df.run.nunique(), 'job')} failed or {'was' if len(failed) == 1 else 'were'} "
                f"interrupted; summary in {sweep_dir}"
            )
