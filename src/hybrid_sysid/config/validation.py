"""``validate(cfg)``: every check of a composed config, before any data is simulated or any directory filled.

Each value is checked by the object that owns it: the data's by DatasetSpec and WindowSettings, the network's
and the objective's by their constructors (the network built once and run on one window), a baseline's by its
own; this module adds what belongs to no object (seeds, noise levels, the trainer, the memory bound) and turns
every message into one line naming the config key (ConfigError).
"""

from __future__ import annotations

import difflib
import importlib.util
import logging
import math
import os
import re
from dataclasses import asdict, fields
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config.schema import SECTIONS
from hybrid_sysid.config.targets import arguments, build, check_target
from hybrid_sysid.core.checks import ConfigError, bad, check_choice
from hybrid_sysid.core.install import install_command
from hybrid_sysid.core.options import MONITORS, OPTIMIZERS, PROFILERS, SCHEDULES, TASKS
from hybrid_sysid.data.dataset import CHANNELS
from hybrid_sysid.data.spec import DatasetSpec, WindowSettings, check_eval_windows
from hybrid_sysid.physics import QuarterCar

SEED_MAX = 2**32 - 1  # numpy's and Lightning's seeds are 32-bit unsigned
CAR_FIELDS = tuple(asdict(QuarterCar()))
log = logging.getLogger("hybrid_sysid")


def window_settings(cfg: DictConfig) -> WindowSettings:
    """The data section's WindowSettings, read by field name."""
    return WindowSettings(**{f.name: cfg.data[f.name] for f in fields(WindowSettings)})


def validate(cfg: DictConfig) -> None:
    """Every check, before any work; raises ConfigError naming the key, the value and what is allowed."""
    d, t, o = cfg.data, cfg.trainer, cfg.model.optim
    _check_known_keys(cfg)
    # typed values (derived ones are checked later); the car's constants have their own check below
    _check_finite({k: v for k, v in OmegaConf.to_container(cfg, resolve=False).items() if k != "car"}, "")
    for key, value in (("seed", cfg.seed), ("data.seed", d.seed)):
        if not 0 <= value <= SEED_MAX:
            bad(key, value, f"must lie in [0, {SEED_MAX}] (a 32-bit unsigned seed)")
    for key, value in cfg.car.items():
        if key not in CAR_FIELDS:
            bad(f"car.{key}", value, f"unknown; the car's constants are {', '.join(CAR_FIELDS)}")
        if not (math.isfinite(value) and value > 0):
            bad(f"car.{key}", value, "must be finite and > 0")
    _check_task(cfg)
    figures = cfg.get("run_figures", "auto")
    if not (isinstance(figures, bool) or figures == "auto"):
        bad("run_figures", figures, "true, false or auto (a single run's figures, not a sweep job's)")
    spec = DatasetSpec.from_config(cfg)
    spec.validate()
    for s in cfg.noise.eval_std:
        if not s >= 0:
            bad("noise.eval_std", list(cfg.noise.eval_std), "every standard deviation must be >= 0")
    if not cfg.noise.eval_std:
        bad("noise.eval_std", [], "give at least one level, e.g. [0.0]")
    curve_std = cfg.noise.get("curve_std")
    if curve_std is not None and not (curve_std and all(s >= 0 for s in curve_std)):
        allowed = "a list of standard deviations >= 0 (at least one), or null for eval_std's"
        bad("noise.curve_std", list(curve_std), allowed)
    if not cfg.noise.train_std >= 0:
        bad("noise.train_std", cfg.noise.train_std, "must be >= 0")
    if cfg.model.batch_size < 1:
        bad("model.batch_size", cfg.model.batch_size, "must be >= 1")
    if not o.lr > 0:
        bad("model.optim.lr", o.lr, "must be > 0")
    if not o.weight_decay >= 0:
        bad("model.optim.weight_decay", o.weight_decay, "must be >= 0")
    if not 0 < o.warmup_fraction < 1:
        bad("model.optim.warmup_fraction", o.warmup_fraction, "must lie in (0, 1)")
    check_choice("model.optim.name", o.name, OPTIMIZERS)
    check_choice("model.optim.schedule", o.schedule, SCHEDULES)
    if t.max_steps < 1:
        bad("trainer.max_steps", t.max_steps, "must be >= 1")
    if t.eval_every_n_steps < 1:
        bad("trainer.eval_every_n_steps", t.eval_every_n_steps, "must be >= 1")
    curve_every = t.get("curve_every_n_steps")
    if curve_every is not None and not (curve_every >= 1 and curve_every % t.eval_every_n_steps == 0):
        bad(
            "trainer.curve_every_n_steps",
            curve_every,
            f"a multiple of trainer.eval_every_n_steps = "
            f"{t.eval_every_n_steps} (curve points are taken at validations), or null for every validation",
        )
    if t.threads is not None and t.threads < 1:
        bad("trainer.threads", t.threads, "must be >= 1, or null for torch's default")
    check_choice("trainer.monitor", t.monitor, MONITORS)
    if not (isinstance(t.progress_bar, bool) or t.progress_bar == "auto"):
        bad("trainer.progress_bar", t.progress_bar, "true, false or auto (a bar when stdout is a terminal)")
    if t.get("profiler") is not None:
        check_choice("trainer.profiler", t.profiler, PROFILERS)
    validate_loggers(cfg)
    validate_callbacks(cfg)
    if cfg.get("baseline") is not None:  # each checks the window against what it reads
        _validate_baseline(cfg, spec)
    else:
        _validate_training(cfg, spec)
    check_eval_windows(cfg.evaluation.windows, window_settings(cfg).n_starts(spec))
    check_memory(cfg)


def _check_task(cfg: DictConfig) -> None:
    """task names what the job does; transfer and tuned need their section, a baseline runs alone."""
    task = cfg.get("task", "train")
    check_choice("task", task, TASKS)
    if task != "train" and cfg.get(task) is None:
        bad("task", task, f"needs its settings under {task}: (experiment={task} gives them)")
    if cfg.get("baseline") is not None:
        if task != "train":
            bad("task", task, "a baseline (baseline=...) runs alone: task=train")
        if cfg.get("init_from"):
            bad("init_from", cfg.init_from, "not with a baseline (baseline=...): it has no weights to start from")


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
                bad(
                    name,
                    OmegaConf.select(node, str(key), throw_on_missing=False),
                    "unknown key"
                    + (
                        f" (did you mean {section + '.' if section else ''}{hint[0]}?)"
                        if hint
                        else f"; {section or 'the config'} has {', '.join(known)}"
                    ),
                )


def _check_finite(value, key: str) -> None:
    """inf or nan anywhere a float is accepted (noise levels, rates, time step, speed, weights...)."""
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


def available_memory() -> int | None:
    """Bytes of memory available to this process: the kernel's MemAvailable, capped by a cgroup (container,
    cluster job) limit; None where neither can be read."""
    found = []
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                found.append(int(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        try:
            found.append(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (OSError, ValueError, AttributeError):
            pass
    try:
        cg = Path("/sys/fs/cgroup")
        limit = (cg / "memory.max").read_text().strip()
        if limit != "max":
            found.append(int(limit) - int((cg / "memory.current").read_text()))
    except (OSError, ValueError):
        pass
    return min(found) if found else None


def dataset_bytes(cfg: DictConfig) -> int:
    """What a dataset needs in memory while it is simulated and stored: every channel of every recording at
    8 bytes (float32 channels, plus the copy that checksums or loads them) and the float64 road profiles
    (twice: the profile and the wave sum it is built from)."""
    d = cfg.data
    n_recordings = d.n_roads * d.n_masses
    return n_recordings * d.n_steps * len(CHANNELS) * 8 + 2 * d.n_roads * d.n_steps * 8


def check_memory(cfg: DictConfig) -> None:
    need, available = dataset_bytes(cfg), available_memory()
    if available is not None and need > available:
        d = cfg.data
        bad(
            "data.n_roads * data.n_masses * data.n_steps",
            f"{d.n_roads} * {d.n_masses} * {d.n_steps}",
            f"the dataset needs about {need / 2**30:.3g} GiB, more than the {available / 2**30:.3g} GiB of "
            "memory available",
        )


def _one_line(exc: BaseException) -> str:
    """The innermost message of an exception chain (instantiate wraps the constructor's), on one line."""
    while exc.__cause__ is not None:
        exc = exc.__cause__
    return " ".join(str(exc).split())


def _built(cfg: DictConfig, key: str):
    """The object at ``key`` (model.net, objective) built by its own constructor, whose checks name their
    argument: a ConfigError naming the config key otherwise."""
    try:
        return build(OmegaConf.select(cfg, key), key)
    except ConfigError:
        raise
    except Exception as exc:  # noqa: BLE001 - TypeError (unknown argument), ValueError (its own checks)...
        raise _named(exc, key) from exc


def _named(exc: BaseException, key: str) -> ConfigError:
    message = _one_line(exc)
    # the networks' and objectives' messages start with the argument's name: give it its config key
    if not message.startswith(key):
        message = f"{key}.{message}" if re.match(r"\w+ = ", message) else f"{key}: {message}"
    return ConfigError(message)


def _validate_training(cfg: DictConfig, spec: DatasetSpec) -> None:
    """The network (its shortest window, then built and run on one window) and the objective (built: its filter
    must fit the window), before any data is simulated."""
    cls, net_args = arguments(cfg.model.net, "model.net")
    try:
        shortest = cls.shortest_window(**net_args)
    except Exception as exc:  # noqa: BLE001 - e.g. a value of the wrong type
        raise _named(exc, "model.net") from exc
    objective = _built(cfg, "objective")
    fir = getattr(objective, "fir", None)
    window_settings(cfg).validate(spec, min_window=shortest, taps=None if fir is None else len(fir))
    import torch

    net = _built(cfg, "model.net")
    try:
        with torch.no_grad():
            net.eval()(torch.zeros(2, int(cfg.model.net.get("in_channels", 2)), cfg.data.window))
    except Exception as exc:  # noqa: BLE001 - a network that cannot read the window names its own problem
        raise _named(exc, "model.net") from exc


def _validate_baseline(cfg: DictConfig, spec: DatasetSpec) -> None:
    """A baseline (no network) checks its own arguments when built, and its band-pass against the lengths."""
    cls, kwargs = arguments(cfg.baseline, "baseline")
    if kwargs.get("unknown") == "m3" and spec.seat_spread > 0:
        bad(
            "baseline.unknown",
            "m3",
            f"needs the car's C3 and K3 on every recording, but data.seat_spread = "
            f"{spec.seat_spread} varies them; use unknown=p",
        )
    window_settings(cfg).validate(spec)
    try:  # called directly: instantiate() would wrap the one-line message in its own
        cls(**kwargs).check_lengths(cfg.data.window, cfg.data.n_steps)
    except ValueError as exc:  # its messages name the key already (baseline.<argument>)
        raise _named(exc, "baseline") from exc


# a logger class -> the modules it can run on (any one of them); they come with the "loggers" extra
LOGGER_MODULES = {"TensorBoardLogger": ("tensorboard", "tensorboardX"), "MLFlowLogger": ("mlflow",)}


def validate_loggers(cfg: DictConfig) -> None:
    """Each configured logger names a class, and the library it needs is installed."""
    for name, lg in (cfg.get("logger") or {}).items():
        target = str(lg.get("_target_", "")) if isinstance(lg, DictConfig) else ""
        if not target:
            bad(f"logger.{name}", lg, "a mapping with the _target_ of a Lightning logger (see conf/logger)")
        check_target(target, f"logger.{name}")
        needs = next((mods for cls, mods in LOGGER_MODULES.items() if target.endswith("." + cls)), ())
        if needs and not any(importlib.util.find_spec(m) for m in needs):
            raise ConfigError(
                f"logger.{name} needs the {needs[0]} package, which is not installed: {install_command('loggers')}"
            )


# a callback class -> the module it needs; it comes with the "rich" extra
CALLBACK_MODULES = {"RichProgressBar": "rich", "RichModelSummary": "rich"}


def validate_callbacks(cfg: DictConfig) -> None:
    """Each configured callback (conf/callbacks) names an allowed class, the library it needs is installed, and
    a monitor it watches is one trainer.monitor may name (auto: the run's own)."""
    for name, cb in (cfg.get("callbacks") or {}).items():
        target = str(cb.get("_target_", "")) if isinstance(cb, DictConfig) else ""
        if not target:
            bad(f"callbacks.{name}", cb, "a mapping with the _target_ of a Lightning callback (see conf/callbacks)")
        check_target(target, f"callbacks.{name}")
        module = CALLBACK_MODULES.get(target.rsplit(".", 1)[-1])
        if module and not importlib.util.find_spec(module):
            raise ConfigError(
                f"callbacks.{name} needs the {module} package, which is not installed: {install_command('rich')}"
            )
        if "monitor" in cb:
            check_choice(f"callbacks.{name}.monitor", cb.monitor, MONITORS)
