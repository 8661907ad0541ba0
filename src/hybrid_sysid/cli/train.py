"""``hybrid-sysid``: compose the config, check it, run its task (one run, a transfer chain, a tuned comparison),
draw the run's figures. The job's signals, interruption and failure records: hybrid_sysid.launch.job; exit statuses:
hybrid_sysid.launch.process.

A job returns its record. Under a hyperparameter search (hybrid_sysid.launch.search, conf/hparams_search) the
study reads its ``best_score``: the validation figure its model selection used (val/loss for a label-free
objective, val/rel_dev otherwise; trainer.monitor).
"""

from __future__ import annotations

import gc
import sys
from pathlib import Path
from typing import Any

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig

from hybrid_sysid import config
from hybrid_sysid.config import validate
from hybrid_sysid.config.help import quick_help
from hybrid_sysid.launch.choices import check_choices
from hybrid_sysid.launch.console import tolerant_streams
from hybrid_sysid.launch.first_composition import single_runs_checked_early
from hybrid_sysid.launch.job import (
    Preflight,
    checks_complete,
    draw_run_figures,
    draws_figures,
    run_job,
    task_config,
)
from hybrid_sysid.launch.process import console_main
from hybrid_sysid.runs.layout import SWEEP_CONFIG, check_outside_runs
from hybrid_sysid.runs.resume import check_resume
from hybrid_sysid.runs.rundir import RunDir
from hybrid_sysid.training.tracking import job_naming, log_run_figures


class TrainPreflight(Preflight):
    """Preflight (hybrid_sysid.launch.job) that also checks the config's values and its ``resume=`` directory."""

    saves_task_config = True

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        with checks_complete():  # a refusal here ends the command in one line, before any directory
            outside_other_runs(Path(str(config.hydra.run.dir)), "hydra.run.dir", config.get("resume"))
        super().on_run_start(config, **kwargs)

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        with checks_complete():
            outside_other_runs(Path(str(config.hydra.sweep.dir)), "hydra.sweep.dir")
        super().on_multirun_start(config, **kwargs)

    def check(self, cfg: DictConfig, overrides: list[str]) -> None:
        validate(cfg)
        if cfg.get("init_from"):  # its weights must fit and load, before a directory exists
            from hybrid_sysid.training.build import check_weights  # deferred

            check_weights(cfg, Path(str(cfg.init_from)), "init_from")
        if cfg.get("resume"):
            check_resume(RunDir(str(cfg.resume)), cfg, overrides)


def outside_other_runs(out_dir: Path, key: str, resume=None) -> None:
    """A run or sweep lies inside no other run or sweep directory: a run in a completed run's checkpoints/ once
    trained there, and that run's report then listed two runs (eval refuses the same: cli.evaluate). A sweep's
    job lives in its sweep's directory, so ``resume=`` of that job (its parent holds multirun.yaml), or that job's
    existing directory as a single run's, is allowed."""
    here = out_dir.resolve()
    own_job = (here.parent / SWEEP_CONFIG).is_file()
    # a job of its sweep run again as a single run, in its own directory: its record decides (a completed one is
    # skipped, a changed config refused: launch.job), as for the sweep's command again
    if own_job and (here.is_dir() or (resume and Path(str(resume)).resolve() == here)):
        return
    check_outside_runs(key, out_dir, here.parent)


def run_task(cfg: DictConfig, run_dir: Path, overrides: list[str], multirun: bool, hc=None) -> dict:
    """The job's task (``task``): imported here, so a sweep's parent process, which only composes and launches
    jobs, loads no torch. ``hc``: the job's Hydra config, which names it in an experiment tracker (a sweep's jobs
    are runs of one experiment, <preset>:<sweep>, named by their differing overrides)."""
    if cfg.task == "transfer":
        from hybrid_sysid.experiments.transfer import run_chain as chain  # deferred
    elif cfg.task == "tuned":
        from hybrid_sysid.experiments.tuned import run_tuned as chain  # deferred
    else:
        from hybrid_sysid.training.run import train  # deferred
    freeze_imports()
    if cfg.task in ("transfer", "tuned"):  # a chain of runs in sub-directories, each with its own record
        result = chain(cfg, run_dir, overrides)
        RunDir(run_dir).drop_stale_record()  # an earlier interruption's record: every run it named is done now
        return result

    naming = job_naming(hc) if hc is not None and cfg.get("logger") else None  # names only a tracker needs
    # a single run's config was validated by the preflight; a sweep's job has had no preflight
    return train(cfg, run_dir, overrides, experiment=naming, checked=not multirun)


def freeze_imports() -> None:
    """torch, Lightning and their imports leave hundreds of thousands of long-lived objects that every full garbage
    collection walks again: during a job, and when a sweep's worker process ends, which held the sweep's exit back
    (benchmarks/README.md). Collected once and frozen (``gc.freeze``), they are skipped from then on; what the
    job allocates afterwards is collected as usual, and the collection first frees whatever an earlier job in
    the same worker left, so nothing of it is kept."""
    gc.collect()
    gc.freeze()


@hydra.main(version_base="1.3", config_path=config.CONF_DIR, config_name="config")
def hydra_main(cfg: DictConfig) -> Any:
    hc = HydraConfig.get()
    run_dir, overrides = Path(hc.runtime.output_dir), list(hc.overrides.task)
    multirun = hc.mode == RunMode.MULTIRUN
    sweep_dir = Path(hc.sweep.dir) if multirun else None
    record = run_job(
        lambda: run_task(cfg, run_dir, overrides, multirun, hc),
        run_dir,
        overrides,
        cfg.get("seed", 0),
        multirun=multirun,
        sweep_dir=sweep_dir,
        again=f"continue it with resume={run_dir} (a sweep: run the same command again)",
    )
    draw = draws_figures(cfg.get("run_figures", "auto"), multirun)
    if draw and cfg.task == "train" and record.get("status") == "completed" and record.get("rank", 0) == 0:
        draw_run_figures(run_dir)  # with DDP, rank 0 alone has the record
        log_run_figures(run_dir)  # into the job's MLflow run, now that they exist
    return record


def values_checked(cfg: DictConfig) -> None:
    """A single run's values and group choices, on Hydra's first composition (launch.first_composition): a refusal
    in one composition, not two. The run's preflight checks them again, with its directory and resume=."""
    with checks_complete():
        check_choices(cfg)
        validate(task_config(cfg))


def main() -> None:
    """Console script ``hybrid-sysid`` (exit statuses: hybrid_sysid.launch.process)."""
    tolerant_streams()
    text = quick_help(sys.argv[1:], config.CONF_DIR, "config")  # --help in one composition, Hydra's text
    if text is not None:
        print(text)
        return
    with single_runs_checked_early(values_checked):
        console_main(hydra_main, sys.argv[1:])


if __name__ == "__main__":
    main()
