"""``hybrid-sysid experiment=transfer`` (and experiment=field): identification on a car the network was not
trained on.

One job per seed (the sweep runs them side by side) trains, in order, in its own directory:

- ``source/``: the labelled objective on the config's car (the paper's), evaluated there;
- for each target scenario (``transfer.scenarios``: another car preset, other data values):
  ``<scenario>/source``: that network evaluated on the target's test roads, no training
  (hybrid_sysid.training.run.evaluate_checkpoint, what hybrid-sysid-eval runs);
  ``<scenario>/adapted[_<objective>]``: for each label-free objective of ``transfer.adapt_objectives``, that
  network, then ``transfer.adapt_steps`` steps of the objective on the target's unlabelled training recordings
  (``init_from``; model selection by the label-free val/loss);
  ``<scenario>/scratch[_<objective>]``: the label-free ``transfer.scratch_objective`` from random weights on the
  target;
  ``<scenario>/anchored_<objective>``: for each label-free objective of ``transfer.anchored_objectives``,
  model=anchored trained with it from scratch on the target (docs/anchored.md, "The anchored estimator");
  ``<scenario>/oracle``: the labelled objective with the target's labels;
  ``<scenario>/baseline_<name>``: when ``transfer.baseline`` names a baseline preset (conf/baseline), that
  baseline on the target, without a network (an ordinary ``baseline=`` run).

Each sub-run writes an ordinary run record whose overrides are ``scenario=...`` and ``row=...``, so the sweep
summary's table has one row per (scenario, row, K); a re-run skips the sub-runs whose records are complete. A
Hydra sweep cannot chain jobs that depend on each other; this module does, inside a job.
"""

from __future__ import annotations

import logging
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import CONF_DIR, validate
from hybrid_sysid.config.resolvers import p_prior
from hybrid_sysid.config.targets import build
from hybrid_sysid.core.checks import ConfigError, bad
from hybrid_sysid.experiments.presets import preset
from hybrid_sysid.runs.rundir import RunDir
from hybrid_sysid.training.run import evaluate_checkpoint, train

log = logging.getLogger("hybrid_sysid")
# table rows, numbered so they sort (as text) in the order the scenario reads: 1 < 2 + ... < 3 ... < 4 < 5
SOURCE = "1 labelled, paper's car"
ORACLE = "4 labelled oracle"
SCENARIO_KEYS = ("car", "data")
# the objective whose sub-runs have the bare directory names adapted/ and scratch/, those of a chain with the hybrid
# objective alone: a re-run of such a sweep skips them instead of training them again under new names (which its
# summary would then count twice); the other objectives' runs are adapted_<objective>/, scratch_<objective>/
PLAIN = "hybrid"


def adapted_row(objective: str) -> str:
    return f"2 + {objective} adaptation"


def scratch_row(objective: str) -> str:
    return f"3 {objective} from scratch"


def anchored_row(objective: str) -> str:
    return f"3 {objective} from scratch, anchored"


def baseline_row(name: str) -> str:
    return f"5 {name} (no network)"


def _subdir(kind: str, objective: str) -> str:
    return kind if objective == PLAIN else f"{kind}_{objective}"


def composed(group: str, choice: str, key: str) -> DictConfig:
    """conf/<group>/<choice>.yaml as Hydra composes a group choice: its defaults list (other presets of the same
    group, and ``_self_``, which is last when not listed) merged in order. ConfigError naming ``key`` when there
    is no such preset."""
    node = preset(group, choice, key)
    defaults = node.pop("defaults", None)
    if defaults is None:
        return node
    parts = []
    for entry in defaults:
        if entry == "_self_":
            parts.append(node)
        elif isinstance(entry, str):
            parts.append(composed(group, entry, key))
        else:  # the presets this module reads name only presets of their own group
            bad(key, choice, f"a {group} preset whose defaults list names {group} presets ({entry} is not one)")
    if "_self_" not in defaults:
        parts.append(node)
    return OmegaConf.merge(*parts)


def variant(cfg: DictConfig, objective: str, **changes) -> DictConfig:
    """A copy of the config for one run (task=train) with another objective and the given dotted keys changed."""
    out = OmegaConf.merge(cfg, {"task": "train", "transfer": None})
    out.objective = composed("objective", objective, "transfer")
    for key, value in changes.items():
        OmegaConf.update(out, key.replace("__", "."), value, merge=False)
    return out


def target(cfg: DictConfig, name: str, scenario) -> DictConfig:
    """The config on a scenario's target: ``car`` names a car preset (conf/car), ``data`` holds data values."""
    unknown = sorted(set(scenario) - set(SCENARIO_KEYS))
    if unknown:
        bad(
            f"transfer.scenarios.{name}.{unknown[0]}",
            scenario[unknown[0]],
            f"a scenario sets {' and '.join(SCENARIO_KEYS)}",
        )
    out = OmegaConf.merge(cfg, {"data": scenario.get("data") or {}})
    if scenario.get("car"):
        out.car = preset("car", scenario.car, f"transfer.scenarios.{name}")
    return out


def _presets(group: str) -> list[str]:
    return sorted(p.stem for p in (Path(CONF_DIR) / group).glob("*.yaml"))


def _reads_labels(cfg: DictConfig, objective: str) -> bool:
    """Whether an objective preset reads labels: its built objective's ``uses_labels`` (model.base.Objective)."""
    return bool(build(variant(cfg, objective).objective, "objective").uses_labels)


def _label_free_objectives(cfg: DictConfig, key: str, value, names: list[str]) -> None:
    """Each of ``names`` is an objective preset that reads no labels; else one line naming ``key``, the value
    and the presets allowed."""
    offending = [n for n in names if n not in _presets("objective") or _reads_labels(cfg, n)]
    if offending:
        allowed = [n for n in _presets("objective") if not _reads_labels(cfg, n)]
        why = "no such objective preset" if offending[0] not in _presets("objective") else "it reads labels"
        bad(key, value, f"{offending[0]}: {why}; a label-free objective preset (conf/objective): {', '.join(allowed)}")


def check_settings(cfg: DictConfig) -> None:
    """transfer.adapt_objectives, scratch_objective, anchored_objectives and baseline, each a one-line ConfigError
    naming the key."""
    t = cfg.transfer
    adapt = [str(o) for o in t.adapt_objectives]
    twice = sorted({o for o in adapt if adapt.count(o) > 1})
    if twice:
        bad("transfer.adapt_objectives", adapt, f"{twice[0]} twice; each objective once (one row each)")
    _label_free_objectives(cfg, "transfer.adapt_objectives", adapt, adapt)
    # the labelled objective from scratch on the target is the oracle row already
    _label_free_objectives(cfg, "transfer.scratch_objective", str(t.scratch_objective), [str(t.scratch_objective)])
    anchored = [str(o) for o in t.get("anchored_objectives") or []]
    _label_free_objectives(cfg, "transfer.anchored_objectives", anchored, anchored)
    if t.baseline is not None and str(t.baseline) not in _presets("baseline"):
        bad(
            "transfer.baseline",
            t.baseline,
            f"null or a baseline preset (conf/baseline): {', '.join(_presets('baseline'))}",
        )


def check_bounds(source: DictConfig, goal: DictConfig, name: str) -> None:
    """An adapted network keeps the source network's output bounds (init_from loads them with the weights), so
    adaptation can only reach the target's p inside them: the target's prior (``${p_prior:...}``) must be, else
    a ConfigError naming the scenario. A network without a bounded head passes (model.base.Network)."""
    bounds = build(source.model.net, "model.net").output_bounds()
    if bounds is None:
        return
    low, high = (b.tolist() for b in bounds)
    want = p_prior("min", _root_=goal), p_prior("max", _root_=goal)
    for i in range(2):
        # relative slack: the float32 buffers round the bounds
        if want[0][i] < low[i] * (1 - 1e-6) or want[1][i] > high[i] * (1 + 1e-6):
            raise ConfigError(
                f"transfer.scenarios.{name}",
                allowed=f"with adaptation the target's p{i + 1} range {want[0][i]:.4g} to {want[1][i]:.4g} leaves the "
                f"source network's output bounds {low[i]:.4g} to {high[i]:.4g}, which the adapted networks keep; "
                "widen the source's prior (data.m3_min, data.m3_max, data.seat_spread) or set "
                "transfer.adapt_objectives=[]",
            )


def plan(cfg: DictConfig, job_dir: Path) -> list[tuple[str, DictConfig, Path, list[str], Path | None]]:
    """(kind, config, directory, overrides, source) of every sub-run in order; every setting and every config
    validated here, before any work."""
    t = cfg.transfer
    check_settings(cfg)
    source_dir = job_dir / "source"
    source = variant(cfg, "labelled")
    runs = [("train", source, source_dir, ["scenario=paper", f"row={SOURCE}"], None)]
    for name, scenario in t.scenarios.items():
        goal = target(cfg, name, scenario)
        if t.adapt_objectives:
            check_bounds(source, goal, name)
        tag = [f"scenario={name}"]
        runs.append(("eval", variant(goal, "labelled"), job_dir / name / "source", tag + [f"row={SOURCE}"], source_dir))
        for objective in t.adapt_objectives:
            adapted = variant(
                goal,
                objective,
                init_from=str(source_dir),
                trainer__max_steps=t.adapt_steps,
                model__optim__lr=t.adapt_lr,
            )
            where = job_dir / name / _subdir("adapted", objective)
            runs.append(("train", adapted, where, tag + [f"row={adapted_row(objective)}"], None))
        scratch = t.scratch_objective
        where = job_dir / name / _subdir("scratch", scratch)
        runs.append(("train", variant(goal, scratch), where, tag + [f"row={scratch_row(scratch)}"], None))
        for objective in t.get("anchored_objectives") or []:
            model = composed("model", "anchored", "transfer.anchored_objectives")
            anchored = variant(goal, objective, model__net=model.net, model__batch_size=model.batch_size)
            OmegaConf.update(anchored, "model.optim", model.optim, merge=True)  # a structured node: merged, not set
            where = job_dir / name / f"anchored_{objective}"
            runs.append(("train", anchored, where, tag + [f"row={anchored_row(objective)}"], None))
        runs.append(("train", variant(goal, "labelled"), job_dir / name / "oracle", tag + [f"row={ORACLE}"], None))
        if t.baseline is not None:
            # an ordinary baseline run (cfg.baseline set): training.run.train evaluates it without a network
            base = variant(goal, "labelled", baseline=composed("baseline", t.baseline, "transfer.baseline"))
            where = job_dir / name / f"baseline_{t.baseline}"
            runs.append(("train", base, where, tag + [f"row={baseline_row(t.baseline)}"], None))
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
        RunDir(run_dir).write_config(sub, overrides)  # never over a completed run's
        if kind == "eval":
            evaluate_checkpoint(sub, source, run_dir, overrides, checked=True)
        else:
            train(sub, run_dir, overrides, checked=True)
    return {"status": "completed", "runs": [str(r[2].relative_to(job_dir)) for r in runs]}
