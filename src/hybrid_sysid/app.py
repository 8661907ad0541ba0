"""The Hydra application behind ``hybrid-sysid``: compose the config, run ``train``, draw the run's figures.

Each job records its own failure in its run directory (Hydra skips ``on_multirun_end`` when a job raises),
so a sweep goes on and its summary lists the failed job.
"""

from __future__ import annotations

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


@hydra.main(version_base="1.3", config_path=config.CONF_DIR, config_name="config")
def hydra_main(cfg: DictConfig) -> dict:
    global _task_started
    _task_started = True
    hc = HydraConfig.get()
    run_dir = Path(hc.runtime.output_dir)
    overrides = list(hc.overrides.task)
    multirun = hc.mode == RunMode.MULTIRUN
    try:
        # imported here: a sweep's parent process composes and launches jobs, and need not load torch for it
        from hybrid_sysid.report.run_figures import write_run_figures
        from hybrid_sysid.train import train

        if cfg.get("transfer"):  # experiment=transfer: a chain of runs in this job's directory
            from hybrid_sysid.transfer import run_chain

            return run_chain(cfg, run_dir, overrides)
        record = train(cfg, run_dir, overrides)
        write_run_figures(run_dir)
        return record
    except Exception as exc:  # record the failure where the sweep summary will look for it
        error = f"{type(exc).__name__}: {exc}"
        run_dir.mkdir(parents=True, exist_ok=True)
        write_json_atomic(run_dir / RECORD, run_record("failed", overrides, cfg.get("seed", 0), error=error))
        if multirun:  # let the other jobs run; the sweep summary exits non-zero
            log.error("job failed: %s", error)
            return {"status": "failed", "error": error}
        if isinstance(exc, ConfigError) and os.environ.get("HYDRA_FULL_ERROR") != "1":
            print(f"error: {exc}", file=sys.stderr)
            sys.exit(2)  # a bad value: one line, no traceback
        raise


def main() -> None:
    """Console script: Hydra's app, with exit status 2 for a config that does not compose (unknown key,
    wrong type, unknown group option): Hydra itself exits 1 for those, like for any failure."""
    try:
        hydra_main()
    except SystemExit as exc:
        if exc.code == 1 and not _task_started:
            sys.exit(2)
        raise


if __name__ == "__main__":
    main()
