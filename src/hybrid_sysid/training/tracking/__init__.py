"""Experiment trackers (conf/logger): Lightning loggers for a run, and what the run logs to them beyond Lightning's
own training loss and validation metrics: the resolved config as hyperparameters, the learning-curve rows and the
final results (docs/usage/trackers.md). How runs are named: naming.py; MLflow's tags, files and sweep
summary: mlflow_store.py; TensorBoard's HPARAMS table: hparams.py. TensorBoard names a run by its directory: a
sweep's jobs write to ``<sweep dir>/tensorboard/<run name>/``, a single run to ``<run dir>/tensorboard/``.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Any, Iterable, Sequence

from filelock import FileLock
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import flatten
from hybrid_sysid.config.targets import build
from hybrid_sysid.training.tracking.hparams import hparams_values, write_hparams
from hybrid_sysid.training.tracking.mlflow_store import (
    SWEEP_RUN,
    artifact_root,
    finished,
    guarded,
    log_run_figures,
    log_run_files,
    log_sweep,
    mlflow_client,
    mlflow_experiment,
    run_tags,
    sweep_tags,
)
from hybrid_sysid.training.tracking.mlflow_store import kind as logger_kind
from hybrid_sysid.training.tracking.naming import SINGLE_RUNS, Naming, job_naming, override_key, swept_keys

__all__ = [
    "SWEEP_RUN",
    "Naming",
    "Trackers",
    "build_loggers",
    "curve_metrics",
    "finish",
    "hyperparameters",
    "job_naming",
    "log_metrics",
    "log_run_figures",
    "log_sweep",
    "result_metrics",
    "swept_keys",
]


class Trackers(list):
    """The run's loggers (a list, as Lightning takes it), with what :func:`finish` logs beyond metrics."""

    def __init__(self, loggers=(), cfg: DictConfig | None = None, naming: Naming | None = None, run_dir=None):
        super().__init__(loggers)
        self.cfg, self.naming, self.run_dir = cfg, naming or Naming(), run_dir


def build_loggers(
    cfg: DictConfig,
    run_dir: Path,
    experiment: str | Naming | None = None,
    run_name: str | None = None,
    overrides: Sequence[str] = (),
) -> Trackers:
    """The config's loggers. ``experiment``: the job's :class:`Naming` (hybrid_sysid.cli.train: :func:`job_naming`)
    or just an MLflow experiment's name; ``run_name`` the run's (default: the naming's, else the run directory's
    name). Null arguments in conf/logger are filled: a null save_dir is the run directory (TensorBoard in a
    sweep: ``<sweep dir>``, with version = the run name), a null MLflow experiment_name is the naming's
    experiment, a null artifact_location beside a SQLite store is ``<its folder>/mlartifacts/<experiment>``."""
    naming = experiment if isinstance(experiment, Naming) else Naming(experiment or SINGLE_RUNS, run_name)
    run_name = run_name or naming.run or Path(run_dir).name
    out = Trackers((), cfg, naming, Path(run_dir))
    for name, lg in (cfg.get("logger") or {}).items():
        fill: dict[str, Any] = {}
        kind = logger_kind(lg)
        if "save_dir" in lg and lg.save_dir is None:
            in_sweep = kind == "TensorBoardLogger" and naming.sweep_dir is not None
            fill["save_dir"] = str(naming.sweep_dir if in_sweep else run_dir)
        if kind == "TensorBoardLogger" and "version" in lg and lg.version is None:
            fill["version"] = run_name.replace("/", "_") if naming.sweep_dir is not None else ""
        if kind != "MLFlowLogger":
            out.append(build(lg, f"logger.{name}", **fill))
            continue
        exp_name = str(lg.experiment_name) if lg.get("experiment_name") is not None else naming.experiment
        fill["experiment_name"] = exp_name
        if "run_name" in lg and lg.run_name is None:
            fill["run_name"] = run_name
        fill["tags"] = {**run_tags(cfg, naming, run_dir, overrides), **dict(lg.get("tags") or {})}
        uri, location = str(lg.get("tracking_uri") or ""), lg.get("artifact_location")
        # a sweep's experiment is tagged with its preset and directory; "runs", shared by single runs, is not
        exp_tags = sweep_tags(naming.preset, naming.sweep_dir) if naming.sweep_dir is not None else {}
        lock = contextlib.nullcontext()
        if uri.startswith("sqlite:///"):
            # parallel jobs share one database: create its tables, the experiment and this run one at a time
            db = Path(uri.removeprefix("sqlite:///"))
            db.parent.mkdir(parents=True, exist_ok=True)
            if location is None:
                location = fill["artifact_location"] = artifact_root(db, exp_name)
            lock = FileLock(str(db) + ".lock")
        with lock:
            # the experiment made here first, with its tags and artifact location, so Lightning finds it
            mlflow_experiment(mlflow_client(uri or None), exp_name, location, exp_tags)
            logger = build(lg, f"logger.{name}", **fill)
            logger.experiment  # noqa: B018 - the property creates the run
        out.append(logger)
    return out


def hyperparameters(cfg: DictConfig) -> dict:
    """The resolved config flattened to dotted keys (lists as text), e.g. {"model.optim.lr": 0.02}."""
    flat = flatten(OmegaConf.to_container(cfg, resolve=True))
    return {k: v if isinstance(v, (int, float, str, bool)) else str(v) for k, v in flat.items()}


def _as_metrics(rows: Iterable[dict], base) -> dict[str, float]:
    out = {}
    for r in rows:
        out[f"{base(r)}_mean_rel_dev"], out[f"{base(r)}_std_rel_dev"] = r["mean_rel_dev"], r["std_rel_dev"]
    return out


def curve_metrics(rows: Iterable[dict]) -> dict[str, float]:
    """Learning-curve rows as metrics: curve/<split>/noise_<std>/<parameter>_mean_rel_dev (and _std_)."""
    return _as_metrics(rows, lambda r: f"curve/{r['split']}/noise_{r['noise_std']:g}/{r['parameter']}")


def result_metrics(results: Iterable[dict]) -> dict[str, float]:
    """The record's results as metrics: final/<split>/noise_<std>/K<windows>/<parameter>_mean_rel_dev."""
    return _as_metrics(
        results, lambda r: f"final/{r['split']}/noise_{r['noise_std']:g}/K{r.get('windows', 1)}/{r['parameter']}"
    )


def log_metrics(loggers: Sequence, metrics: dict[str, float], step: int) -> None:
    for logger in loggers:
        logger.log_metrics(metrics, step=step)


def finish(loggers: Sequence, results: Iterable[dict], step: int, status: str = "success") -> None:
    """Log the final results (TensorBoard: and the HPARAMS table; MLflow: and the run's files) and close every
    logger."""
    metrics = result_metrics(results)
    cfg, naming, run_dir = (getattr(loggers, a, None) for a in ("cfg", "naming", "run_dir"))
    for logger in loggers:
        logger.log_metrics(metrics, step=step)
        kind = type(logger).__name__
        if cfg is not None and kind == "TensorBoardLogger":
            varied = [override_key(o) for o in naming.varied]
            guarded("the hparams table", write_hparams, logger, hparams_values(cfg, naming), metrics, varied)
        if run_dir is not None and kind == "MLFlowLogger":
            guarded("the run's artifacts", log_run_files, logger.experiment, logger.run_id, run_dir)
        logger.save()
        logger.finalize(status)
        if run_dir is not None and kind == "MLFlowLogger":
            finished(run_dir, logger.experiment.tracking_uri, logger.run_id)
