"""How a job is named in the trackers: a sweep is one MLflow experiment, ``<preset>:<sweep directory's name>``
(``sweep:<name>`` without an experiment preset); its jobs are runs named by the overrides that differ between them
(``objective=hybrid seed=1``: the sweep's swept keys, :func:`swept_keys`). A single run goes to the experiment
``runs``, named by its overrides (the logger's left out) or else its directory's name."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.core.overrides import parse_override
from hybrid_sysid.runs.sweepdir import SweepDir

log = logging.getLogger("hybrid_sysid")

SINGLE_RUNS = "runs"  # the MLflow experiment of runs outside a sweep
NO_PRESET = "sweep"  # the first part of the experiment name of a sweep without experiment=<preset>
MAX_NAME = 200  # characters of a run name (MLflow and file names both take it)


@dataclass(frozen=True)
class Naming:
    """How a job is named in the trackers: its experiment, its run name, the overrides that differ between the
    sweep's jobs (``varied``), the experiment preset, the sweep directory and Hydra's config-group choices."""

    experiment: str = SINGLE_RUNS
    run: str | None = None
    varied: tuple[str, ...] = ()
    preset: str | None = None
    sweep_dir: Path | None = None
    choices: dict = field(default_factory=dict)


def experiment_name(preset: str | None, sweep_dir: Path) -> str:
    """A sweep's experiment: ``<preset>:<sweep directory's name>``, e.g. ``robustness:2026-11-24_01-02-03_123456``
    (not "/": MLflow's UI takes a name with a slash for a folder path and shows only its last part)."""
    return f"{preset or NO_PRESET}:{Path(sweep_dir).name}"


def job_naming(hc: DictConfig) -> Naming:
    """The naming of the job whose Hydra config (``HydraConfig.get()``) is ``hc``; a sweep's job, when its
    naming cannot be told, is named after its number (never an error: the job must run)."""
    try:
        return _job_naming(hc)
    except Exception as exc:  # noqa: BLE001
        log.warning("tracker names not found (%s: %s): the run is named after its number", type(exc).__name__, exc)
        num = OmegaConf.select(hc, "job.num", default=None)
        return Naming(SINGLE_RUNS, None if num is None else f"job {num}")


def _job_naming(hc: DictConfig) -> Naming:
    choices = {k: v for k, v in OmegaConf.to_container(hc.runtime.choices).items() if v is not None}
    preset, overrides = choices.get("experiment"), list(hc.overrides.task)
    if hc.mode != RunMode.MULTIRUN:
        shown = [o for o in overrides if override_key(o).split(".")[0] != "logger"]
        return Naming(SINGLE_RUNS, clip(" ".join(shown)) or None, (), preset, None, choices)
    sweep_dir = Path(str(hc.sweep.dir))
    swept = swept_keys(sweep_dir, hc.sweeper.get("params"))
    varied = tuple(o for o in overrides if override_key(o) in swept)
    run = clip(" ".join(varied)) or f"job {hc.job.num}"
    return Naming(experiment_name(preset, sweep_dir), run, varied, preset, sweep_dir, choices)


def swept_keys(sweep_dir: Path, params=None) -> set[str]:
    """The keys a sweep varies: its command-line sweeps (``objective=labelled,hybrid``, ``seed=range(3)``) and its
    sweeper's parameters (an experiment preset's ``hydra.sweeper.params``, a search's space), read from the
    sweep's multirun.yaml, which Hydra's sweepers write before the first job; ``params``: the job's own sweeper
    parameters, for a sweep directory without that file."""
    texts = []
    saved = SweepDir(sweep_dir).saved_config()
    try:
        texts += [str(o) for o in saved.hydra.overrides.task]
        params = saved.hydra.sweeper.get("params", params)
    except Exception:  # noqa: BLE001 - no readable file (None) or one without them: the sweeper's parameters alone
        pass
    if params:
        given = OmegaConf.to_container(params) if OmegaConf.is_config(params) else dict(params)
        texts += [f"{k}={v}" for k, v in given.items() if v is not None]
    parser, keys = OverridesParser.create(), set()
    for text in texts:
        try:
            override = parser.parse_override(text)
        except Exception:  # noqa: BLE001 - Hydra refused it already, or will: it names no swept key here
            continue
        if override.is_sweep_override():
            keys.add(override_key(text))
    return keys


def override_key(override: str) -> str:
    """The key an override sets: ``+model.optim.lr=0.1`` -> ``model.optim.lr``, ``db@pkg=x`` -> ``db@pkg``."""
    return parse_override(override).key


def clip(name: str) -> str:
    return name if len(name) <= MAX_NAME else name[: MAX_NAME - 1] + "…"


def objective_name(cfg: DictConfig, choices: dict) -> str:
    """The objective's config-group name (a baseline's name for a baseline run); outside Hydra, from its class:
    HybridObjective -> hybrid."""
    if cfg.get("baseline") is not None:
        return str(choices.get("baseline") or str(cfg.baseline._target_).rsplit(".", 1)[-1])
    if "objective" in choices:
        return str(choices["objective"])
    name = str(cfg.objective._target_).rsplit(".", 1)[-1]
    return name.removesuffix("Objective").lower() or name
