"""The checks a command makes before Hydra creates a directory (Hydra writes .hydra/ there first), as a Hydra
callback: a single job's own checks (``check``, which each command's subclass gives) and no completed run of other
overrides in its run directory; a re-run sweep's overrides against those its directory was made with. A refusal is
one line and exit status 2 (a callback's exception would only be a warning to Hydra)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.cli.job import task_config
from hybrid_sysid.cli.process import PROCESS, fail
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.runs import locks
from hybrid_sysid.runs.layout import STOP_MARKER
from hybrid_sysid.runs.rundir import RunDir
from hybrid_sysid.runs.sweepdir import SweepDir

SEARCH_SWEEPER = "hydra_plugins.hybrid_sysid_search.StudySweeper"  # conf/hydra/sweeper/study.yaml


class Preflight(Callback):
    def check(self, cfg: DictConfig, overrides: list[str]) -> None:
        """The command's checks of a single job's config (without Hydra's section); raise ConfigError."""

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        run_dir, overrides = Path(str(config.hydra.run.dir)), list(config.hydra.overrides.task)
        try:
            self.check(task_config(config), overrides)
            make_dir(run_dir, "hydra.run.dir")
            locks.hold(run_dir, "hydra.run.dir")  # before Hydra writes .hydra/ there: one writer per directory
            RunDir(run_dir).previous_record(overrides)  # a completed run of other overrides
        except (ConfigError, ValueError) as exc:
            fail(str(exc))

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = PROCESS.sweep_dir = Path(str(config.hydra.sweep.dir))
        try:
            if is_search(config):  # a search: its space and settings before any trial
                from hybrid_sysid.experiments.search import study_settings

                study_settings(task_config(config), config.hydra.sweeper, config.hydra.overrides.task)
            make_dir(sweep_dir, "hydra.sweep.dir")
            locks.hold(sweep_dir, "hydra.sweep.dir")  # one sweep per directory at a time
        except ConfigError as exc:
            fail(str(exc))
        (sweep_dir / STOP_MARKER).unlink(missing_ok=True)  # a re-run continues an interrupted sweep
        was = SweepDir(sweep_dir).saved_config()
        if was is None:  # none yet, or unreadable: the jobs' own guards still hold
            return
        try:
            differs = _sweep_of(was) != _sweep_of(config)
        except Exception:  # noqa: BLE001 - a file without Hydra's keys cannot tell either
            return
        if differs:
            fail(
                f"hydra.sweep.dir = {sweep_dir} holds a sweep of other overrides ({' '.join(_sweep_of(was)[0])}); "
                "re-run it with the same ones, or choose another hydra.sweep.dir"
            )


def is_search(config: DictConfig) -> bool:
    """Whether the sweep is a hyperparameter search (the study sweeper, hybrid_sysid.cli.search)."""
    return str(config.hydra.sweeper.get("_target_", "")) == SEARCH_SWEEPER


def _sweep_of(cfg: DictConfig) -> tuple:
    """What makes a sweep's jobs: its command-line overrides and the sweeper's parameters (an experiment's)."""
    params = cfg.hydra.sweeper.get("params")
    return sorted(cfg.hydra.overrides.task), OmegaConf.to_container(params) if params is not None else {}


def make_dir(path: Path, key: str) -> None:
    """Hydra would make it next, and print a traceback if it cannot: one line instead."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        fail(f"{key} = {path} cannot be created: {type(exc).__name__}: {exc}")
