"""``validate(cfg)``: every check of a composed config, before any data is simulated or any directory filled.

Each value is checked once, by what owns it: the data's by DatasetSpec, WindowSettings and BatchSettings, the
optimiser's by OptimSettings, the network's, the objective's and a baseline's by their constructors (the network
also run on one window; this package's own networks and objectives first by their constructors' torch-free part,
model.arguments, so that a refusal imports no torch). Each names its own argument, and this module places it in
the config (``config_key``: ``window`` is ``data.window``); it checks itself only what no object owns (seeds, noise
levels, the trainer, the memory bound).
"""

from __future__ import annotations

import difflib
import math
from dataclasses import asdict, fields

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import recordings_checks, versions
from hybrid_sysid.config.loggers import validate_callbacks, validate_loggers
from hybrid_sysid.config.memory import check_memory
from hybrid_sysid.config.paths import check_paths
from hybrid_sysid.config.schema import SECTIONS
from hybrid_sysid.config.tags import check_tags
from hybrid_sysid.config.targets import arguments, build, check_objective_members, data_module, own_part
from hybrid_sysid.config.trainer import check_trainer, check_trainer_arguments
from hybrid_sysid.core.checks import ConfigError, bad, check_choice
from hybrid_sysid.core.options import TASKS
from hybrid_sysid.data.spec import (
    NOISE_MAX,
    NOISE_UNIT,
    BatchSettings,
    DatasetSpec,
    WindowSettings,
    check_eval_windows,
    check_seed,
)
from hybrid_sysid.model.optim import OptimSettings
from hybrid_sysid.physics import QuarterCar

CAR_FIELDS = tuple(asdict(QuarterCar()))
INT_MIN, INT_MAX = -(2**63), 2**63 - 1
# where the data's owners' arguments lie in the config, where it is not data.<argument>
CONFIG_PATHS = {
    "road_classes": "road.classes",
    "taps": "objective.filter.taps",
    "batch_size": "model.batch_size",
    "train_std": "noise.train_std",
    "train_std_max": "noise.train_std_max",
}


def config_key(key: str) -> str:
    """The config key of an argument of DatasetSpec, WindowSettings or BatchSettings (``car.<constant>`` and
    ``sensor.<key>`` stay)."""
    if key.startswith(("car.", "sensor.")):
        return key
    return CONFIG_PATHS.get(key, f"data.{key}")


def validate(cfg: DictConfig, training: bool = True, trains: bool = True) -> None:
    """Every check of a composed config, before any work.

    Parameters
    ----------
    cfg : omegaconf.DictConfig
        The composed config (a command line's, or a received run's saved one).
    training : bool
        False: a received run's saved config read to estimate with, without what only training here needs
        (loggers, callbacks, the dataset in memory, data.path's files).
    trains : bool
        False: an evaluation.

    Raises
    ------
    ConfigError
        The first bad value, naming its config key, the value and what is allowed.
    """
    _check_known_keys(cfg)
    # typed values (derived ones are checked later); the car's constants have their own check
    _check_finite({k: v for k, v in OmegaConf.to_container(cfg, resolve=False).items() if k != "car"}, "")
    check_seed("seed", cfg.seed)
    if not 0 <= cfg.get(versions.KEY, versions.VERSION) <= versions.VERSION:  # a saved config's own, or this one's
        bad(versions.KEY, cfg[versions.KEY], f"a version of the config schema, 0 to {versions.VERSION}")
    for key, value in cfg.car.items():
        if key not in CAR_FIELDS:
            bad(f"car.{key}", value, f"unknown; the car's constants are {', '.join(CAR_FIELDS)}")
    _check_task(cfg)
    _check_steps(cfg)
    figures = cfg.get("run_figures", "auto")
    if not (isinstance(figures, bool) or figures == "auto"):
        bad("run_figures", figures, "true, false or auto (a single run's figures, not a sweep job's)")
    _check_noise(cfg)
    check_paths(cfg)
    check_tags(cfg.get("tags"))
    check_trainer(cfg.trainer)
    with _placed("model.optim"):
        OptimSettings(**cfg.model.optim).validate()
    if training:
        validate_loggers(cfg)
        validate_callbacks(cfg)
        check_memory(cfg.data.n_roads, cfg.data.n_masses, cfg.data.n_steps)  # against the memory the process may use
    spec = DatasetSpec.from_config(cfg)
    with _placed():
        BatchSettings(cfg.model.batch_size, cfg.noise.train_std, cfg.noise.get("train_std_max")).validate()
        spec.validate_values() if cfg.data.get("path") else spec.validate()  # its stability search: the one that costs
    spec = recordings_checks.checked(cfg, spec, training, trains)  # data=recordings: its files (else spec as is)
    if cfg.get("baseline") is not None:  # each checks the window against what it reads
        _validate_baseline(cfg, spec)
    else:
        _validate_training(cfg, spec)
        if training:  # Lightning's own checks of the trainer's arguments, trainer.extra's too
            check_trainer_arguments(cfg.trainer)
    data_module(cfg)  # data.module's, when set: built, and checked against the run's objective or baseline
    check_eval_windows(cfg.evaluation.windows, WindowSettings.from_config(cfg).n_starts(spec), "evaluation.windows")


class _placed:
    """Within: a ConfigError of an owner's argument is raised again under its config key (``config_key``, or
    ``prefix`` + the argument)."""

    def __init__(self, prefix: str | None = None):
        self.prefix = prefix

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if isinstance(exc, ConfigError):
            raise (exc.under(self.prefix) if self.prefix else exc.with_key(config_key(exc.key))) from None
        return False


def _check_noise(cfg: DictConfig) -> None:
    levels = list(cfg.noise.eval_std)
    if not levels or not all(0 <= s <= NOISE_MAX for s in levels):
        allowed = (
            f"every standard deviation must lie in [0, {NOISE_MAX:g}] ({NOISE_UNIT}), at least one level (e.g. [0.0])"
        )
        bad("noise.eval_std", levels, allowed)
    curve_std = cfg.noise.get("curve_std")
    if curve_std is not None and not (curve_std and all(0 <= s <= NOISE_MAX for s in curve_std)):
        allowed = f"a list of standard deviations >= 0 and <= {NOISE_MAX:g} (at least one), or null for eval_std's"
        bad("noise.curve_std", list(curve_std), allowed)


def _check_steps(cfg: DictConfig) -> None:
    """A network's, objective's or baseline's ``dt`` (``${data.dt}`` in every preset) is the recordings' step: any
    other would read them at a step they were not sampled at (model.net.dt=0.01 on 0.005 s data: 50% off)."""
    for section in ("model.net", "objective", "baseline"):
        node = OmegaConf.select(cfg, section)
        step = node.get("dt") if isinstance(node, DictConfig) else None
        if step is not None and step != cfg.data.dt:
            bad(f"{section}.dt", step, f"the recordings' step, data.dt = {cfg.data.dt} (${{data.dt}})")


def _check_task(cfg: DictConfig) -> None:
    """task names what the job does; transfer and tuned need their section, a baseline runs alone."""
    task = cfg.get("task", "train")
    check_choice("task", task, TASKS)
    if task != "train" and cfg.get(task) is None:
        bad("task", task, f"a task with its settings under {task}: (experiment={task} gives them)")
    if cfg.get("baseline") is not None:
        if task != "train":
            bad("task", task, "train with a baseline (baseline=...), which runs alone")
        if cfg.get("init_from"):
            bad("init_from", cfg.init_from, "null with a baseline (baseline=...): it has no weights to start from")


def _check_known_keys(cfg: DictConfig) -> None:
    """A key the schema does not have: ``+data.n_road=3`` adds one (the ``+`` lifts the schema's own check)."""
    for section, schema in SECTIONS.items():
        node = OmegaConf.select(cfg, section) if section else cfg
        if not isinstance(node, DictConfig):
            continue
        known = [f.name for f in fields(schema)]
        for key in node.keys():
            if key not in known:
                name = f"{section}.{key}" if section else str(key)
                hint = difflib.get_close_matches(str(key), known, n=1)
                where = f"{section + '.' if section else ''}{hint[0]}" if hint else ""
                bad(
                    name,
                    OmegaConf.select(node, str(key), throw_on_missing=False),
                    f"unknown key (did you mean {where}?)"
                    if hint
                    else f"unknown key; {section or 'the config'} has " + ", ".join(known),
                )


def _check_finite(value, key: str) -> None:
    """inf or nan anywhere a float is accepted (noise levels, rates, time step, speed, weights...), and an integer
    beyond 64 bits anywhere (numpy and torch would overflow on it, far from its key)."""
    if isinstance(value, dict):
        for k, v in value.items():
            _check_finite(v, f"{key}.{k}" if key else str(k))
    elif isinstance(value, list):
        for v in value:
            if isinstance(v, float) and not math.isfinite(v):
                bad(key, value, "every value must be finite")
            _check_finite(v, key)
    elif isinstance(value, float) and not math.isfinite(value):
        bad(key, value, "must be finite")
    elif isinstance(value, int) and not isinstance(value, bool) and not INT_MIN <= value <= INT_MAX:
        bad(key, value, f"an integer in [{INT_MIN}, {INT_MAX}] (64 bits, as numpy and torch hold it)")


def _built(cfg: DictConfig, key: str):
    """The object at ``key`` (model.net, objective) built by its own constructor, whose errors name their argument
    under ``key``; any other failure is a ConfigError naming ``key`` with the failure's own words."""
    try:
        return build(OmegaConf.select(cfg, key), key)
    except ConfigError:
        raise
    except Exception as exc:  # noqa: BLE001 - a TypeError of a mistyped argument, say: the class names it
        raise ConfigError(key, allowed=_one_line(exc)) from exc


def _one_line(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {' '.join(str(exc).split())}"


def _validate_training(cfg: DictConfig, spec: DatasetSpec) -> None:
    """The network (its window bounds, then built and run on one window) and the objective (built: its filter
    must fit the window), before any data is simulated. This package's own classes are checked first without
    torch (config.targets.own_part), so a refusal of one of their values costs no torch import."""
    net, objective = own_part(cfg.model.net, "model.net"), own_part(cfg.objective, "objective")
    if net is not None and objective is not None:
        fits = (getattr(objective[0], name, None) for name in ("fir", "outside_fir"))
        with _placed():
            WindowSettings.from_config(cfg).validate(spec, net[1], *(None if f is None else len(f) for f in fits))
    cls, net_args = arguments(cfg.model.net, "model.net")
    try:
        bounds = cls.window_bounds(**net_args)
    except ConfigError as exc:  # the network's own check of an argument: placed under model.net
        raise exc.under("model.net") from None
    except Exception as exc:  # noqa: BLE001 - e.g. a value of the wrong type
        raise ConfigError("model.net", allowed=_one_line(exc)) from exc
    objective = _built(cfg, "objective")
    check_objective_members(objective, "objective")
    taps, outside = (None if f is None else len(f) for f in (objective.fir, objective.outside_fir))
    with _placed():
        WindowSettings.from_config(cfg).validate(spec, bounds, taps, outside)
    import torch  # deferred

    net = _built(cfg, "model.net")
    try:
        with torch.no_grad():
            net.eval()(torch.zeros(2, 2, cfg.data.window))
    except Exception as exc:  # noqa: BLE001 - a network that cannot read the window names its own problem
        allowed = f"a network that reads a window of data.window steps ({_one_line(exc)})"
        raise ConfigError("model.net", allowed=allowed) from exc


def _validate_baseline(cfg: DictConfig, spec: DatasetSpec) -> None:
    """A baseline (no network) checks its own arguments when built, and its band-pass against the lengths."""
    cls, kwargs = arguments(cfg.baseline, "baseline")
    if kwargs.get("unknown") == "m3" and spec.seat_spread > 0:
        bad(
            "baseline.unknown",
            "m3",
            f"needs the car's C3 and K3 on every recording, but data.seat_spread = {spec.seat_spread} varies them; "
            "use unknown=p",
        )
    with _placed():
        WindowSettings.from_config(cfg).validate(spec)
    baseline = _built(cfg, "baseline")
    with _placed("baseline"):
        baseline.check_lengths(cfg.data.window, cfg.data.n_steps)
