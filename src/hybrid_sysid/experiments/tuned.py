"""``hybrid-sysid experiment=tuned``: each objective searched with the same budget, then its default and its
best values trained on the seeds the table reports. Does tuning change the comparison of objectives?

One job per objective (the sweep runs them side by side) does, in its own directory:

- ``search/<n>``: ``tuned.n_trials`` trials of a seeded TPE study (optuna) over the space and sampler settings of
  an hparams_search preset (``tuned.search``: conf/hparams_search/<name>.yaml), each trained as the runs below
  are (without learning-curve points), on ``tuned.trial_seed``, and scored by its model-selection figure
  (val/loss for the hybrid objective, which reads no labels; val/rel_dev for the others). Trial 0 is the
  model's default values, so the best trial is never worse on validation than the untuned network.
  ``search/best.yaml`` and ``search/trials.csv`` hold the study.
- ``default/<seed>`` and ``tuned/<seed>``: the default values and the best trial's, trained with the
  experiment's own trainer settings for each of ``tuned.seeds``.

A sub-run's overrides are the job's plus ``tuning=default|tuned`` and its seed (a trial's: ``tuning=trial``, its
number and values), so the sweep summary, which leaves ``*/search/*`` out, has one row per objective, tuning and
K. The study lives in memory: a re-run asks the sampler seeded per trial (hybrid_sysid.experiments.search), which
proposes the same values, finds each completed trial's record and trains only what is missing.
"""

from __future__ import annotations

import logging
from pathlib import Path

import optuna
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import validate
from hybrid_sysid.core.checks import bad
from hybrid_sysid.core.files import write_atomic, write_yaml_atomic
from hybrid_sysid.data.spec import check_seed
from hybrid_sysid.experiments.presets import preset
from hybrid_sysid.experiments.search import check_sampler, check_search, sampler_for
from hybrid_sysid.runs.rundir import RunDir
from hybrid_sysid.training.run import train

log = logging.getLogger("hybrid_sysid")
SEARCH, DEFAULT, TUNED = "search", "default", "tuned"  # sub-directories of a job, and the values of ``tuning``


def defaults_in(cfg: DictConfig, space: dict) -> dict:
    """The config's own values of the searched keys (trial 0); ConfigError for a key it lacks or a value outside
    the space."""
    out = {}
    for key, dist in space.items():
        value = OmegaConf.select(cfg, key, default=None)
        inside = (
            value in dist.choices
            if hasattr(dist, "choices")
            else isinstance(value, (int, float)) and dist.low <= value <= dist.high
        )
        if value is None or not inside:
            bad(
                key,
                value,
                f"a value inside the search's space with experiment=tuned, {dist} (its first trial is the "
                "config's own values)",
            )
        out[key] = value
    return out


def with_values(cfg: DictConfig, values: dict, seed: int, extra=None) -> DictConfig:
    """A copy of the config for one sub-run (task=train): ``extra`` merged (a preset's trainer settings), the
    values set and the seed."""
    out = OmegaConf.merge(cfg, {"task": "train", "tuned": None}, extra or {})
    for key, value in values.items():
        OmegaConf.update(out, key, value, merge=False)
    out.seed = seed
    return out


def as_overrides(values: dict) -> list[str]:
    return [f"{key}={value}" for key, value in values.items()]


def run_sub(sub: DictConfig, run_dir: Path, overrides: list[str]) -> dict:
    log.info("tuned: %s", " ".join(overrides))
    RunDir(run_dir).write_config(sub, overrides)  # never over a completed run's
    return train(sub, run_dir, overrides)


def run_tuned(cfg: DictConfig, job_dir: str | Path, job_overrides=()) -> dict:
    """The search, then the default and best values on each seed (module docstring). Returns a short record."""
    job_dir, t = Path(job_dir), cfg.tuned
    sweeper = preset("hparams_search", t.search, "tuned.search").hydra.sweeper
    space = check_search(cfg, sweeper.params, t.n_trials, "tuned.search: hydra.sweeper", "tuned.n_trials")
    trial_settings = {"trainer": {"curve_every_n_steps": None}}  # a trial is scored on validation alone
    defaults = defaults_in(cfg, space)
    if not t.seeds:
        bad("tuned.seeds", [], "at least one seed, e.g. [0, 1, 2]")
    validate(with_values(cfg, defaults, t.trial_seed, trial_settings))
    for i, seed in enumerate(t.seeds):  # every seed before the search, not when its job comes
        check_seed(f"tuned.seeds[{i}]", seed)
    validate(with_values(cfg, defaults, t.seeds[0]))
    base = [o for o in job_overrides if not o.startswith("seed=")]

    sampler = check_sampler(sweeper.sampler, "tuned.search: hydra.sweeper.sampler")
    study = optuna.create_study(direction=sweeper.direction, study_name=sweeper.study_name)
    study.enqueue_trial(defaults)
    monitors = set()
    for n in range(t.n_trials):
        study.sampler = sampler_for(sampler, n)
        trial = study.ask(space)
        overrides = base + ["tuning=trial", f"trial={n}"] + as_overrides(trial.params) + [f"seed={t.trial_seed}"]
        sub = with_values(cfg, trial.params, t.trial_seed, trial_settings)
        run_dir = job_dir / SEARCH / str(n)
        try:
            record = run_sub(sub, run_dir, overrides)
            score = record.get("best_score")
            monitors.add(record.get("monitor"))
        except Exception as exc:  # noqa: BLE001 - a trial that fails is a failed trial; the study goes on
            error = f"{type(exc).__name__}: {exc}"
            log.error("tuned: trial %d failed: %s", n, error)
            RunDir(run_dir).record_end(overrides, t.trial_seed, "failed", error)
            score = None
        if score is None:
            study.tell(trial, state=optuna.trial.TrialState.FAIL)
        else:
            study.tell(trial, float(score))
    done = [tr for tr in study.trials if tr.state == optuna.trial.TrialState.COMPLETE]
    if not done:
        raise RuntimeError(f"every one of the {t.n_trials} trials failed (records in {job_dir / SEARCH})")
    best = study.best_trial
    write_yaml_atomic(
        job_dir / SEARCH / "best.yaml",
        {
            "overrides": base,
            "monitor": " / ".join(sorted(map(str, monitors))),
            "direction": sweeper.direction,
            "n_trials": t.n_trials,
            "completed": len(done),
            "default": {"trial": 0, "value": study.trials[0].value, "params": defaults},
            "best": {"trial": best.number, "value": best.value, "params": best.params},
        },
    )
    trials = study.trials_dataframe(attrs=("number", "value", "params", "state"))
    write_atomic(job_dir / SEARCH / "trials.csv", lambda p: trials.to_csv(p, index=False))

    runs = []
    for tuning, values in ((DEFAULT, defaults), (TUNED, best.params)):
        for seed in t.seeds:
            run_dir = job_dir / tuning / str(seed)
            run_sub(with_values(cfg, values, seed), run_dir, base + [f"tuning={tuning}", f"seed={seed}"])
            runs.append(str(run_dir.relative_to(job_dir)))
    return {"status": "completed", "best": best.params, "runs": runs}
