"""Structured-config schemas (Hydra's ConfigStore): an unknown key or a wrong type fails when Hydra composes.

One dataclass per section of the config. The data section has no list of its own: its keys are the fields of
``DatasetSpec`` (what changes the simulated data) and ``WindowSettings`` (how the data module cuts it), plus
where the cache lies, so a new data value is declared once, where it is used. Likewise model.optim is the fields of
``OptimSettings`` (``section_of``: the class is the schema).
"""

from __future__ import annotations

import typing
from dataclasses import MISSING as NO_DEFAULT
from dataclasses import asdict, dataclass, field, fields, make_dataclass
from pathlib import Path
from typing import Any, Dict, List, Optional

from omegaconf import MISSING

from hybrid_sysid.config.versions import VERSION
from hybrid_sysid.data.spec import OUTSIDE_DATA, DatasetSpec, WindowSettings
from hybrid_sysid.model.optim import OptimSettings
from hybrid_sysid.physics import QuarterCar
from hybrid_sysid.physics.faults import settings as fault_settings

CONF_DIR = str(Path(__file__).resolve().parents[1] / "conf")  # inside the package, so an installed wheel has it


def _data_fields() -> list:
    out = []
    for cls in (DatasetSpec, WindowSettings):
        hints = typing.get_type_hints(cls)
        for f in fields(cls):
            if f.name not in OUTSIDE_DATA:
                default = f.default if f.default is not NO_DEFAULT else MISSING
                out.append((f.name, hints[f.name], field(default=default)))
    out.append(("module", Optional[Dict[str, Any]], field(default=None)))  # a plugin's: targets.data_module
    recordings = [  # data=recordings: a user's files (data.recordings); null: the simulator's recordings
        ("path", Optional[str], field(default=None)),
        ("labels", Optional[str], field(default=None)),
    ]
    return out + [("cache_dir", str, field(default="${paths.cache_dir}"))] + recordings


DataConfig = make_dataclass("DataConfig", _data_fields())
DataConfig.__doc__ = "The data section: DatasetSpec's and WindowSettings' fields, cache_dir, and a user's files."


@dataclass
class PathsConfig:
    """Where everything is written (conf/paths): runs, sweeps, evaluations, the dataset cache and the trackers'
    stores, all under ``root`` by default, so paths.root=/somewhere moves them at once."""

    root: str = "outputs"
    runs_dir: str = "${paths.root}/runs"  # single runs (hydra.run.dir)
    multirun_dir: str = "${paths.root}/multirun"  # sweeps (hydra.sweep.dir)
    evals_dir: str = "${paths.root}/evals"  # hybrid-sysid-eval's single runs
    cache_dir: str = "${oc.env:HYBRID_SYSID_CACHE,${paths.root}/.cache}"  # simulated datasets (data.cache_dir)
    trackers_dir: str = "${paths.root}"  # experiment trackers' stores (logger=mlflow's mlflow.db)


@dataclass
class RoadConfig:
    classes: List[str] = field(default_factory=lambda: list("ABCDE"))


@dataclass
class NoiseConfig:
    # the test noise levels of the final evaluation and the learning curves (hybrid_sysid.training)
    eval_std: List[float] = field(default_factory=lambda: [0.0, 0.01])
    train_std: float = 0.0
    # set: each training window's std log-uniform in [train_std, train_std_max], validation at their geometric
    # mean (docs/noise.md); null: every window at train_std
    train_std_max: Optional[float] = None
    # the learning curves' test noise levels; null: every level of eval_std
    curve_std: Optional[List[float]] = None


def sensor_section() -> type:
    """The recording's sensor faults (conf/sensor, docs/faults.md) as a section: the settings of every registered
    sensor fault (hybrid_sysid.physics.faults), all off by default; drawn per recording, keyed in the cache when on."""
    section = make_dataclass(
        "SensorConfig", [(name, s.type, field(default=s.default)) for name, s in fault_settings("sensor").items()]
    )
    section.__doc__ = "The settings of every registered sensor fault (hybrid_sysid.physics.faults), as a section."
    return section


SensorConfig = sensor_section()  # of the faults registered when the schema is imported (installed ones included)


def section_of(owner: type, name: str) -> type:
    """A config section whose keys, types and defaults are the fields of ``owner``, the class that checks and uses
    them (the class is the schema), as a dataclass Hydra may merge overrides into (the owner may be frozen)."""
    hints = typing.get_type_hints(owner)
    section = make_dataclass(name, [(f.name, hints[f.name], field(default=f.default)) for f in fields(owner)])
    section.__doc__ = f"The fields of {owner.__module__}.{owner.__qualname__}, as a config section."
    return section


OptimConfig = section_of(OptimSettings, "OptimConfig")  # model.optim


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
    devices: Any = 1  # processes (DDP ranks) a node
    num_nodes: int = 1  # nodes of a DDP training: num_nodes x devices ranks in all
    threads: Optional[int] = None
    deterministic: bool = True
    monitor: str = "auto"
    progress_bar: Any = "auto"  # true, false, or auto: a bar when stdout is a terminal
    profiler: Optional[str] = None  # simple or advanced: Lightning's profiler, its report in the run directory
    extra: Dict[str, Any] = field(default_factory=dict)  # passed to lightning.Trainer as is


@dataclass
class EvaluationConfig:
    # K values: for each K and test noise level, average the predictions on K fixed, seeded windows per
    # recording (K = 1: one window)
    windows: List[int] = field(default_factory=lambda: [1])


@dataclass
class TransferConfig:
    """task=transfer (hybrid_sysid.experiments.transfer): a labelled network on the config's car, then on each
    scenario's target: evaluated, adapted without labels, a label-free objective from scratch, a labelled oracle,
    and optionally a baseline without a network."""

    adapt_steps: int = 600  # label-free steps from the source network's weights
    adapt_lr: float = 5e-3
    # label-free objective presets (conf/objective), one adapted row each; [] for none
    adapt_objectives: List[str] = field(default_factory=lambda: ["hybrid"])
    scratch_objective: str = "hybrid"  # the label-free objective preset of the from-scratch row
    anchored_objectives: List[str] = field(default_factory=list)  # label-free presets: model=anchored from scratch
    baseline: Optional[str] = None  # a baseline preset (conf/baseline, e.g. ls_bandpass) for a row without network
    scenarios: Dict[str, Any] = field(default_factory=dict)  # name -> {car: a car preset, data: {key: value}}


@dataclass
class TunedConfig:
    """task=tuned (hybrid_sysid.experiments.tuned): each objective searched with the same budget, then trained with
    its default and its best values on several seeds."""

    search: str = "fast_cnn"  # the hparams_search preset whose space and sampler the study uses
    n_trials: int = 12  # per objective; trial 0 is the model's default values
    trial_seed: int = 1000  # the trials' seed, apart from the seeds the table reports
    seeds: List[int] = field(default_factory=lambda: [0, 1, 2])


@dataclass
class Config:
    # the schema's version, saved with the config (first, so a file cut short keeps it): a reader fills in the keys
    # added since (config.versions)
    schema_version: int = VERSION
    # what a job does (core.options.TASKS): one run, a transfer chain (transfer:), a tuned comparison (tuned:)
    task: str = "train"
    seed: int = 0
    resume: Optional[str] = None
    init_from: Optional[str] = None  # a run directory: start from its best weights
    run_figures: Any = "auto"  # a run's figures/: true, false, or auto (a single run yes, a sweep's jobs no)
    tags: List[str] = field(default_factory=list)  # the user's labels: in metrics.json and the trackers (tags=[a,b])
    data: DataConfig = MISSING
    road: RoadConfig = MISSING
    noise: NoiseConfig = MISSING
    model: ModelConfig = MISSING
    objective: Dict[str, Any] = MISSING  # _target_ and the objective's own arguments
    # a baseline without a network (conf/baseline, e.g. baseline=ls_bandpass): _target_ and its arguments; when
    # set, the run evaluates it instead of training model and objective
    baseline: Optional[Dict[str, Any]] = None
    trainer: TrainerConfig = MISSING
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    # experiment trackers: name -> a Lightning logger's _target_ and arguments (conf/logger; {} for none)
    logger: Dict[str, Any] = field(default_factory=dict)
    # Lightning callbacks beside the run's own: name -> a callback's _target_ and arguments (conf/callbacks; {})
    callbacks: Dict[str, Any] = field(default_factory=dict)
    paths: PathsConfig = field(default_factory=PathsConfig)  # where runs, sweeps, cache and trackers go (conf/paths)
    # the car's constants (QuarterCar's fields; the group conf/car, car=paper by default), e.g. car.c3=700
    car: Dict[str, float] = field(default_factory=lambda: asdict(QuarterCar()))
    sensor: SensorConfig = field(default_factory=SensorConfig)  # the recording's sensor faults (conf/sensor)
    transfer: Optional[TransferConfig] = None  # task=transfer's settings
    tuned: Optional[TunedConfig] = None  # task=tuned's settings


@dataclass
class EvalConfig(Config):
    """hybrid-sysid-eval's config (conf/eval.yaml): the training config's groups, to compose overrides, and the
    run to evaluate."""

    run: str = MISSING


# the schema's sections, whose keys are fixed (model.net, objective, baseline, car, logger, callbacks and
# trainer.extra are free-form)
SECTIONS = {
    "": Config,
    "paths": PathsConfig,
    "data": DataConfig,
    "road": RoadConfig,
    "noise": NoiseConfig,
    "sensor": SensorConfig,
    "model": ModelConfig,
    "model.optim": OptimConfig,
    "trainer": TrainerConfig,
    "evaluation": EvaluationConfig,
    "transfer": TransferConfig,
    "tuned": TunedConfig,
}


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
