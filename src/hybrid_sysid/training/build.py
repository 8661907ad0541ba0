"""What a run is built from its config: the data module, the model (network + objective), the Trainer."""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import lightning as L
import torch
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config.targets import arguments, build, data_module
from hybrid_sysid.core.checks import Shown, bad
from hybrid_sysid.data.datamodule import QuarterCarDataModule
from hybrid_sysid.data.spec import DatasetSpec
from hybrid_sysid.model.module import LOG_EVERY, IdentificationModule
from hybrid_sysid.runs.layout import CONFIG
from hybrid_sysid.runs.rundir import RunDir
from hybrid_sysid.training.callbacks import AtomicCheckpointIO, StepReports, StopAtSafePoints, ValidateAtEnd
from hybrid_sysid.training.data_arguments import window_arguments
from hybrid_sysid.training.recordings import recordings_datamodule

log = logging.getLogger("hybrid_sysid")


def build_objective(cfg: DictConfig):
    return build(cfg.objective, "objective")


def build_datamodule(cfg: DictConfig, objective=None) -> QuarterCarDataModule:
    """The data module; when the objective reads band-passed signals (its ``fir``) or the fit over each window's
    outside samples (its ``outside_fir`` and ``outside_target``), the batches carry them. ``objective``: the run's,
    else built from the config (none for a baseline)."""
    if objective is None and cfg.get("baseline") is None:
        objective = build_objective(cfg)
    if cfg.data.get("module") is not None:  # a data module of its own class (a plugin's: docs/extending.md)
        return data_module(cfg, objective)
    d = cfg.data
    if d.get("path") is not None:  # a user's recordings (data=recordings), read from their files
        return recordings_datamodule(cfg, objective)
    return QuarterCarDataModule(
        DatasetSpec.from_config(cfg),
        cache_dir=d.cache_dir,
        train_fraction=d.train_fraction,
        val_fraction=d.val_fraction,
        **window_arguments(cfg, objective),
    )


def build_model(cfg: DictConfig, objective=None) -> IdentificationModule:
    """The network and the objective of the config (their prior of p comes from the car and the mass range:
    ``${p_prior:...}``, hybrid_sysid.config.resolvers) in an IdentificationModule; ``objective``: one built
    already from the config."""
    net = build(cfg.model.net, "model.net")
    o = cfg.model.optim
    return IdentificationModule(
        net,
        build_objective(cfg) if objective is None else objective,
        optimizer=o.name,
        lr=o.lr,
        weight_decay=o.weight_decay,
        schedule=o.schedule,
        max_steps=cfg.trainer.max_steps,
        warmup_fraction=o.warmup_fraction,
    )


def build_baseline(cfg: DictConfig):
    """The baseline of ``baseline=`` (a model.base.SplitPredictor without a network)."""
    return build(cfg.baseline, "baseline")


def build_trainer(cfg: DictConfig, run_dir, callbacks=(), loggers=(), **overrides) -> L.Trainer:
    """The run's lightning.Trainer (benchmarks/training_throughput.py times this same one). ``loggers``: the
    experiment trackers (hybrid_sysid.training.tracking); none by default. trainer.extra and then ``overrides``
    may replace any argument."""
    t = cfg.trainer
    callbacks = [StopAtSafePoints(), ValidateAtEnd(), StepReports(), *callbacks]
    bar = L.pytorch.callbacks.ProgressBar
    show_bar = progress_bar_on(t.progress_bar)
    if not show_bar:  # bars off (a parallel launcher's workers, a log file): a configured bar too
        callbacks = [c for c in callbacks if not isinstance(c, bar)]
    elif not any(isinstance(c, bar) for c in callbacks):  # the default bar unless callbacks= chose another
        # Lightning redraws the bar every step by default; every 10th step reads as well and costs less
        callbacks = [*callbacks, L.pytorch.callbacks.TQDMProgressBar(refresh_rate=10)]
    kwargs = dict(
        max_steps=t.max_steps,
        val_check_interval=t.eval_every_n_steps,
        check_val_every_n_epoch=None,
        accelerator=t.accelerator,
        devices=t.devices,
        num_nodes=t.get("num_nodes", 1),
        deterministic=t.deterministic,
        logger=list(loggers) or False,
        callbacks=callbacks,
        enable_progress_bar=show_bar,
        enable_model_summary=False,
        num_sanity_val_steps=0,
        default_root_dir=str(run_dir),
        plugins=[AtomicCheckpointIO()],
        log_every_n_steps=LOG_EVERY,
    )  # the steps on which the module logs its training loss
    if t.get("profiler"):
        kwargs["profiler"] = build_profiler(t.profiler, run_dir)
    kwargs.update(t.get("extra", {}))
    kwargs.update(overrides)
    trainer = L.Trainer(**kwargs)
    if kwargs["deterministic"]:
        # deterministic mode also fills every new tensor with NaN, against ops that read memory they did not
        # write; none of a run's does (tests/model/test_deterministic_fill.py: the same weights either way), and
        # the fill costs a share of every step (benchmarks/README.md, "The main job")
        torch.utils.deterministic.fill_uninitialized_memory = False
    return trainer


def progress_bar_on(setting) -> bool:
    """trainer.progress_bar: true or false as given; auto: a bar only when stdout (where Lightning draws it) is a
    terminal, so a run whose output goes to a file or a pipe writes no bar into it."""
    if isinstance(setting, bool):
        return setting
    return sys.stdout is not None and sys.stdout.isatty()


def build_callbacks(cfg: DictConfig, monitor: str) -> list:
    """The Lightning callbacks of conf/callbacks (``callbacks.<name>``: a _target_ and its arguments), beside the
    run's own; a ``monitor`` of auto is the run's model-selection figure ``monitor`` (monitor_of)."""
    out = []
    for name, node in (cfg.get("callbacks") or {}).items():
        fill = {"monitor": monitor} if node.get("monitor") == "auto" else {}
        out.append(build(node, f"callbacks.{name}", **fill))
    return out


def build_profiler(name: str, run_dir):
    """Lightning's profiler ``name`` (simple, advanced), its report written into the run directory at the end of
    training (fit-profiler.txt)."""
    cls = {"simple": L.pytorch.profilers.SimpleProfiler, "advanced": L.pytorch.profilers.AdvancedProfiler}[name]
    return cls(dirpath=str(run_dir), filename="profiler")


def monitor_of(cfg: DictConfig, objective) -> str:
    """trainer.monitor, where 'auto' is the objective's own model-selection figure (model.base.Objective: the
    training objective on validation windows for one that reads no labels, so a label-free run stays
    label-free; the labelled relative deviation otherwise)."""
    m = cfg.trainer.monitor
    return objective.monitor if m == "auto" else m


def first_misfit(cfg: DictConfig, state: dict) -> tuple[str, tuple | str, tuple | str, int] | None:
    """The first tensor whose shape differs between the network ``cfg`` describes and a checkpoint's ``state``
    (key, shape there, shape in the config, how many differ), None when all fit. The network is built on torch's
    meta device, without memory: a received config asking for 200,000 channels (1.4 TB) is told here, before any
    check builds it for real, whose size is then bounded by the checkpoint file's."""
    try:
        with torch.device("meta"):
            meta = build_model(cfg)
    except Exception:  # noqa: BLE001 - a config the checks refuse (they name it), a builder needing real tensors
        return None
    want = {k: tuple(v.shape) for k, v in meta.state_dict().items()}
    have = {k: tuple(v.shape) for k, v in state.items() if isinstance(v, torch.Tensor)}
    differ = sorted(k for k in want.keys() | have.keys() if want.get(k) != have.get(k))
    if not differ:
        return None
    k = differ[0]
    return k, have.get(k, "missing"), want.get(k, "missing"), len(differ)


def check_sizes(cfg: DictConfig, run_dir: Path, key: str) -> None:
    """``first_misfit`` against the trained checkpoint of the run in ``run_dir``: a ConfigError naming ``key``. A
    baseline run has no network to build: the other checks name it."""
    if OmegaConf.select(cfg, "baseline", default=None) is not None:
        return
    run = RunDir(run_dir)
    path, state = run.load_weights(key)
    words = misfit_words(cfg, run.path, path, state)
    if words is not None:
        bad(key, Shown(str(run_dir)), words)


def misfit_words(cfg: DictConfig, run_path: Path, path: Path, state: dict) -> str | None:
    """What a run must be when its checkpoint ``path`` does not fit the config's model.net (``first_misfit``), in
    the words every refusal of it uses (training's and inference's); None when it fits."""
    misfit = first_misfit(cfg, state)
    if misfit is None:
        return None
    k, there, here, n = misfit
    return (
        f"a run whose {path.relative_to(run_path)} fits its model.net ({cfg.model.net._target_}): {k} is "
        f"{there} there, {here} in the config ({n} tensors differ)"
    )


def check_weights(cfg: DictConfig, run_dir: Path, key: str) -> None:
    """The network of ``cfg`` takes the trained weights of the run in ``run_dir`` (``load_network``): a ConfigError
    naming ``key`` otherwise, before any directory is made (the command-line preflight)."""
    load_network(build(cfg.model.net, "model.net"), cfg, run_dir, key)


def load_network(net: torch.nn.Module, cfg: DictConfig, run_dir: Path, key: str) -> Path:
    """Put the trained weights of the run in ``run_dir`` into ``net`` (a network built from model.net); the
    whole network state comes with them (batch-norm statistics, and the output bounds the source run was trained
    with). A network of another architecture (class or any argument besides the prior of p) is a ConfigError
    naming ``key``."""
    run = RunDir(run_dir)
    run.ended_record(key)  # a run still training has not yet the weights it will leave; a damaged record is refused
    source = run.saved_config(key)
    saved_net = OmegaConf.select(source, "model.net")
    prior = arguments(cfg.model.net, "model.net")[0].prior_arguments  # derived from the data, not the architecture
    mine = {k: v for k, v in OmegaConf.to_container(cfg.model.net).items() if k not in prior}
    saved = OmegaConf.to_container(saved_net) if isinstance(saved_net, DictConfig) else {}
    theirs = {k: v for k, v in saved.items() if k not in prior}
    lacks = ["model.net"] if "_target_" not in theirs else sorted(f"model.net.{k}" for k in set(mine) - set(theirs))
    if lacks and theirs.get("_target_", mine.get("_target_")) == mine.get("_target_"):
        # a file cut at a line's end parses: the network's section, or its last arguments, are gone
        bad(key, Shown(str(run_dir)), f"its {CONFIG} has no value for {', '.join(lacks)} (a file cut short?)")
    if mine != theirs:
        diff = sorted(k for k in set(mine) | set(theirs) if mine.get(k) != theirs.get(k))
        bad(
            key,
            Shown(str(run_dir)),
            "its network differs from model.net in "
            + ", ".join(f"{k} ({theirs.get(k)} there, {mine.get(k)} here)" for k in diff),
        )
    path, state = run.load_weights(key)
    try:
        net.load_state_dict({k[len("net.") :]: v for k, v in state.items() if k.startswith("net.")})
    except RuntimeError as exc:  # torch lists every mismatched key: its first line names the problem
        bad(key, Shown(str(run_dir)), f"a run whose weights fit model.net ({str(exc).splitlines()[0]})")
    return path
