"""One run: build the data and the model, fit, score the best checkpoint, write the run record.

Three kinds of run share one start (``_open``: the record of a run already completed here, the directory, the
thread count) and one end (``_finish``: score, write predictions, curves and the record, close the trackers,
print the table): ``train`` (a network), a baseline (``baseline=``, no training) and ``evaluate_checkpoint``
(a trained run's network on other data). They are plain Python on a composed config (tests call them in
process); the command-line entry points are hybrid_sysid.cli.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import lightning as L
import pandas as pd
import torch
from omegaconf import DictConfig

from hybrid_sysid.config import validate
from hybrid_sysid.core import stop
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.runs.records import cpu_model, run_record
from hybrid_sysid.runs.rundir import RunDir
from hybrid_sysid.training.build import (
    build_baseline,
    build_callbacks,
    build_datamodule,
    build_model,
    build_trainer,
    load_network,
    monitor_of,
)
from hybrid_sysid.training.callbacks import CURVE_COLUMNS, LearningCurves, RunCheckpoint, TrainingClock
from hybrid_sysid.training.evaluation import by_road_class, class_table, console_table, score, write_outputs
from hybrid_sysid.training.tracking import Naming, build_loggers, finish, git_state, hyperparameters

log = logging.getLogger("hybrid_sysid")


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
    run, done = _open(cfg, run_dir, overrides)
    if done is not None:
        return done
    L.seed_everything(cfg.seed, workers=True)  # 0 included
    loggers = build_loggers(cfg, run.path, experiment, run_name, overrides)
    for logger in loggers:
        logger.log_hyperparams(hyperparameters(cfg))
    if cfg.get("baseline") is not None:
        return _run_baseline(cfg, run, overrides, loggers)
    model = model if model is not None else build_model(cfg)
    dm = build_datamodule(cfg, model.objective)
    monitor = monitor_of(cfg, model.objective)

    ckpt = RunCheckpoint(
        dirpath=run.checkpoints,
        filename="best",
        monitor=monitor,
        mode="min",
        save_last=True,
        auto_insert_metric_name=False,
    )
    clock = TrainingClock()
    curve_std = cfg.noise.get("curve_std")
    curve_levels = _noise_levels(cfg) if curve_std is None else [float(s) for s in curve_std]
    curves = LearningCurves(clock, curve_levels, every_n_steps=cfg.trainer.get("curve_every_n_steps"))
    trainer = build_trainer(cfg, run.path, [clock, curves, ckpt, *build_callbacks(cfg, monitor)], loggers)
    dm.setup("fit")
    last = run.resume_checkpoint()
    if last is not None:
        log.info("resuming from %s", last)
    start = time.perf_counter()
    trainer.fit(model, datamodule=dm, ckpt_path=str(last) if last is not None else None)
    fit_seconds = time.perf_counter() - start
    if trainer.global_rank != 0:
        return {"status": "completed", "rank": trainer.global_rank}

    if ckpt.best_model_path:
        state = torch.load(ckpt.best_model_path, map_location="cpu", weights_only=True)["state_dict"]
        model.load_state_dict(state)
    train_seconds = clock.seconds  # evaluations excluded, the time before a resume included
    return _finish(
        cfg,
        run,
        overrides,
        model,
        dm,
        curves.rows,
        loggers,
        trainer.global_step,
        f"{trainer.global_step} steps in {train_seconds:.1f} s",
        train_seconds=train_seconds,
        monitor=monitor,
        best_checkpoint=Path(ckpt.best_model_path).name or None,
        best_score=None if ckpt.best_model_score is None else float(ckpt.best_model_score),
        devices=trainer.world_size,
        fit_seconds=round(fit_seconds, 2),
        **({"init_from": str(init)} if init else {}),
    )


def _run_baseline(cfg: DictConfig, run: RunDir, overrides, loggers) -> dict:
    """A baseline without a network (``baseline=``, e.g. least squares): no Lightning, no training. Its record
    has the same form as a network run's, with steps 0 and train_seconds = the time of its fits (all done while
    scoring); curves.csv has the header only (no learning curve)."""
    estimator = build_baseline(cfg)
    dm = build_datamodule(cfg)
    dm.setup()
    return _finish(
        cfg,
        run,
        overrides,
        estimator,
        dm,
        [],
        loggers,
        0,
        lambda: f"baseline {cfg.baseline._target_}, fits in {estimator.fit_seconds:.2f} s",
        train_seconds=lambda: estimator.fit_seconds,
        monitor=None,
        best_checkpoint=None,
        fit_seconds=lambda: round(estimator.fit_seconds, 2),
    )


def evaluate_checkpoint(
    cfg: DictConfig, source: str | Path, run_dir: str | Path, overrides=(), checked: bool = False
) -> dict:
    """Score the trained network of the run ``source`` on the data of ``cfg`` (its saved config with other data,
    car, road, noise or evaluation: hybrid_sysid.cli.evaluate), without training; write the record (naming the
    source run), predictions.csv and an empty curves.csv into ``run_dir``."""
    if not checked:
        validate(cfg)
    source = Path(source)
    if cfg.get("baseline") is not None:
        raise ConfigError(
            f"run = {str(source)!r} is not allowed: a baseline run (baseline._target_ = "
            f"{cfg.baseline._target_}) has no trained network to evaluate"
        )
    model = build_model(cfg)
    checkpoint = load_network(model.net, cfg, source, "run")
    steps = (RunDir(source).read_record("run") or {}).get("steps", 0)  # a damaged record fails here, before work
    run, done = _open(cfg, run_dir, overrides)
    if done is not None:  # a re-run sweep skips what it evaluated
        return done
    dm = build_datamodule(cfg, model.objective)
    dm.setup()
    return _finish(
        cfg,
        run,
        overrides,
        model,
        dm,
        [],
        (),
        steps,
        f"the network of {source}",
        source_run=str(source),
        checkpoint=checkpoint.name,
    )


def _open(cfg: DictConfig, run_dir, overrides) -> tuple[RunDir, dict | None]:
    """The start every run shares: the record of a run of these overrides already completed here (then nothing
    else is done), else the directory made and the thread count set."""
    run = RunDir(run_dir)
    done = run.previous_record(overrides)
    if done is not None:
        log.info("run %s already completed; not running it again", run.path)
        return run, done
    run.path.mkdir(parents=True, exist_ok=True)
    if cfg.trainer.get("threads"):
        torch.set_num_threads(int(cfg.trainer.threads))
    return run, None


def _finish(cfg: DictConfig, run: RunDir, overrides, model, dm, curve_rows, loggers, step: int, what, **fields) -> dict:
    """The end every run shares: score the model on the noise levels and K values of the config, write
    predictions.csv, curves.csv and the record (``fields`` added to it; a callable is read after scoring), close
    the trackers, print the table. Returns the record."""
    stop.check()  # a safe point: a termination signal swallowed during the work ends the run here
    threads = torch.get_num_threads()  # recorded: the numbers depend on it (docs/reliability.md)
    results, predictions = score(model, dm, _noise_levels(cfg), [int(k) for k in cfg.evaluation.windows])
    write_outputs(run.path, predictions, pd.DataFrame(curve_rows, columns=CURVE_COLUMNS))
    classes = by_road_class(predictions)
    fields = {k: v() if callable(v) else v for k, v in fields.items()}
    # the code and the processor that made the numbers (report/provenance.py names them under each table); both
    # are read once per process, so a record is no slower to write
    commit, dirty = git_state() or (None, None)
    record = run_record(
        "completed",
        overrides,
        cfg.seed,
        steps=step,
        results=results,
        threads=threads,
        by_road_class=classes,
        git_commit=commit,
        git_dirty=dirty,
        cpu=cpu_model(),
        **fields,
    )
    stop.check()  # the last safe point before the run is final
    run.write_record(record)
    finish(loggers, results, step)
    log.info(
        "run %s: %s\n%s\n%s", run.path, what() if callable(what) else what, console_table(results), class_table(classes)
    )
    return record


def _noise_levels(cfg: DictConfig) -> list[float]:
    """The test noise levels (noise.eval_std): the final scores', and the learning curves' unless noise.curve_std
    names others."""
    return [float(s) for s in cfg.noise.eval_std]
