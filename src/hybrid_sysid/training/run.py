"""One run: build the data and the model, fit, score the best checkpoint, write the run record.

Three kinds of run share one start (``Job.open``: the record of a run already completed here, the directory, the
thread count) and one end (``Job.finish``: score, write predictions, curves and the record, close the trackers,
print the table): ``train`` (a network), a baseline (``baseline=``, no training) and ``evaluate_checkpoint`` (a
trained run's network on other data). Each hands the end an ``Outcome``: the estimator, its data and what the record
says of its training. They are plain Python on a composed config (tests call them in process); the command-line
entry points are hybrid_sysid.cli.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import lightning as L
import pandas as pd
import torch
from omegaconf import DictConfig

from hybrid_sysid.config import validate
from hybrid_sysid.config.targets import plugin_fields
from hybrid_sysid.core import stop
from hybrid_sysid.core.checks import Shown, bad
from hybrid_sysid.core.ranks import is_global_zero
from hybrid_sysid.model.base import SplitPredictor
from hybrid_sysid.runs.provenance import provenance_fields
from hybrid_sysid.runs.resume import resume_checkpoint, uncompared
from hybrid_sysid.runs.rundir import RunDir, is_completed, run_record
from hybrid_sysid.training.build import (
    build_baseline,
    build_callbacks,
    build_datamodule,
    build_model,
    build_objective,
    build_trainer,
    load_network,
    monitor_of,
)
from hybrid_sysid.training.callbacks import CURVE_COLUMNS, LearningCurves, RunCheckpoint, TrainingClock
from hybrid_sysid.training.evaluation import by_road_class, class_table, console_table, score
from hybrid_sysid.training.threads import keeps_thread_count
from hybrid_sysid.training.tracking import Naming, build_loggers, finish, hyperparameters

log = logging.getLogger("hybrid_sysid")


@dataclass
class Outcome:
    """What a run hands to its end: the estimator to score, the data module it is scored on, the optimiser steps
    and learning-curve rows of its training, a line for the console and the record's fields of its kind."""

    model: SplitPredictor
    dm: object
    steps: int = 0
    curves: list[dict] = field(default_factory=list)
    what: str = ""
    fields: dict = field(default_factory=dict)
    rank: int = 0  # with DDP, the process's global rank: only rank 0 scores and writes

    def summary(self) -> str:
        return self.what

    def record_fields(self) -> dict:
        """The record's fields of this kind of run, read once the scores are in."""
        return dict(self.fields)


@dataclass
class BaselineOutcome(Outcome):
    """A baseline's: its fits run while it is scored, so their time is read after scoring."""

    def summary(self) -> str:
        return f"{self.what}, fits in {self.model.fit_seconds:.2f} s"

    def record_fields(self) -> dict:
        seconds, cpu = self.model.fit_seconds, getattr(self.model, "fit_cpu_seconds", None)  # a plugin's may lack it
        cpu = None if cpu is None else round(cpu, 2)
        times = {"train_seconds": seconds, "fit_seconds": round(seconds, 2), "fit_cpu_seconds": cpu}
        return times | {"monitor": None, "best_checkpoint": None}


@dataclass
class Job:
    """A run being made: its config, its directory, the overrides it was asked with and its trackers."""

    cfg: DictConfig
    run: RunDir
    overrides: list[str]
    loggers: Sequence = ()

    @classmethod
    def open(cls, cfg: DictConfig, run_dir, overrides) -> tuple[Job, dict | None]:
        """The start every run shares: the record of a run of these overrides already completed here (then nothing
        else is done), else the directory made and the thread count set."""
        job = cls(cfg, RunDir(run_dir), list(overrides))
        done = job.run.previous_record(job.overrides)
        if done is not None:
            log.info("run %s already completed; not running it again", job.run.path)
            return job, done
        job.run.path.mkdir(parents=True, exist_ok=True)
        if cfg.trainer.get("threads"):
            torch.set_num_threads(int(cfg.trainer.threads))
        return job, None

    def finish(self, outcome: Outcome) -> dict:
        """The end every run shares: score the model on the noise levels and K values of the config, write
        predictions.csv, curves.csv and the record, close the trackers, print the table. Returns the record."""
        stop.check()  # a safe point: a termination signal swallowed during the work ends the run here
        cfg = self.cfg
        threads = torch.get_num_threads()  # recorded: the numbers depend on it (docs/reliability/reproducibility.md)
        ks = [int(k) for k in cfg.evaluation.windows]
        results, predictions = score(outcome.model, outcome.dm, noise_levels(cfg), ks)
        self.run.write_tables(predictions, pd.DataFrame(outcome.curves, columns=CURVE_COLUMNS))
        classes = by_road_class(predictions)
        record = run_record(
            "completed",
            self.overrides,
            cfg.seed,
            tags=list(cfg.get("tags") or []),  # the user's labels of the run (config/tags.py)
            steps=outcome.steps,
            results=results,
            threads=threads,
            by_road_class=classes,
            **provenance_fields(),  # the code and the processor that made the numbers, read once per process
            **plugin_fields(cfg),  # the plugin classes it was made with: opened without them, it names their package
            **outcome.record_fields(),
            **getattr(outcome.dm, "record_fields", dict)(),  # a user's recordings: their files' fingerprint
        )
        stop.check()  # the last safe point before the run is final
        self.run.write_record(record)
        finish(self.loggers, results, outcome.steps)
        log.info("run %s: %s\n%s\n%s", self.run.path, outcome.summary(), console_table(results), class_table(classes))
        return record


@keeps_thread_count
def train(
    cfg: DictConfig,
    run_dir: str | Path,
    overrides=(),
    experiment: str | Naming | None = None,
    run_name: str | None = None,
    checked: bool = False,
) -> dict:
    """Fit and evaluate one configuration (or evaluate its baseline); write metrics.json, curves.csv,
    predictions.csv. ``experiment`` and ``run_name`` name the run in an experiment tracker
    (hybrid_sysid.training.tracking.build_loggers). ``checked``: the caller has validated ``cfg`` (the command
    line's preflight, a chain that validates every run before the first), so it is not validated again.

    With several devices (DDP) every rank trains on its own window stream; rank 0 alone evaluates and writes,
    and the other ranks return {"status": "completed", "rank": r} without a record."""
    if not checked:
        validate(cfg)  # every check before any work
    init = cfg.get("init_from")
    model = None
    if init:  # before any directory is made or data simulated: a network that does not fit fails here
        model = build_model(cfg)
        log.info("starting from the weights of %s", load_network(model.net, cfg, Path(init), "init_from"))
    job, done = Job.open(cfg, run_dir, overrides)
    if done is not None:
        return done
    for message in uncompared():  # resume='s warning, on stderr already: the run's log file keeps it too
        to_log_file(message)
    L.seed_everything(cfg.seed, workers=True)  # 0 included
    if cfg.get("logger") and is_global_zero():  # experiment trackers (with DDP, global rank 0's alone)
        job.loggers = build_loggers(cfg, job.run.path, experiment, run_name, overrides)
        for logger in job.loggers:
            logger.log_hyperparams(hyperparameters(cfg))
    if cfg.get("baseline") is not None:
        return job.finish(_baseline(cfg))
    outcome = _fit(job, model)
    if outcome.rank != 0:
        return {"status": "completed", "rank": outcome.rank}
    if init:
        outcome.fields["init_from"] = str(init)
    return job.finish(outcome)


def _fit(job: Job, model=None) -> Outcome:
    """Train the model (built here from the config when None) with the run's Trainer and load its best checkpoint
    (rank 0 alone, with DDP). The data, the callbacks and the Trainer come first, the model last."""
    cfg = job.cfg
    objective = build_objective(cfg) if model is None else model.objective
    dm = build_datamodule(cfg, objective)
    monitor = monitor_of(cfg, objective)
    ckpt = RunCheckpoint(
        dirpath=job.run.checkpoints,
        filename="best",
        monitor=monitor,
        mode="min",
        save_last=True,
        auto_insert_metric_name=False,
    )
    clock = TrainingClock()
    curve_std = cfg.noise.get("curve_std")
    curve_levels = noise_levels(cfg) if curve_std is None else [float(s) for s in curve_std]
    curves = LearningCurves(clock, curve_levels, every_n_steps=cfg.trainer.get("curve_every_n_steps"))
    trainer = build_trainer(cfg, job.run.path, [clock, curves, ckpt, *build_callbacks(cfg, monitor)], job.loggers)
    model = build_model(cfg, objective) if model is None else model
    dm.setup("fit")
    last = resume_checkpoint(job.run)
    if last is not None:
        log.info("resuming from %s", last)
    start, cpu = time.perf_counter(), time.process_time()
    trainer.fit(model, datamodule=dm, ckpt_path=str(last) if last is not None else None)
    fit_seconds, fit_cpu = time.perf_counter() - start, time.process_time() - cpu
    if trainer.global_rank != 0:
        return Outcome(model, dm, rank=trainer.global_rank)
    if ckpt.best_model_path:
        state = torch.load(ckpt.best_model_path, map_location="cpu", weights_only=True)["state_dict"]
        model.load_state_dict(state)
    train_seconds = clock.seconds  # evaluations excluded, the time before a resume included
    return Outcome(
        model,
        dm,
        trainer.global_step,
        curves.rows,
        f"{trainer.global_step} steps in {train_seconds:.1f} s",
        {
            "train_seconds": train_seconds,
            "monitor": monitor,
            "best_checkpoint": Path(ckpt.best_model_path).name or None,
            "best_score": None if ckpt.best_model_score is None else float(ckpt.best_model_score),
            "devices": trainer.world_size,
            "fit_seconds": round(fit_seconds, 2),
            "fit_cpu_seconds": round(fit_cpu, 2),
        },
    )


def _baseline(cfg: DictConfig) -> BaselineOutcome:
    """A baseline without a network (``baseline=``, e.g. least squares): no Lightning, no training. Its record
    has the same form as a network run's, with steps 0 and train_seconds = the time of its fits (all done while
    scoring); curves.csv has the header only (no learning curve)."""
    estimator = build_baseline(cfg)
    dm = build_datamodule(cfg)
    dm.setup()
    return BaselineOutcome(estimator, dm, what=f"baseline {cfg.baseline._target_}")


@keeps_thread_count
def evaluate_checkpoint(
    cfg: DictConfig, source: str | Path, run_dir: str | Path, overrides=(), checked: bool = False
) -> dict:
    """Score the trained network of the run ``source`` on the data of ``cfg`` (its saved config with other data,
    car, road, noise or evaluation: hybrid_sysid.cli.evaluate), without training; write the record (naming the
    source run), predictions.csv and an empty curves.csv into ``run_dir``."""
    if not checked:
        validate(cfg, trains=False)
    source = Path(source)
    if cfg.get("baseline") is not None:
        bad(
            "run",
            Shown(str(source)),
            f"a run that trained a network (a baseline run, {cfg.baseline._target_}, has none)",
        )
    record = RunDir(source).ended_record("run")  # a run still training, or a damaged record: refused before work
    model = build_model(cfg)
    checkpoint = load_network(model.net, cfg, source, "run")
    job, done = Job.open(cfg, run_dir, overrides)
    if done is not None:  # a re-run sweep skips what it evaluated
        return done
    fields = {"source_run": str(source), "checkpoint": checkpoint.name}
    if is_completed(record):
        steps = record.get("steps", 0)
    else:  # a run killed, interrupted or failed: its checkpoint says how far it trained, and the record says so
        steps = int(torch.load(checkpoint, map_location="cpu", weights_only=True).get("global_step", 0))
        fields["source_status"] = (record or {}).get("status") or "no record"
        log.warning(
            "run %s has no completed record (%s): evaluating its %s, saved at step %d",
            source,
            fields["source_status"],
            checkpoint.relative_to(source),
            steps,
        )
    dm = build_datamodule(cfg, model.objective)
    dm.setup()
    return job.finish(Outcome(model, dm, steps, what=f"the network of {source}", fields=fields))


def to_log_file(message: str) -> None:
    """A warning into the log files of the root logger's handlers (Hydra's job logging: <run>/train.log) alone,
    when the console has shown it already."""
    record = log.makeRecord(log.name, logging.WARNING, __file__, 0, message, None, None)
    for handler in logging.getLogger().handlers:
        if isinstance(handler, logging.FileHandler):
            handler.handle(record)


def noise_levels(cfg: DictConfig) -> list[float]:
    """The test noise levels (noise.eval_std): the final scores', and the learning curves' unless noise.curve_std
    names others."""
    return [float(s) for s in cfg.noise.eval_std]
