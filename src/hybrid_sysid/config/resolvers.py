"""The config's resolvers and its registration with Hydra: ``${p_prior:...}`` derives the prior of p from the
car and the data, ``${first_set:...}`` picks the run directory, ``${fault_fix:}`` the least-squares fix of a fault,
``${slurm_mem_gb:...}`` the memory a SLURM job asks (``${hydra_subdir:...}``, where Hydra saves a job's config, is the
runs layer's: hybrid_sysid/runs/__init__.py)."""

from __future__ import annotations

import math

from hydra.core.config_store import ConfigStore
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config.memory import dataset_bytes
from hybrid_sysid.config.schema import Config, EvalConfig
from hybrid_sysid.core.checks import bad
from hybrid_sysid.data.spec import DatasetSpec
from hybrid_sysid.physics.faults import fix_for


def p_prior(which: str, *, _root_: DictConfig) -> list[float]:
    """``${p_prior:min}``, ``${p_prior:max}`` or ``${p_prior:scale}`` in the model and objective configs: the
    prior range of p = (C3, K3) / m3 for the config's car and seat masses, from p_min = (C3, K3) (1 - s) /
    data.m3_max to p_max = (C3, K3) (1 + s) / data.m3_min (s: data.seat_spread, 0 for the paper's data), or its
    midpoint (the label scale). Derived here, once, so an override of the car, of the mass range or of the seat
    spread moves the networks' bounds and the labelled objective's scale with the data."""
    spec = DatasetSpec.from_config(_root_)
    s = spec.seat_spread
    p_min = [p * (1 - s) for p in spec.car.parameters(spec.m3_max)]
    p_max = [p * (1 + s) for p in spec.car.parameters(spec.m3_min)]
    pairs = {"min": p_min, "max": p_max, "scale": [(a + b) / 2 for a, b in zip(p_min, p_max)]}
    if which not in pairs:
        bad("p_prior", which, f"one of {', '.join(pairs)}")
    return [float(v) for v in pairs[which]]


def fault_fix(*, _root_: DictConfig) -> str:
    """``${fault_fix:}`` in conf/estimator/ls_fix.yaml: the classical fix (baselines.fixes) of the fault the config
    simulates, as each fault declares it (physics.faults: a low-pass that differs between the sensors is, in the
    seat band, close to a delay, so it gets the skew fix). With several faults on, that of the lowest fix_rank
    (hardening, then skew, then gain); with none, "none" (the plain fit)."""
    return fix_for(_root_.get("sensor") or {}, _root_.get("car") or {})


TORCH_GB = 2  # beside the dataset: torch, Lightning, the network, its batches (sacct: 0.54 GB RSS, data=tiny job)


def slurm_mem_gb(n_roads: int, n_masses: int, n_steps: int) -> int:
    """``${slurm_mem_gb:${data.n_roads},${data.n_masses},${data.n_steps}}`` in conf/launcher/slurm.yaml: the GB
    one job asks SLURM for, the dataset's size (config.memory.dataset_bytes: n_roads x n_masses x n_steps x 4
    channels x 8 bytes, and the road profiles) plus TORCH_GB, rounded up to a whole GB."""
    return math.ceil(dataset_bytes(int(n_roads), int(n_masses), int(n_steps)) / 2**30 + TORCH_GB)


def register() -> None:
    """The schema for Hydra and the resolvers: ``p_prior``, ``fault_fix`` and ``slurm_mem_gb`` (above), and
    ``first_set`` for the run directory (hydra.run.dir is ``resume`` when given, else a new time-stamped one)."""
    ConfigStore.instance().store(name="schema", node=Config)
    ConfigStore.instance().store(name="eval_schema", node=EvalConfig)
    OmegaConf.register_new_resolver("first_set", lambda *xs: next((x for x in xs if x), None), replace=True)
    OmegaConf.register_new_resolver("p_prior", p_prior, replace=True)
    OmegaConf.register_new_resolver("fault_fix", fault_fix, replace=True)
    OmegaConf.register_new_resolver("slurm_mem_gb", slurm_mem_gb, replace=True)
