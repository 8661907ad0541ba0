"""One run: build the data and the model, fit, evaluate the best checkpoint, write the run record.

``train(cfg, run_dir)`` is plain Python on a composed config (tests call it in process); the Hydra entry
point that calls it is ``hybrid_sysid.app``.
"""

from __future__ import annotations

import json
import logging
import time
from pathlib import Path

import lightning as L
import pandas as pd
import torch
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.baselines import is_baseline
from hybrid_sysid.callbacks import CURVE_COLUMNS, LearningCurves, RunCheckpoint, TrainingClock
from hybrid_sysid.config import ConfigError, dataset_spec, validate
from hybrid_sysid.data.datamodule import QCMDataModule
from hybrid_sysid.files import write_atomic
from hybrid_sysid.model.metrics import summarise
from hybrid_sysid.model.module import LOG_EVERY, ParameterEstimator
from hybrid_sysid.physics.filters import filter_taps
from hybrid_sysid.records import RECORD, previous_record, run_record, write_record
from hybrid_sysid.tracking import build_loggers, finish, hyperparameters

log = logging.getLogger("hybrid_sysid")


def build_datamodule(cfg: DictConfig) -> QCMDataModule:
    """The data module; with ``objective.filter`` its batches carry the band-passed signals too."""
    d = cfg.data
    f = cfg.objective.get("filter")
    fir = None if f is None else filter_taps(OmegaConf.to_container(f), d.dt)
    return QCMDataModule(dataset_spec(cfg), cache_dir=d.cache_dir, window=d.window, batch_size=cfg.model.batch_size,
                         train_fraction=d.train_fraction, val_fraction=d.val_fraction,
                         eval_std=list(cfg.noise.eval_std), train_std=cfg.noise.train_std, seed=cfg.seed,
                         integration=d.get("integration", "t0"), fir=fir)


def build_model(cfg: DictConfig) -> ParameterEstimator:
    """The network and the objective of the config (their prior of p comes from the car and the mass range:
    ``${p_prior:...}``, hybrid_sysid.config) in a ParameterEstimator."""
    net = instantiate(cfg.model.net, _convert_="all")
    objective = instantiate(cfg.objective, _convert_="all")
    o = cfg.model.optim
    return ParameterEstimator(net, objective, optimizer=o.name, lr=o.lr, weight_decay=o.weight_decay,
                              schedule=o.schedule, max_steps=cfg.trainer.max_steps,
                              warmup_fraction=o.warmup_fraction)


def build_trainer(cfg: DictConfig, run_dir, callbacks=(), loggers=(), **overrides) -> L.Trainer:
    """The run's lightning.Trainer (benchmarks/training_throughput.py times this same one). ``loggers``: the
    experiment trackers (hybrid_sysid.tracking); none by default. trainer.extra and then ``overrides`` may
    replace any argument."""
    t = cfg.trainer
    callbacks = list(callbacks)
    if t.progress_bar:
        # Lightning redraws the bar every step by default; every 10th step reads as well and costs less
        callbacks.append(L.pytorch.callbacks.TQDMProgressBar(refresh_rate=10))
    kwargs = dict(
        max_steps=t.max_steps, val_check_interval=t.eval_every_n_steps, check_val_every_n_epoch=None,
        accelerator=t.accelerator, devices=t.devices, deterministic=t.deterministic, logger=list(loggers) or False,
        callbacks=callbacks, enable_progress_bar=t.progress_bar, enable_model_summary=False,
        num_sanity_val_steps=0, default_root_dir=str(run_dir),
        log_every_n_steps=LOG_EVERY)  # the steps on which the module logs its training loss
    kwargs.update(t.get("extra", {}))
    kwargs.update(overrides)
    return L.Trainer(**kwargs)


def monitor_of(cfg: DictConfig, objective) -> str:
    """'auto' selects by the training objective on validation windows when it reads no labels (hybrid), so a
    label-free run stays label-free; by the labelled relative deviation otherwise."""
    m = cfg.trainer.monitor
    if m == "auto":
        return "val/rel_dev" if getattr(objective, "uses_labels", True) else "val/loss"
    return m


def evaluate(model, dm: QCMDataModule, noise_levels, windows=(1,)) -> tuple[list[dict], pd.DataFrame]:
    """Relative deviations per split, noise level and K (test predictions averaged over K windows per
    recording; train and val on one window), plus one prediction row per recording and evaluation.

    ``model`` is anything with ``predict_split(dm, split, noise_std, limit, windows)``: a ParameterEstimator
    or a baseline (hybrid_sysid.baselines)."""
    results, frames = [], []
    evals = [("train", 0.0, 1), ("val", 0.0, 1)] + [("test", float(s), int(k)) for s in noise_levels for k in windows]
    for split, std, k in evals:
        pred, true = model.predict_split(dm, split, std, windows=k)
        results += summarise(pred, true, split=split, noise_std=std, windows=k)
        rows = dm.rows(split)
        frames.append(pd.DataFrame({
            "split": split, "noise_std": std, "windows": k, "recording": rows,
            "road_class": dm.dataset.road_class[rows], "m3": dm.dataset.m3[rows], "p1_true": true[:, 0],
            "p1_pred": pred[:, 0], "p2_true": true[:, 1], "p2_pred": pred[:, 1]}))
    return results, pd.concat(frames, ignore_index=True)


def by_road_class(predictions: pd.DataFrame) -> list[dict]:
    """Test relative deviations per road class, noise level and K (metrics.json's "by_road_class"): under
    noise the smooth classes, whose signals are smallest, carry most of the error."""
    rows = []
    test = predictions[predictions.split == "test"]
    for (std, k, cls), g in test.groupby(["noise_std", "windows", "road_class"], sort=True):
        pred, true = g[["p1_pred", "p2_pred"]].to_numpy(), g[["p1_true", "p2_true"]].to_numpy()
        rows += summarise(pred, true, split="test", noise_std=float(std), windows=int(k), road_class=str(cls))
    return rows


def class_table(rows: list[dict]) -> str:
    if not rows:
        return ""
    table = pd.DataFrame(rows).pivot_table(index=["noise_std", "windows"], columns=["parameter", "road_class"],
                                           values="mean_rel_dev")
    return "test mean rel. dev. [%] per road class\n" + (table * 100).round(2).to_string()


def write_outputs(run_dir: Path, predictions: pd.DataFrame, curves: pd.DataFrame) -> None:
    """predictions.csv and curves.csv; the run's figures are drawn from them by the report layer."""
    write_atomic(run_dir / "curves.csv", lambda p: curves.to_csv(p, index=False))
    write_atomic(run_dir / "predictions.csv", lambda p: predictions.to_csv(p, index=False))


def console_table(results: list[dict]) -> str:
    df = pd.DataFrame(results)
    df = df[df.split != "val"]
    index = ["split", "noise_std"] + (["windows"] if df.get("windows", pd.Series([1])).ne(1).any() else [])
    table = df.pivot_table(index=index, columns="parameter", values="mean_rel_dev")
    return (table * 100).round(2).rename(columns=lambda c: f"{c} mean rel. dev. [%]").to_string()


def loadable(path: Path) -> bool:
    try:
        torch.load(path, map_location="cpu", weights_only=True)
        return True
    except Exception:  # noqa: BLE001 - truncated, garbage, another format: all mean "cannot resume from it"
        return False


def resume_checkpoint(ckpt_dir: Path) -> Path | None:
    """The checkpoint to resume from: last.ckpt; best.ckpt when last.ckpt is damaged (both hold the full training
    state); None (train from the beginning, which gives the same numbers) when best.ckpt is damaged, as the best
    weights the run would be evaluated with are then lost, or when neither loads. Damaged files are reported and
    overwritten by the run's next checkpoints, so a damaged file never blocks a run."""
    ok = {}
    for name in ("last.ckpt", "best.ckpt"):
        path = ckpt_dir / name
        if path.exists():
            ok[name] = loadable(path)
            if not ok[name]:
                log.warning("checkpoint %s cannot be loaded (damaged or truncated); not resuming from it", path)
    if ok.get("best.ckpt", True) is False or (ok and not any(ok.values())):
        log.warning("training %s from the beginning", ckpt_dir.parent)
        return None
    if ok.get("last.ckpt"):
        return ckpt_dir / "last.ckpt"
    return ckpt_dir / "best.ckpt" if ok.get("best.ckpt") else None


def best_checkpoint(run_dir: Path, key: str) -> Path:
    """checkpoints/best.ckpt of a trained run (last.ckpt when it never validated); ConfigError naming ``key``
    otherwise."""
    for name in ("best.ckpt", "last.ckpt"):
        if (run_dir / "checkpoints" / name).is_file():
            return run_dir / "checkpoints" / name
    raise ConfigError(f"{key} = {str(run_dir)!r} is not allowed: it holds no checkpoints/best.ckpt or last.ckpt "
                      "(a run directory of hybrid-sysid that trained a network)")


def saved_config(run_dir: Path, key: str) -> DictConfig:
    """The composed config a run saved (.hydra/config.yaml); ConfigError naming ``key`` when it has none."""
    path = run_dir / ".hydra" / "config.yaml"
    if not path.is_file():
        raise ConfigError(f"{key} = {str(run_dir)!r} is not allowed: it has no .hydra/config.yaml (a run "
                          "directory written by hybrid-sysid)")
    return OmegaConf.load(path)


# the prior of p is derived from the data (${p_prior:...}), not part of the architecture
PRIOR_KEYS = ("p_min", "p_max", "p_scale")


def load_network(model: ParameterEstimator, cfg: DictConfig, run_dir: Path, key: str) -> Path:
    """Put the best weights of the run in ``run_dir`` into ``model.net``; the whole network state comes with them
    (batch-norm statistics, and the output bounds the source run was trained with). A network of another
    architecture (class or any argument besides the prior of p) is a ConfigError naming ``key``."""
    source = saved_config(run_dir, key)
    mine = {k: v for k, v in OmegaConf.to_container(cfg.model.net).items() if k not in PRIOR_KEYS}
    theirs = {k: v for k, v in OmegaConf.to_container(source.model.net).items() if k not in PRIOR_KEYS}
    if mine != theirs:
        diff = sorted(k for k in set(mine) | set(theirs) if mine.get(k) != theirs.get(k))
        raise ConfigError(f"{key} = {str(run_dir)!r} is not allowed: its network differs from model.net in "
                          + ", ".join(f"{k} ({theirs.get(k)} there, {mine.get(k)} here)" for k in diff))
    path = best_checkpoint(run_dir, key)
    state = torch.load(path, map_location="cpu", weights_only=True)["state_dict"]
    model.net.load_state_dict({k[len("net."):]: v for k, v in state.items() if k.startswith("net.")})
    return path


def train(cfg: DictConfig, run_dir: str | Path, overrides=(), experiment: str | None = None,
          run_name: str | None = None) -> dict:
    """Fit and evaluate one configuration; write metrics.json, curves.csv, predictions.csv and figures/.
    ``experiment`` and ``run_name`` name the run in an experiment tracker (hybrid_sysid.tracking.build_loggers).

    With several devices (DDP) every rank trains on its own window stream; rank 0 alone evaluates and writes,
    and the other ranks return {"status": "completed", "rank": r} without a record."""
    validate(cfg)  # every range check before any work
    run_dir = Path(run_dir)
    init = cfg.get("init_from")
    if init and is_baseline(cfg.model.net._target_):
        raise ConfigError(f"init_from = {init!r} is not allowed with a baseline (model.net._target_ = "
                          f"{cfg.model.net._target_}): it has no weights to start from")
    model = None
    if init:  # before any directory is made or data simulated: a network that does not fit fails here
        model = build_model(cfg)
        log.info("starting from the weights of %s", load_network(model, cfg, Path(init), "init_from"))
    done = previous_record(run_dir, overrides)
    if done is not None:
        log.info("run %s already completed; not training it again", run_dir)
        return done
    run_dir.mkdir(parents=True, exist_ok=True)
    t = cfg.trainer
    if t.get("threads"):
        torch.set_num_threads(int(t.threads))
    threads = torch.get_num_threads()  # recorded: the numbers depend on it (docs/reliability.md)
    L.seed_everything(cfg.seed, workers=True)  # 0 included

    dm = build_datamodule(cfg)
    noise_levels = [float(s) for s in cfg.noise.eval_std]
    windows = [int(k) for k in cfg.evaluation.windows]
    loggers = build_loggers(cfg, run_dir, experiment, run_name)
    for logger in loggers:
        logger.log_hyperparams(hyperparameters(cfg))
    if is_baseline(cfg.model.net._target_):
        return run_baseline(cfg, dm, run_dir, overrides, noise_levels, windows, threads, loggers)
    model = model if model is not None else build_model(cfg)
    monitor = monitor_of(cfg, model.objective)

    ckpt = RunCheckpoint(dirpath=run_dir / "checkpoints", filename="best", monitor=monitor, mode="min",
                         save_last=True, auto_insert_metric_name=False)
    clock = TrainingClock()
    curves = LearningCurves(clock, noise_levels, every_n_steps=cfg.trainer.get("curve_every_n_steps"))
    trainer = build_trainer(cfg, run_dir, [clock, curves, ckpt], loggers)
    dm.setup("fit")
    last = resume_checkpoint(run_dir / "checkpoints")
    if last is not None:
        log.info("resuming from %s", last)
    start = time.perf_counter()
    trainer.fit(model, datamodule=dm, ckpt_path=str(last) if last is not None else None)
    fit_seconds = time.perf_counter() - start
    train_seconds = clock.seconds  # evaluations excluded, the time before a resume included
    if trainer.global_rank != 0:
        return {"status": "completed", "rank": trainer.global_rank}

    if ckpt.best_model_path:
        state = torch.load(ckpt.best_model_path, map_location="cpu", weights_only=True)["state_dict"]
        model.load_state_dict(state)
    results, predictions = evaluate(model, dm, noise_levels, windows)
    write_outputs(run_dir, predictions, pd.DataFrame(curves.rows, columns=CURVE_COLUMNS))

    classes = by_road_class(predictions)
    record = run_record("completed", overrides, cfg.seed, steps=trainer.global_step, train_seconds=train_seconds,
                        results=results, monitor=monitor, best_checkpoint=Path(ckpt.best_model_path).name or None,
                        best_score=None if ckpt.best_model_score is None else float(ckpt.best_model_score),
                        devices=trainer.world_size, fit_seconds=round(fit_seconds, 2), threads=threads,
                        by_road_class=classes, **({"init_from": str(init)} if init else {}))
    write_record(run_dir, record)
    finish(loggers, results, trainer.global_step)
    log.info("run %s: %d steps in %.1f s\n%s\n%s", run_dir, trainer.global_step, train_seconds,
             console_table(results), class_table(classes))
    return record


def run_baseline(cfg: DictConfig, dm: QCMDataModule, run_dir: Path, overrides, noise_levels, windows,
                 threads: int, loggers=()) -> dict:
    """A baseline without a network (``trainable = False``, e.g. least squares): no Lightning, no training.
    Its record has the same form as a network run's, with steps 0 and train_seconds = the time of its fits
    (all done while evaluating); curves.csv has the header only (no learning curve)."""
    estimator = instantiate(cfg.model.net, _convert_="all")
    dm.setup()
    results, predictions = evaluate(estimator, dm, noise_levels, windows)
    write_outputs(run_dir, predictions, pd.DataFrame(columns=CURVE_COLUMNS))
    classes = by_road_class(predictions)
    record = run_record("completed", overrides, cfg.seed, steps=0, train_seconds=estimator.fit_seconds,
                        results=results, monitor=None, best_checkpoint=None,
                        fit_seconds=round(estimator.fit_seconds, 2), threads=threads, by_road_class=classes)
    write_record(run_dir, record)
    finish(loggers, results, 0)
    log.info("run %s: baseline %s, fits in %.2f s\n%s\n%s", run_dir, cfg.model.net._target_,
             estimator.fit_seconds, console_table(results), class_table(classes))
    return record


def evaluate_run(cfg: DictConfig, source: str | Path, run_dir: str | Path, overrides=()) -> dict:
    """Evaluate the best checkpoint of the trained run ``source`` on the data of ``cfg`` (its saved config with
    other data, car, road, noise or evaluation: hybrid_sysid.evaluate), without training; write the record
    (naming the source run), predictions.csv and an empty curves.csv into ``run_dir``."""
    validate(cfg)
    source, run_dir = Path(source), Path(run_dir)
    if is_baseline(cfg.model.net._target_):
        raise ConfigError(f"run = {str(source)!r} is not allowed: a baseline run (model.net._target_ = "
                          f"{cfg.model.net._target_}) has no trained network to evaluate")
    model = build_model(cfg)
    checkpoint = load_network(model, cfg, source, "run")
    done = previous_record(run_dir, overrides)
    if done is not None:  # a re-run sweep skips what it evaluated
        log.info("evaluation %s already completed; not evaluating it again", run_dir)
        return done
    run_dir.mkdir(parents=True, exist_ok=True)
    if cfg.trainer.get("threads"):
        torch.set_num_threads(int(cfg.trainer.threads))
    dm = build_datamodule(cfg)
    dm.setup()
    noise_levels = [float(s) for s in cfg.noise.eval_std]
    results, predictions = evaluate(model, dm, noise_levels, [int(k) for k in cfg.evaluation.windows])
    write_outputs(run_dir, predictions, pd.DataFrame(columns=CURVE_COLUMNS))
    source_record = source / RECORD
    steps = json.loads(source_record.read_text()).get("steps", 0) if source_record.is_file() else 0
    record = run_record("completed", overrides, cfg.seed, steps=steps, results=results, source_run=str(source),
                        checkpoint=checkpoint.name, threads=torch.get_num_threads())
    write_record(run_dir, record)
    log.info("run %s evaluated on %s\n%s", source, run_dir, console_table(results))
    return record
