"""The Hydra application behind ``hybrid-sysid``: compose the config, run ``train``, draw the run's figures.

Each job records its own failure in its run directory (Hydra skips ``on_multirun_end`` when a job raises),
so a sweep goes on and its summary lists the failed job.

Under a hyperparameter search (hydra-optuna-sweeper, conf/hparams_search) a job returns one number: the
validation figure its model selection used (``best_score`` of its record: val/loss for a label-free objective,
val/rel_dev otherwise; trainer.monitor). A failed job returns None, which the sweeper cannot cast to a number:
it records a failed trial and the study goes on (a NaN would stop the whole study in optuna's ``tell``).
"""

from __future__ import annotations

import importlib.util
import logging
import os
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig

from hybrid_sysid import config
from hybrid_sysid.config import ConfigError
from hybrid_sysid.records import RECORD, run_record, write_json_atomic

log = logging.getLogger("hybrid_sysid")
_task_started = False


# an option that needs an optional package -> (the module it needs, the install that brings it)
EXTRAS = {
    "hparams_search=": ("hydra_plugins.hydra_optuna_sweeper", 'pip install -e ".[search]"'),
    "hydra/sweeper=optuna": ("hydra_plugins.hydra_optuna_sweeper", 'pip install -e ".[search]"'),
    "launcher=slurm": ("hydra_plugins.hydra_submitit_launcher", 'pip install -e ".[slurm]"'),
    "launcher=submitit_local": ("hydra_plugins.hydra_submitit_launcher", 'pip install -e ".[slurm]"'),
}


def missing_extra(args) -> str | None:
    """A one-line error for the first command-line option whose optional package is not installed (Hydra
    itself would fail on it with a long message on the config search path), else None."""
    for arg in args:
        for prefix, (module, install) in EXTRAS.items():
            if arg.lstrip("+~").startswith(prefix) and not _installed(module):
                return f"{arg} needs {module.split('.')[-1].replace('_', '-')}, which is not installed: {install}"
    return None


def _installed(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:  # its parent package is missing
        return False


def search_value(record: dict) -> float | None:
    """What a job returns to a hyperparameter search: its model-selection figure, None if it has none."""
    value = record.get("best_score")
    return None if value is None else float(value)


@hydra.main(version_base="1.3", config_path=config.CONF_DIR, config_name="config")
def hydra_main(cfg: DictConfig) -> dict | float | None:
    global _task_started
    _task_started = True
    hc = HydraConfig.get()
    run_dir = Path(hc.runtime.output_dir)
    overrides = list(hc.overrides.task)
    multirun = hc.mode == RunMode.MULTIRUN
    searching = "optuna" in str(hc.sweeper.get("_target_", ""))
    # in a tracker, a sweep's jobs are runs of one experiment named after the sweep directory
    experiment = Path(hc.sweep.dir).name if multirun else None
    run_name = hc.job.override_dirname or None
    try:
        # imported here: a sweep's parent process composes and launches jobs, and need not load torch for it
        from hybrid_sysid.report.run_figures import write_run_figures
        from hybrid_sysid.train import train

        if cfg.get("transfer"):  # experiment=transfer: a chain of runs in this job's directory
            from hybrid_sysid.transfer import run_chain

            return run_chain(cfg, run_dir, overrides)
        record = train(cfg, run_dir, overrides, experiment=experiment, run_name=run_name)
        if record.get("rank", 0) == 0:  # with DDP, rank 0 alone has the record
            write_run_figures(run_dir)
        return search_value(record) if searching else record
    except Exception as exc:  # record the failure where the sweep summary will look for it
        error = f"{type(exc).__name__}: {exc}"
        run_dir.mkdir(parents=True, exist_ok=True)
        write_json_atomic(run_dir / RECORD, run_record("failed", overrides, cfg.get("seed", 0), error=error))
        if multirun:  # let the other jobs run; the sweep summary exits non-zero
            log.error("job failed: %s", error)
            return None if searching else {"status": "failed", "error": error}
        if isinstance(exc, ConfigError) and os.environ.get("HYDRA_FULL_ERROR") != "1":
            print(f"error: {exc}", file=sys.stderr)
            sys.exit(2)  # a bad value: one line, no traceback
        raise


def main() -> None:
    """Console script: Hydra's app, with exit status 2 for a config that does not compose (unknown key,
    wrong type, unknown group option) or an option whose optional package is missing: Hydra itself exits 1
    for those, like for any failure."""
    missing = missing_extra(sys.argv[1:])
    if missing:
        print(f"error: {missing}", file=sys.stderr)
        sys.exit(2)
    try:
        hydra_main()
    except SystemExit as exc:
        if exc.code == 1 and not _task_started:
            sys.exit(2)
        raise


if __name__ == "__main__":
    main()
