"""``hybrid-sysid experiment=transfer``: identification on a car the network was not trained on.

One job per seed (the sweep runs them side by side) trains, in order, in its own directory:

- ``source/``: the labelled objective on the config's car (the paper's), evaluated there;
- for each target scenario (``transfer.scenarios``: another car preset, other data values):
  ``<scenario>/source``: that network evaluated on the target's test roads, no training
  (hybrid_sysid.training.run.evaluate_checkpoint, what hybrid-sysid-eval runs);
  ``<scenario>/adapted``: that network, then ``transfer.adapt_steps`` steps of the hybrid objective on the
  target's unlabelled training recordings (``init_from``; model selection by the label-free val/loss);
  ``<scenario>/scratch``: the hybrid objective from random weights on the target;
  ``<scenario>/oracle``: the labelled objective with the target's labels.

Each sub-run writes an ordinary run record whose overrides are ``scenario=...`` and ``row=...``, so the sweep
summary's table has one row per (scenario, row, K). A Hydra sweep cannot chain jobs that depend on each other;
this module does, inside a job.
"""

from __future__ import annotations

import logging
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import validate
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.experiments.presets import preset
from hybrid_sysid.runs.rundir import RunDir
from hybrid_sysid.training.run import evaluate_checkpoint, train

log = logging.getLogger("hybrid_sysid")
# table rows, numbered so they sort in the order the scenario reads
SOURCE, ADAPTED, SCRATCH, ORACLE = (
    "1 labelled, paper's car",
    "2 + hybrid adaptation",
    "3 hybrid from scratch",
    "4 labelled oracle",
)
SCENARIO_KEYS = ("car", "data")


def variant(cfg: DictConfig, objective: str, **changes) -> DictConfig:
    """A copy of the config for one run (task=train) with another objective and the given dotted keys changed."""
    out = OmegaConf.merge(cfg, {"task": "train", "transfer": None})
    out.objective = preset("objective", objective, "transfer")
    for key, value in changes.items():
        OmegaConf.update(out, key.replace("__", "."), value, merge=False)
    return out


def target(cfg: DictConfig, name: str, scenario) -> DictConfig:
    """The config on a scenario's target: ``car`` names a car preset (conf/car), ``data`` holds data values."""
    unknown = sorted(set(scenario) - set(SCENARIO_KEYS))
    if unknown:
        raise ConfigError(
            f"transfer.scenarios.{name}.{unknown[0]} is not allowed: a scenario sets {' and '.join(SCENARIO_KEYS)}"
        )
    out = OmegaConf.merge(cfg, {"data": scenario.get("data") or {}})
    if scenario.get("car"):
        out.car = preset("car", scenario.car, f"transfer.scenarios.{name}")
    return out


def plan(cfg: DictConfig, job_dir: Path) -> list[tuple[str, DictConfig, Path, list[str], Path | None]]:
    """(kind, config, directory, overrides, source) of every sub-run in order; every config validated here,
    before any work."""
    t = cfg.transfer
    source_dir = job_dir / "source"
    runs = [("train", variant(cfg, "labelled"), source_dir, ["scenario=paper", f"row={SOURCE}"], None)]
    for name, scenario in t.scenarios.items():
        goal = target(cfg, name, scenario)
        tag = [f"scenario={name}"]
        runs += [
            ("eval", variant(goal, "labelled"), job_dir / name / "source", tag + [f"row={SOURCE}"], source_dir),
            (
                "train",
                variant(
                    goal,
                    "hybrid",
                    init_from=str(source_dir),
                    trainer__max_steps=t.adapt_steps,
                    model__optim__lr=t.adapt_lr,
                ),
                job_dir / name / "adapted",
                tag + [f"row={ADAPTED}"],
                None,
            ),
            ("train", variant(goal, "hybrid"), job_dir / name / "scratch", tag + [f"row={SCRATCH}"], None),
            ("train", variant(goal, "labelled"), job_dir / name / "oracle", tag + [f"row={ORACLE}"], None),
        ]
    for _, sub, _, _, _ in runs:
        validate(sub)
    return runs


def run_chain(cfg: DictConfig, job_dir: str | Path, job_overrides=()) -> dict:
    """Every sub-run of one seed, in order (module docstring). Each sub-run directory gets its config in
    .hydra/config.yaml, as a run of hybrid-sysid has (so hybrid-sysid-eval and load_estimator read it), and a
    record whose overrides are the job's plus scenario and row. Every sub-run is validated by ``plan``, before
    the first one starts. Returns a short record of what ran."""
    job_dir = Path(job_dir)
    runs = plan(cfg, job_dir)
    for kind, sub, run_dir, overrides, source in runs:
        overrides = [o for o in job_overrides if not o.startswith("seed=")] + overrides + [f"seed={cfg.seed}"]
        log.info("transfer: %s %s", kind, " ".join(overrides))
        RunDir(run_dir).write_config(sub, overrides)
        if kind == "eval":
            evaluate_checkpoint(sub, source, run_dir, overrides, checked=True)
        else:
            train(sub, run_dir, overrides, checked=True)
    return {"status": "completed", "runs": [str(r[2].relative_to(job_dir)) for r in runs]}
