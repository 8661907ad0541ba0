"""Experiment trackers (conf/logger): Lightning loggers for a run, and what the run logs to them beyond
Lightning's own training loss and validation metrics: the resolved config as hyperparameters, the
learning-curve rows and the final results.

A tracker's run is one job; a sweep's jobs share one experiment (MLflow) or one log directory (TensorBoard:
``tensorboard --logdir <sweep dir>``), so the jobs show side by side.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable, Sequence

from filelock import FileLock
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import flatten
from hybrid_sysid.config.targets import build

SINGLE_RUNS = "runs"  # the MLflow experiment of runs outside a sweep


def build_loggers(cfg: DictConfig, run_dir: Path, experiment: str | None = None, run_name: str | None = None) -> list:
    """The config's loggers; a null save_dir is the run directory, a null MLflow experiment_name is
    ``experiment`` (the sweep) or "runs", a null run_name is ``run_name`` or the run directory's name."""
    out = []
    for name, lg in (cfg.get("logger") or {}).items():
        fill = {}
        if "save_dir" in lg and lg.save_dir is None:
            fill["save_dir"] = str(run_dir)
        if "experiment_name" in lg and lg.experiment_name is None:
            fill["experiment_name"] = experiment or SINGLE_RUNS
        if "run_name" in lg and lg.run_name is None:
            fill["run_name"] = run_name or Path(run_dir).name
        uri = str(lg.get("tracking_uri") or "")
        if uri.startswith("sqlite:///"):
            # parallel jobs share one database: create its tables, the experiment and this run one at a time
            db = Path(uri.removeprefix("sqlite:///"))
            db.parent.mkdir(parents=True, exist_ok=True)
            with FileLock(str(db) + ".lock"):
                logger = build(lg, f"logger.{name}", **fill)
                logger.experiment  # noqa: B018 - the property creates the experiment and the run
        else:
            logger = build(lg, f"logger.{name}", **fill)
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
    """Log the final results and close every logger."""
    metrics = result_metrics(results)
    for logger in loggers:
        logger.log_metrics(metrics, step=step)
        logger.save()
        logger.finalize(status)
