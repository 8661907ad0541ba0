"""``hybrid-sysid hparams_search=...``: a hyperparameter search. The study sweeper (hydra_plugins/
hybrid_sysid_search, config conf/hydra/sweeper/study.yaml) hands its work here: an optuna study asked and told
trial by trial, each trial a job of the launcher, numbered as its trial, in ``<sweep dir>/<trial number>``.

The study is stored (``hydra.sweeper.storage``; by default ``study.db`` in the sweep directory), so the same
command re-run into the same sweep directory (``hydra.sweep.dir=...``) resumes it:

- completed and failed trials stay as they are (``n_trials`` counts them);
- the batch an interruption broke off (``n_jobs`` trials at a time) is asked full first, as it would have been,
  then its trials that the interruption left running are launched again with their own numbers and values (each
  job continues from its last checkpoint, as any interrupted run does);
- then the search goes on.

With the sampler seeded per trial (hybrid_sysid.experiments.search) and each job's numbers fixed by its config
and seed, the resumed search holds the trials and values of an uninterrupted one (keep ``n_jobs``: it decides
which trials are asked together).

A job's value is its record's ``best_score`` (the figure its model selection used); a failed job, or one without
that figure, is a failed trial, listed by the sweep summary, which then exits non-zero. A signal ends the search
once the running jobs have recorded it; their trials stay running in the study, for the re-run.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

import optuna
from omegaconf import DictConfig

from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.core.files import write_atomic, write_yaml_atomic
from hybrid_sysid.experiments.search import StudySettings, sampler_for, study_settings
from hybrid_sysid.launch.job import task_config
from hybrid_sysid.launch.process import fail, sweep_stopped
from hybrid_sysid.launch.study import open_owned
from hybrid_sysid.runs.sweepdir import SweepDir

log = logging.getLogger("hybrid_sysid")
STUDY_FILE = "study.db"  # the default storage, in the sweep directory
RESULTS = "optimization_results.yaml"


def run_study(config: DictConfig, launcher, settings: dict, arguments: list[str]) -> list:
    """The search (module docstring): returns the jobs' returns, as Hydra's sweepers do."""
    sweep_dir = Path(str(config.hydra.sweep.dir))
    try:
        s = study_settings(task_config(config), settings, arguments)
    except ConfigError as exc:
        fail(str(exc))
    sweep_dir.mkdir(parents=True, exist_ok=True)
    optuna.logging.set_verbosity(optuna.logging.WARNING)  # the sweep prints its own lines
    study = open_study(s, sweep_dir)
    SweepDir(sweep_dir).write_config(config)
    done = sum(t.state.is_finished() for t in study.get_trials(deepcopy=False))
    if done:
        log.info("search: study %s resumed with %d of %d trials ended", s.name, done, s.n_trials)
    returns = []
    while not sweep_stopped(sweep_dir):
        batch = _next_batch(study, s)
        if not batch:
            break
        for group in _contiguous(batch):
            if sweep_stopped(sweep_dir):
                break
            overrides = [s.fixed + [f"{key}={value}" for key, value in params.items()] for _, params in group]
            ran = launcher.launch(overrides, initial_job_idx=group[0][0])
            for (number, _), ret in zip(group, ran):
                _tell(study, number, ret)
            returns.extend(ran)
    _write_results(study, sweep_dir, s)
    return returns


def open_study(s: StudySettings, sweep_dir: Path):
    """The search's study, made or resumed (hybrid_sysid.launch.study: several searches starting at once on one
    storage; one search per study)."""
    return open_owned(s, s.storage or f"sqlite:///{sweep_dir / STUDY_FILE}", sweep_dir if s.storage else None, _own)


def _own(study, sweep_dir: Path | None, s: StudySettings) -> None:
    """A stored study belongs to one search: what makes its trials and, in a storage outside the sweep directory
    (``sweep_dir`` given), that directory. Another search's study is refused in one line (its trials would not be
    this search's)."""
    mine = {
        "sweep_dir": None if sweep_dir is None else str(sweep_dir.resolve()),
        "fixed": sorted(s.fixed),
        "space": [f"{key}: {dist!r}" for key, dist in sorted(s.space.items())],
    }
    attrs = study.user_attrs
    if not attrs.get("search"):
        study.set_user_attr("search", mine)
        return
    was = attrs["search"]
    if was.get("sweep_dir") != mine["sweep_dir"]:
        fail(
            f"hydra.sweeper.storage holds study {s.name!r} of the search in {was.get('sweep_dir')}: resume it with "
            f"hydra.sweep.dir={was.get('sweep_dir')}, or give another hydra.sweeper.study_name"
        )
    if was != mine:
        fail(
            f"hydra.sweeper.storage holds study {s.name!r} of other overrides or another space "
            f"({' '.join(was.get('fixed', []))}; {', '.join(was.get('space', []))}); re-run it with the same ones, "
            "or give another hydra.sweeper.study_name"
        )


def _next_batch(study, s: StudySettings) -> list[tuple[int, dict]]:
    """The trials to launch next, as (number, values): the batch a running trial belongs to (asked full, its
    running trials included), else the next n_jobs trials; [] once n_trials have ended."""
    trials = study.get_trials(deepcopy=False)
    running = [t for t in trials if t.state == optuna.trial.TrialState.RUNNING]
    end = (running[-1].number // s.n_jobs + 1) * s.n_jobs if running else len(trials) + s.n_jobs
    batch = [(t.number, t.params) for t in running]
    for number in range(len(trials), min(end, s.n_trials)):
        study.sampler = sampler_for(s.sampler, number)
        trial = study.ask(s.space)
        if trial.number != number:
            fail(f"study {s.name!r} in {s.storage or 'the sweep directory'} is being written by another process")
        batch.append((number, trial.params))
    return batch


def _contiguous(batch: list) -> list[list]:
    """The batch in runs of consecutive numbers: the launcher numbers a launch's jobs from its first."""
    groups: list[list] = []
    for item in sorted(batch, key=lambda x: x[0]):
        if groups and groups[-1][-1][0] + 1 == item[0]:
            groups[-1].append(item)
        else:
            groups.append([item])
    return groups


def _tell(study, number: int, ret) -> None:
    """The job's value into its trial: its record's best_score; a failed trial without one; a trial whose job
    was interrupted stays running, for the re-run."""
    try:
        record: Any = ret.return_value  # raises the job's exception, had one escaped it
    except Exception as exc:  # noqa: BLE001 - a job's failure is a failed trial
        record = {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}
    record = record if isinstance(record, dict) else {}
    status, value = record.get("status"), record.get("best_score")
    if status == "interrupted":
        return
    if status == "completed" and isinstance(value, (int, float)) and math.isfinite(value):
        study.tell(number, float(value))
        return
    why = record.get("error") or f"its record has no finite best_score ({value!r})"
    log.warning("search: trial %d failed: %s", number, why)
    study.tell(number, state=optuna.trial.TrialState.FAIL)


def _write_results(study, sweep_dir: Path, s: StudySettings) -> None:
    """optimization_results.yaml (the best values and figure, the trial counts) and trials.csv."""
    trials = study.get_trials(deepcopy=False)
    complete = [t for t in trials if t.state == optuna.trial.TrialState.COMPLETE]
    best = study.best_trial if complete else None
    write_yaml_atomic(
        sweep_dir / RESULTS,
        {
            "study_name": s.name,
            "direction": s.direction,
            "n_trials": s.n_trials,
            "completed": len(complete),
            "failed": sum(t.state == optuna.trial.TrialState.FAIL for t in trials),
            "running": sum(t.state == optuna.trial.TrialState.RUNNING for t in trials),
            "best_trial": None if best is None else best.number,
            "best_value": None if best is None else best.value,
            "best_params": None if best is None else best.params,
        },
    )
    frame = study.trials_dataframe(attrs=("number", "value", "params", "state"))
    write_atomic(sweep_dir / "trials.csv", lambda p: frame.to_csv(p, index=False))
    if best is not None:
        log.info("search: best trial %d, value %.6g, %s", best.number, best.value, best.params)
