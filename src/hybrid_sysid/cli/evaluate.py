"""``hybrid-sysid-eval run=<run dir> [overrides]``: a trained run evaluated on other data, without training.

The run's saved config (.hydra/config.yaml) is the base; each override of data, car, road, noise or evaluation
replaces that key (a group choice such as ``car=soft_seat`` replaces the whole group), so one trained network is
evaluated on another car, road class, noise level or measurement. Model, objective and training are the run's:
overriding them is a one-line error (exit 2). Works under ``-m``: every job writes its own record, naming the
source run, and the sweep summary reads them. The job directory's .hydra/config.yaml is replaced by the config
that was evaluated, so the directory describes itself. Signals, interruption and failure records: as
hybrid-sysid (hybrid_sysid.launch.job, hybrid_sysid.launch.process); the preflight checks the evaluated config and
refuses a directory that holds a completed run of other overrides before Hydra writes into it.
"""

from __future__ import annotations

import errno
import logging
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from hybrid_sysid import config
from hybrid_sysid.config import Config, flatten, validate
from hybrid_sysid.config.versions import upgraded
from hybrid_sysid.core.checks import ConfigError, Shown, bad
from hybrid_sysid.core.options import EVAL_OVERRIDABLE
from hybrid_sysid.core.overrides import parse_override
from hybrid_sysid.launch.first_composition import single_runs_checked_early
from hybrid_sysid.launch.job import (
    Preflight,
    checks_complete,
    draw_run_figures,
    draws_figures,
    run_job,
    task_config,
)
from hybrid_sysid.launch.process import console_main, fail
from hybrid_sysid.runs import locks
from hybrid_sysid.runs.layout import check_outside_runs
from hybrid_sysid.runs.rundir import RunDir

log = logging.getLogger("hybrid_sysid")
# keys an evaluation may change; anything else the run trained with stays
OVERRIDABLE = EVAL_OVERRIDABLE
LAUNCHER_KEYS = ("trainer.threads", "trainer.progress_bar")  # what a launcher group sets for its workers
FULL_DISK = (errno.ENOSPC, errno.EDQUOT)
# the directory a single evaluation made for itself (EvalPreflight): removed again if the command ends without
# its record, since an evaluation that cannot be written leaves nothing to resume from (see main)
MADE: list[Path] = []


def override_keys(overrides) -> list[str]:
    """The dotted key of each command-line override ("car.c3=700" -> "car.c3", "+data.x=1" -> "data.x")."""
    return [parse_override(o).key for o in overrides]


def evaluation_config(run_dir: Path, composed: DictConfig, overrides) -> DictConfig:
    """The run's saved config with the overridden keys taken from ``composed`` (the eval app's config, in
    which Hydra has composed the overrides). A key outside OVERRIDABLE raises ConfigError."""
    base = RunDir(run_dir).saved_config("run")
    try:
        cfg = OmegaConf.merge(OmegaConf.structured(Config), {k: v for k, v in base.items() if k != "hydra"})
    except OmegaConfBaseException as exc:  # a key or a type this version does not have
        where = getattr(exc, "full_key", None) or "a key"
        bad(
            "run",
            Shown(str(run_dir)),
            f"a run whose saved config this version reads ({where}: {type(exc).__name__}; a run saved by another "
            "version of hybrid-sysid, whose keys have changed since)",
        )
    # a file cut at a line's end parses: the sections after the cut have no value, and the keys after it in a
    # section would silently take the schema's defaults (another car, say) rather than the run's values
    absent = sorted(OmegaConf.missing_keys(cfg))
    absent += [k for k in lacking(base, cfg) if k.split(".")[0] not in absent]
    if absent:
        shown = ", ".join(absent[:4]) + (f", ... ({len(absent)} keys)" if len(absent) > 4 else "")
        bad("run", Shown(str(run_dir)), f"a run whose saved config is complete (no value for {shown}; cut short?)")
    for key in override_keys(overrides):
        top = key.split(".")[0]
        if key == "run" or top == "hydra":
            continue
        if key == "launcher":
            for k in LAUNCHER_KEYS:
                OmegaConf.update(cfg, k, OmegaConf.select(composed, k), merge=False)
            continue
        if top not in OVERRIDABLE and key not in LAUNCHER_KEYS:
            raise ConfigError(
                key,
                allowed=f"a key of {', '.join(OVERRIDABLE)} in an evaluation (the network and how it was trained "
                "are the run's)",
            )
        OmegaConf.update(cfg, key, OmegaConf.select(composed, key), merge=False)
    return cfg


def lacking(saved: DictConfig, cfg: DictConfig) -> list[str]:
    """The keys of ``cfg`` (the saved config merged into the schema) that the saved file does not hold, but for
    those added since its schema version whose default does what that run did (config.versions) and those the
    schema leaves unset (null, {}): Hydra saves every key of the schema, so a key lacking is a file cut short."""
    have = flatten(OmegaConf.to_container(saved, resolve=False))
    filled = upgraded(have)
    full = flatten(OmegaConf.to_container(cfg, resolve=False))
    unset = [None, {}, "???"]  # "???": a section with no value at all, which OmegaConf.missing_keys names
    return [k for k, v in full.items() if k not in have and v not in unset and not (k in filled and filled[k] == v)]


def validate_saved(cfg: DictConfig, run_dir: Path) -> None:
    """Every check of a command line (config.validate) on the config to evaluate; what no check foresaw (a
    saved section cut short, a value of another type) is a ConfigError naming the run."""
    try:
        validate(cfg, trains=False)  # its network is trained: a labelled one may score a user's unlabelled files
    except ConfigError:
        raise
    except Exception as exc:  # noqa: BLE001 - a damaged saved config breaks the checks in any way
        text = " ".join(str(exc).split())[:300]
        bad("run", Shown(str(run_dir)), f"a run whose saved config this version reads ({type(exc).__name__}: {text})")


def outside_other_runs(out_dir, key: str) -> None:
    """The evaluation's directory lies inside no other run or sweep directory (its own, evaluated again, is its
    own): an evaluation in a run's checkpoints/ once wrote there, and that run's report then listed two runs.
    predict's output= and the report's results= refuse such paths alike (runs.layout.check_outside_runs)."""
    check_outside_runs(key, out_dir, Path(str(out_dir)).resolve().parent)


class EvalPreflight(Preflight):
    """Preflight (hybrid_sysid.launch.job) that also builds and checks the config to evaluate."""

    def on_run_start(self, config: DictConfig, **kwargs) -> None:
        with checks_complete():  # a refusal here ends the command in one line, before any directory
            outside_other_runs(config.hydra.run.dir, "hydra.run.dir")
        out_dir = Path(str(config.hydra.run.dir))
        if not out_dir.exists():  # made by the preflight below: this command's to remove (main)
            MADE.append(out_dir)
        super().on_run_start(config, **kwargs)

    def on_multirun_start(self, config: DictConfig, **kwargs) -> None:
        with checks_complete():
            outside_other_runs(config.hydra.sweep.dir, "hydra.sweep.dir")
        super().on_multirun_start(config, **kwargs)

    def check(self, cfg: DictConfig, overrides: list[str]) -> None:
        run_given(cfg)
        evaluated = evaluation_config(Path(str(cfg.run)), cfg, overrides)
        from hybrid_sysid.training.build import check_sizes, check_weights  # deferred

        check_sizes(evaluated, Path(str(cfg.run)), "run")  # before validate builds the network for real
        validate_saved(evaluated, Path(str(cfg.run)))
        check_weights(evaluated, Path(str(cfg.run)), "run")


def run_given(cfg: DictConfig) -> None:
    """run= is given and names a run that ended with its record (one still training, or a damaged record, is
    refused before any read)."""
    if OmegaConf.is_missing(cfg, "run"):
        raise ConfigError("run", missing=True, allowed="the trained run's directory: hybrid-sysid-eval run=DIR")
    RunDir(str(cfg.run)).ended_record("run")


def run_checked(cfg: DictConfig) -> None:
    """run= and the saved config it holds, on Hydra's first composition (launch.first_composition): a refusal in
    one composition, not two. The preflight checks them again, with the network's size and weights."""
    with checks_complete():
        task = task_config(cfg)
        run_given(task)
        evaluation_config(Path(str(task.run)), task, list(cfg.hydra.overrides.task))


def evaluate(composed: DictConfig, out_dir: Path, overrides: list[str], checked: bool) -> dict:
    """The evaluation of one job; imported here, so a sweep's parent process loads no torch."""
    from hybrid_sysid.training.run import evaluate_checkpoint  # deferred

    source = Path(composed.run)
    cfg = evaluation_config(source, composed, overrides)
    if not checked:
        validate_saved(cfg, source)
    if RunDir(out_dir).completed_record() is not None:  # its saved config is the evaluation's own: not replaced
        done = RunDir(out_dir).previous_record(overrides)  # one of other overrides is refused
        log.info("run %s already completed; not running it again", out_dir)
        return done
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        RunDir(out_dir).write_config(cfg, overrides)
        return evaluate_checkpoint(cfg, source, out_dir, overrides, checked=True)
    except OSError as exc:
        if exc.errno not in FULL_DISK or not checked:  # a sweep's job: run_job records it, the sweep goes on
            raise
        # a full disk: the failure's record seldom fits (run_job would then print a second line), and a directory
        # of half-written files is no evaluation; so one line, and a directory made here is removed
        error = f"{type(exc).__name__}: {exc}"
        if out_dir in MADE and RunDir(out_dir).discard():
            fail(f"{error}: the evaluation cannot be written in {out_dir}; the directory is removed", status=1)
        # a directory of before (an interrupted evaluation): its files stay, and the failure is recorded if it fits
        if RunDir(out_dir).try_record_end(overrides, composed.get("seed", 0), "failed", error) is not None:
            fail(f"{error}: the evaluation cannot be written in {out_dir}, nor its failure recorded", status=1)
        raise


@hydra.main(version_base="1.3", config_path=config.CONF_DIR, config_name="eval")
def hydra_main(composed: DictConfig) -> dict:
    hc = HydraConfig.get()
    out_dir, overrides = Path(hc.runtime.output_dir), list(hc.overrides.task)
    multirun = hc.mode == RunMode.MULTIRUN
    record = run_job(
        lambda: evaluate(composed, out_dir, overrides, checked=not multirun),
        out_dir,
        overrides,
        composed.get("seed", 0),
        multirun=multirun,
        sweep_dir=Path(hc.sweep.dir) if multirun else None,
        again="run the same command again to evaluate it",
    )
    if record.get("status") == "completed" and draws_figures(composed.get("run_figures", "auto"), multirun):
        draw_run_figures(out_dir)
    return record


def main() -> None:
    """Console script ``hybrid-sysid-eval`` (exit statuses: hybrid_sysid.launch.process)."""
    try:
        with single_runs_checked_early(run_checked):
            console_main(hydra_main, sys.argv[1:])
    finally:
        discard_unrecorded()


def discard_unrecorded() -> None:
    """Remove the directory this command made if it holds no record when the command ends: Hydra could not write
    its .hydra/ there (a full disk, before the job), or the record itself did not fit. A record, failed or
    interrupted, stays: it says what happened. Only while this process still holds the directory's lock."""
    while MADE:
        out_dir = MADE.pop()
        if locks.holds(out_dir) and not RunDir(out_dir).record_file.exists():
            RunDir(out_dir).discard()
            locks.release(out_dir)


if __name__ == "__main__":
    # python -m: this file runs as __main__, while Hydra builds the preflight from hybrid_sysid.cli.evaluate, a
    # second copy; that copy's main runs, so the directory the preflight notes in MADE is the one main removes
    from hybrid_sysid.cli.evaluate import main as module_main

    module_main()
