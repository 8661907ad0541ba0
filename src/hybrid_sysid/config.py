"""Structured-config schemas (Hydra's ConfigStore) and range checks with clear messages.

The schemas make an unknown key or a wrong type fail when Hydra composes the config. The range checks in
``validate`` run right after, before any data is simulated or any directory filled, and raise ConfigError
naming the key, the value and what is allowed.
"""

from __future__ import annotations

import difflib
import logging
import importlib.util
import math
import os
import re
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any, Dict, List, Optional

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf

from hybrid_sysid.data import DatasetSpec, split_by_road
from hybrid_sysid.data.dataset import CHANNELS, INTEGRATIONS
from hybrid_sysid.physics.filters import WEIGHTINGS, filter_taps
from hybrid_sysid.physics import DEFAULT_MEASUREMENT, QuarterCar

CONF_DIR = str(Path(__file__).resolve().parent / "conf")  # inside the package, so an installed wheel has it
SEED_MAX = 2**32 - 1  # numpy's and Lightning's seeds are 32-bit unsigned
log = logging.getLogger("hybrid_sysid")


class ConfigError(ValueError):
    """A config value outside what is allowed; the message names the key, the value and the allowed range."""


@dataclass
class DataConfig:
    n_roads: int = MISSING
    n_masses: int = MISSING
    n_steps: int = MISSING
    dt: float = MISSING
    speed: float = MISSING
    n_waves: int = 300
    amplitude: str = "paper"
    m3_min: int = 50
    m3_max: int = 200
    measurement: str = DEFAULT_MEASUREMENT
    seat_spread: float = 0.0
    window: int = 500
    integration: str = "t0"  # t0 | window (hybrid_sysid.data.datamodule.QCMData)
    train_fraction: float = 0.8
    val_fraction: float = 0.125
    seed: int = 0
    cache_dir: str = "outputs/.cache"


@dataclass
class RoadConfig:
    classes: List[str] = field(default_factory=lambda: list("ABCDE"))


@dataclass
class NoiseConfig:
    eval_std: List[float] = field(default_factory=lambda: [0.0, 0.01])
    train_std: float = 0.0


@dataclass
class OptimConfig:
    name: str = "adamw"
    lr: float = 3e-3
    weight_decay: float = 0.0
    schedule: str = "onecycle"
    warmup_fraction: float = 0.3


@dataclass
class ModelConfig:
    net: Dict[str, Any] = MISSING  # _target_ and the network's own arguments
    optim: OptimConfig = field(default_factory=OptimConfig)
    batch_size: int = 64


@dataclass
class TrainerConfig:
    max_steps: int = 6000
    eval_every_n_steps: int = 200
    curve_every_n_steps: Optional[int] = None  # learning-curve points; null: at every validation
    accelerator: str = "cpu"
    devices: Any = 1
    threads: Optional[int] = None
    deterministic: bool = True
    monitor: str = "auto"
    progress_bar: bool = True
    extra: Dict[str, Any] = field(default_factory=dict)  # passed to lightning.Trainer as is


@dataclass
class EvaluationConfig:
    # K values: for each K and test noise level, average the predictions on K fixed, seeded windows per
    # recording (K = 1: one window)
    windows: List[int] = field(default_factory=lambda: [1])


@dataclass
class TunedConfig:
    """experiment=tuned (hybrid_sysid.tuned): each objective searched with the same budget, then trained with its
    default and its best values on several seeds."""

    search: str = "fast_cnn"  # the hparams_search preset whose space and sampler the study uses
    n_trials: int = 12  # per objective; trial 0 is the model's default values
    trial_seed: int = 1000  # the trials' seed, apart from the seeds the table reports
    seeds: List[int] = field(default_factory=lambda: [0, 1, 2])


@dataclass
class Config:
    seed: int = 0
    resume: Optional[str] = None
    init_from: Optional[str] = None  # a run directory: start from its best weights
    data: DataConfig = MISSING
    road: RoadConfig = MISSING
    noise: NoiseConfig = MISSING
    model: ModelConfig = MISSING
    objective: Dict[str, Any] = MISSING  # _target_ and the objective's own arguments
    trainer: TrainerConfig = MISSING
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    # experiment trackers: name -> a Lightning logger's _target_ and arguments (conf/logger; {} for none)
    logger: Dict[str, Any] = field(default_factory=dict)
    # the car's constants (QuarterCar's fields; the group conf/car, car=paper by default), e.g. car.c3=700
    car: Dict[str, float] = field(default_factory=lambda: asdict(QuarterCar()))
    # experiment=transfer: a job is a chain of runs (hybrid_sysid.transfer); null for one run
    transfer: Optional[Dict[str, Any]] = None
    # experiment=tuned: a job searches one objective and trains its default and best values (hybrid_sysid.tuned)
    tuned: Optional[TunedConfig] = None


@dataclass
class EvalConfig(Config):
    """hybrid-sysid-eval's config (conf/eval.yaml): the training config's groups, to compose overrides, and the
    run to evaluate."""

    run: str = MISSING


def p_prior(which: str, *, _root_: DictConfig) -> list[float]:
    """``${p_prior:min}``, ``${p_prior:max}`` or ``${p_prior:scale}`` in the model and objective configs: the
    prior range of p = (C3, K3) / m3 for the config's car and seat masses, from p_min = (C3, K3) (1 - s) /
    data.m3_max to p_max = (C3, K3) (1 + s) / data.m3_min (s: data.seat_spread, 0 for the paper's data), or its
    midpoint (the label scale). Derived here, once, so an override of the car, of the mass range or of the seat
    spread moves the networks' bounds and the labelled objective's scale with the data."""
    spec = dataset_spec(_root_)
    s = spec.seat_spread
    p_min = [p * (1 - s) for p in spec.car.parameters(spec.m3_max)]
    p_max = [p * (1 + s) for p in spec.car.parameters(spec.m3_min)]
    pairs = {"min": p_min, "max": p_max, "scale": [(a + b) / 2 for a, b in zip(p_min, p_max)]}
    if which not in pairs:
        _bad("p_prior", which, f"one of {', '.join(pairs)}")
    return [float(v) for v in pairs[which]]


def register() -> None:
    """The schema for Hydra and two resolvers: ``p_prior`` (above), and ``first_set`` for the run directory
    (hydra.run.dir is ``resume`` when given, else a new time-stamped directory)."""
    ConfigStore.instance().store(name="schema", node=Config)
    ConfigStore.instance().store(name="eval_schema", node=EvalConfig)
    OmegaConf.register_new_resolver("first_set", lambda *xs: next((x for x in xs if x), None), replace=True)
    OmegaConf.register_new_resolver("p_prior", p_prior, replace=True)


def dataset_spec(cfg: DictConfig) -> DatasetSpec:
    """The values of the config that change the simulated data (the cache key)."""
    d = cfg.data
    return DatasetSpec(n_roads=d.n_roads, n_masses=d.n_masses, n_steps=d.n_steps, dt=d.dt, speed=d.speed,
                       n_waves=d.n_waves, amplitude=d.amplitude, road_classes=tuple(cfg.road.classes),
                       m3_min=d.m3_min, m3_max=d.m3_max, measurement=d.measurement, seed=d.seed,
                       car=QuarterCar(**cfg.get("car", {})), seat_spread=d.get("seat_spread", 0.0))


CAR_FIELDS = tuple(asdict(QuarterCar()))


def _bad(key: str, value, allowed: str):
    raise ConfigError(f"{key} = {value!r} is not allowed: {allowed}")


def validate(cfg: DictConfig) -> None:
    """Every range check, before any work. Checks that need the physics (stability) use its own functions."""
    d, t, o = cfg.data, cfg.trainer, cfg.model.optim
    _check_known_keys(cfg)
    # typed values (derived ones are checked later); the car's constants have their own check below
    _check_finite({k: v for k, v in OmegaConf.to_container(cfg, resolve=False).items() if k != "car"}, "")
    for key, value in (("seed", cfg.seed), ("data.seed", d.seed)):
        if not 0 <= value <= SEED_MAX:
            _bad(key, value, f"must lie in [0, {SEED_MAX}] (a 32-bit unsigned seed)")
    for key, value in cfg.car.items():
        if key not in CAR_FIELDS:
            _bad(f"car.{key}", value, f"unknown; the car's constants are {', '.join(CAR_FIELDS)}")
        if not (math.isfinite(value) and value > 0):
            _bad(f"car.{key}", value, "must be finite and > 0")
    try:
        dataset_spec(cfg).validate()
        split_by_road(d.n_roads, d.n_masses, d.train_fraction, d.val_fraction)
    except ConfigError:
        raise
    except ValueError as exc:  # the data layer's own messages already name the key
        raise ConfigError(str(exc)) from exc
    min_window = 59 if "PaperCNN" in str(cfg.model.net.get("_target_", "")) else 16
    if not min_window <= d.window <= d.n_steps:
        _bad("data.window", d.window, f"must lie in [{min_window}, data.n_steps = {d.n_steps}] "
             f"({min_window} = the shortest window the network's kernels fit)")
    for s in cfg.noise.eval_std:
        if not s >= 0:
            _bad("noise.eval_std", list(cfg.noise.eval_std), "every standard deviation must be >= 0")
    if not cfg.noise.eval_std:
        _bad("noise.eval_std", [], "give at least one level, e.g. [0.0]")
    if not cfg.noise.train_std >= 0:
        _bad("noise.train_std", cfg.noise.train_std, "must be >= 0")
    if cfg.model.batch_size < 1:
        _bad("model.batch_size", cfg.model.batch_size, "must be >= 1")
    if not o.lr > 0:
        _bad("model.optim.lr", o.lr, "must be > 0")
    if not o.weight_decay >= 0:
        _bad("model.optim.weight_decay", o.weight_decay, "must be >= 0")
    if not 0 < o.warmup_fraction < 1:
        _bad("model.optim.warmup_fraction", o.warmup_fraction, "must lie in (0, 1)")
    if t.max_steps < 1:
        _bad("trainer.max_steps", t.max_steps, "must be >= 1")
    if t.eval_every_n_steps < 1:
        _bad("trainer.eval_every_n_steps", t.eval_every_n_steps, "must be >= 1")
    curve_every = t.get("curve_every_n_steps")
    if curve_every is not None and not (curve_every >= 1 and curve_every % t.eval_every_n_steps == 0):
        _bad("trainer.curve_every_n_steps", curve_every, f"a multiple of trainer.eval_every_n_steps = "
             f"{t.eval_every_n_steps} (curve points are taken at validations), or null for every validation")
    if t.threads is not None and t.threads < 1:
        _bad("trainer.threads", t.threads, "must be >= 1, or null for torch's default")
    if t.monitor not in ("auto", "val/loss", "val/rel_dev", "val/p1_rel_dev", "val/p2_rel_dev"):
        _bad("trainer.monitor", t.monitor, "one of auto, val/loss, val/rel_dev, val/p1_rel_dev, val/p2_rel_dev")
    windows = list(cfg.evaluation.windows)
    n_starts = d.n_steps - d.window + 1
    if not windows or any(isinstance(k, bool) or not isinstance(k, int) or not 1 <= k <= n_starts for k in windows):
        _bad("evaluation.windows", windows, f"a non-empty list of integers K in [1, data.n_steps - data.window + 1 "
             f"= {n_starts}] (windows per recording)")
    if d.integration not in INTEGRATIONS:
        _bad("data.integration", d.integration, f"one of {', '.join(INTEGRATIONS)}")
    _validate_baseline(cfg)
    validate_loggers(cfg)
    obj = cfg.objective
    net = cfg.model.net
    if net.get("unknown") == "m3" and d.get("seat_spread", 0.0) > 0:
        _bad("model.net.unknown", "m3", f"needs the car's C3 and K3 on every recording, but data.seat_spread = "
             f"{d.seat_spread} varies them; use unknown=p")
    if obj.get("filter") is not None:
        try:
            taps = len(filter_taps(OmegaConf.to_container(obj.filter), d.dt))
        except ValueError as exc:  # the message names the key
            raise ConfigError(str(exc)) from exc
        if taps > d.window - 9:
            _bad("objective.filter.taps", taps, f"must be <= data.window - 9 = {d.window - 9} (the band-pass must "
                 "leave at least 10 samples of each window)")
    if obj.get("weighting", "none") not in WEIGHTINGS:
        _bad("objective.weighting", obj.weighting, f"one of {', '.join(WEIGHTINGS)}")
    if obj.get("weighting", "none") == "eiv" and obj.get("filter") is None:
        _bad("objective.weighting", "eiv", "needs objective.filter (integrated noise has no finite variance)")
    if "labelled_weight" in obj or "hybrid_weight" in obj:
        lw, hw = obj.get("labelled_weight", 0.0), obj.get("hybrid_weight", 0.0)
        if lw < 0 or hw < 0 or lw + hw == 0:
            _bad("objective.labelled_weight / objective.hybrid_weight", [lw, hw],
                 "both must be >= 0 and not both zero")
    _validate_training(cfg)
    check_memory(cfg)


# the schema's sections, whose keys are fixed (model.net, objective, car and trainer.extra are free-form)
_SECTIONS = {"": Config, "data": DataConfig, "road": RoadConfig, "noise": NoiseConfig, "model": ModelConfig,
             "model.optim": OptimConfig, "trainer": TrainerConfig, "evaluation": EvaluationConfig,
             "tuned": TunedConfig}


def _check_known_keys(cfg: DictConfig) -> None:
    """A key the schema does not have: ``+data.n_road=3`` adds one (the ``+`` lifts the schema's own check)."""
    for section, schema in _SECTIONS.items():
        node = OmegaConf.select(cfg, section) if section else cfg
        if not isinstance(node, DictConfig):
            continue
        known = [f.name for f in fields(schema)]
        for key in node.keys():
            if key not in known:
                name = f"{section}.{key}" if section else str(key)
                hint = difflib.get_close_matches(str(key), known, n=1)
                _bad(name, OmegaConf.select(node, str(key), throw_on_missing=False),
                     "unknown key" + (f" (did you mean {section + '.' if section else ''}{hint[0]}?)" if hint
                                      else f"; {section or 'the config'} has {', '.join(known)}"))


def _check_finite(value, key: str) -> None:
    """inf or nan anywhere a float is accepted (noise levels, rates, time step, speed, weights...)."""
    if isinstance(value, dict):
        for k, v in value.items():
            _check_finite(v, f"{key}.{k}" if key else str(k))
    elif isinstance(value, list):
        for v in value:
            if isinstance(v, float) and not math.isfinite(v):
                _bad(key, value, "every value must be finite")
            _check_finite(v, key)
    elif isinstance(value, float) and not math.isfinite(value):
        _bad(key, value, "must be finite")


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
        _bad("data.n_roads * data.n_masses * data.n_steps", f"{d.n_roads} * {d.n_masses} * {d.n_steps}",
             f"the dataset needs about {need / 2**30:.3g} GiB, more than the {available / 2**30:.3g} GiB of "
             "memory available")


def _one_line(exc: BaseException) -> str:
    """The innermost message of an exception chain (instantiate wraps the constructor's), on one line."""
    while exc.__cause__ is not None:
        exc = exc.__cause__
    return " ".join(str(exc).split())


def _validate_training(cfg: DictConfig) -> None:
    """The optimiser, its schedule, the network (built, and run on one window) and the objective (built): their
    own checks, before any data is simulated."""
    o = cfg.model.optim
    from hybrid_sysid.baselines import is_baseline
    from hybrid_sysid.model.module import OPTIMIZERS, SCHEDULES

    if is_baseline(str(cfg.model.net.get("_target_", ""))):
        return
    if o.name not in OPTIMIZERS:
        _bad("model.optim.name", o.name, f"one of {', '.join(OPTIMIZERS)}")
    if o.schedule not in SCHEDULES:
        _bad("model.optim.schedule", o.schedule, f"one of {', '.join(SCHEDULES)}")
    import torch
    from hydra.utils import instantiate

    for key in ("model.net", "objective"):
        try:
            built = instantiate(OmegaConf.select(cfg, key), _convert_="all")
            if key == "model.net":
                with torch.no_grad():
                    built.eval()(torch.zeros(2, int(cfg.model.net.get("in_channels", 2)), cfg.data.window))
        except Exception as exc:  # noqa: BLE001 - TypeError (unknown argument), ValueError (its own checks)...
            message = _one_line(exc)
            # the networks' and objectives' messages start with the argument's name: give it its config key
            if not message.startswith(key):
                message = f"{key}.{message}" if re.match(r"\w+ = ", message) else f"{key}: {message}"
            raise ConfigError(message) from exc


def check_resume(run_dir: Path, cfg: DictConfig) -> None:
    """``resume=run_dir`` must name a run (Hydra's saved .hydra/config.yaml, written before any of its work) of
    this config: every value but those that cannot change the numbers (where the run's files and the cache
    lie, the progress bar) must be the same. Raises ConfigError naming the differing keys."""
    saved_path = run_dir / ".hydra" / "config.yaml"
    if not run_dir.is_dir():
        _bad("resume", str(run_dir), "no such directory; give the directory of the run to continue")
    if not saved_path.is_file():
        _bad("resume", str(run_dir), "the directory holds no run (no .hydra/config.yaml)")
    try:
        saved = OmegaConf.to_container(OmegaConf.load(saved_path), resolve=False)
    except Exception as exc:  # noqa: BLE001 - a damaged file cannot tell; the run's own files still resume
        log.warning("%s is unreadable (%s); resuming without comparing the configs", saved_path, exc)
        return
    now, was = flatten(OmegaConf.to_container(cfg, resolve=False)), flatten(saved if isinstance(saved, dict) else {})
    differ = [k for k in sorted(set(now) | set(was))
              if k not in RESUME_FREE and now.get(k, "(unset)") != was.get(k, "(unset)")]
    if differ:
        shown = "; ".join(f"{k} = {was.get(k, '(unset)')!r} there, {now.get(k, '(unset)')!r} here" for k in differ[:3])
        _bad("resume", str(run_dir), f"it holds a run of another config ({shown}"
             f"{'; ...' if len(differ) > 3 else ''}); resume with the run's own values")


RESUME_FREE = {"resume", "data.cache_dir", "trainer.progress_bar"}


def flatten(tree: dict, prefix: str = "") -> dict:
    """A nested dict as {dotted.key: leaf} (an empty dict is a leaf too)."""
    out = {}
    for k, v in tree.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and v:
            out.update(flatten(v, key + "."))
        else:
            out[key] = v
    return out


# a logger class -> the modules it can run on (any one of them); they come with the "loggers" extra
LOGGER_MODULES = {"TensorBoardLogger": ("tensorboard", "tensorboardX"), "MLFlowLogger": ("mlflow",)}
LOGGERS_EXTRA = 'pip install -e ".[loggers]"'


def validate_loggers(cfg: DictConfig) -> None:
    """Each configured logger names a class, and the library it needs is installed."""
    for name, lg in (cfg.get("logger") or {}).items():
        target = str(lg.get("_target_", "")) if isinstance(lg, DictConfig) else ""
        if not target:
            _bad(f"logger.{name}", lg, "a mapping with the _target_ of a Lightning logger (see conf/logger)")
        needs = next((mods for cls, mods in LOGGER_MODULES.items() if target.endswith("." + cls)), ())
        if needs and not any(importlib.util.find_spec(m) for m in needs):
            raise ConfigError(f"logger.{name} needs the {needs[0]} package, which is not installed: {LOGGERS_EXTRA}")


def _validate_baseline(cfg: DictConfig) -> None:
    """A baseline (no network) checks its own arguments when built: build it here, before any work."""
    from hydra.utils import get_class
    from omegaconf import OmegaConf

    from hybrid_sysid.baselines import is_baseline

    if not is_baseline(str(cfg.model.net.get("_target_", ""))):
        return
    kwargs = OmegaConf.to_container(cfg.model.net, resolve=True)
    cls = get_class(kwargs.pop("_target_"))
    try:  # called directly: instantiate() would wrap the one-line message in its own
        cls(**kwargs).check_lengths(cfg.data.window, cfg.data.n_steps)
    except ValueError as exc:  # the baseline's messages already name the key
        raise ConfigError(str(exc)) from exc


register()  # composing the app's config (the app, tests, notebooks) needs both
