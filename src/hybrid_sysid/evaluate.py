"""``hybrid-sysid-eval run=<run dir> [overrides]``: a trained run evaluated on other data, without training.

The run's saved config (.hydra/config.yaml) is the base; each override of data, car, road, noise or evaluation
replaces that key (a group choice such as ``car=soft_seat`` replaces the whole group), so one trained network is
evaluated on another car, road class, noise level or measurement. Model, objective and training are the run's:
overriding them is a one-line error (exit 2). Works under ``-m``: every job writes its own record, naming the
source run, and the sweep summary reads them. The job directory's .hydra/config.yaml is replaced by the config
that was evaluated, so the directory describes itself.
"""

from __future__ import annotations

import logging
import os
import signal
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf

from hybrid_sysid import config
from hybrid_sysid.app import Interrupted, interruptible, record_end
from hybrid_sysid.config import Config, ConfigError
from hybrid_sysid.records import write_yaml_atomic

log = logging.getLogger("hybrid_sysid")
# keys an evaluation may change; anything else the run trained with stays
OVERRIDABLE = ("data", "car", "road", "noise", "evaluation")
LAUNCHER_KEYS = ("trainer.threads", "trainer.progress_bar")  # what a launcher group sets for its workers
_task_started = False


def override_keys(overrides) -> list[str]:
    """The dotted key of each command-line override ("car.c3=700" -> "car.c3", "+data.x=1" -> "data.x")."""
    return [o.split("=", 1)[0].lstrip("+~") for o in overrides]


def evaluation_config(run_dir: Path, composed: DictConfig, overrides) -> DictConfig:
    """The run's saved config with the overridden keys taken from ``composed`` (the eval app's config, in
    which Hydra has composed the overrides). A key outside OVERRIDABLE raises ConfigError."""
    from hybrid_sysid.train import saved_config

    base = saved_config(run_dir, "run")
    cfg = OmegaConf.merge(OmegaConf.structured(Config), {k: v for k, v in base.items() if k != "hydra"})
    for key in override_keys(overrides):
        top = key.split(".")[0]
        if key == "run" or top == "hydra":
            continue
        if key == "launcher":
            for k in LAUNCHER_KEYS:
                OmegaConf.update(cfg, k, OmegaConf.select(composed, k), merge=False)
            continue
        if top not in OVERRIDABLE and key not in LAUNCHER_KEYS:
            raise ConfigError(f"{key} cannot be overridden in an evaluation: the network and how it was trained "
                              f"are the run's; allowed: {', '.join(OVERRIDABLE)} (and their keys)")
        OmegaConf.update(cfg, key, OmegaConf.select(composed, key), merge=False)
    return cfg


@hydra.main(version_base="1.3", config_path=config.CONF_DIR, config_name="eval")
def hydra_main(composed: DictConfig) -> dict:
    global _task_started
    _task_started = True
    hc = HydraConfig.get()
    out_dir = Path(hc.runtime.output_dir)
    overrides = list(hc.overrides.task)
    multirun = hc.mode == RunMode.MULTIRUN
    seed = composed.get("seed", 0)
    try:
        with interruptible():
            from hybrid_sysid.report.run_figures import write_run_figures
            from hybrid_sysid.train import evaluate_run

            source = Path(composed.run)
            cfg = evaluation_config(source, composed, overrides)
            out_dir.mkdir(parents=True, exist_ok=True)
            write_yaml_atomic(out_dir / ".hydra" / "config.yaml", OmegaConf.to_container(cfg))
            record = evaluate_run(cfg, source, out_dir, overrides)
        write_run_figures(out_dir)
        return record
    except Interrupted as exc:  # as hybrid_sysid.app: recorded, and a re-run evaluates it again
        name = signal.Signals(exc.signum).name
        result = record_end(out_dir, overrides, seed, "interrupted", f"interrupted by {name}")
        log.error("%s: interrupted by %s; run the same command again to evaluate it", out_dir, name)
        if not multirun:
            sys.exit(128 + exc.signum)
        return result
    except Exception as exc:  # as hybrid_sysid.app: the failure is recorded where the sweep summary looks
        error = f"{type(exc).__name__}: {exc}"
        record_end(out_dir, overrides, seed, "failed", error)
        if multirun:
            log.error("job failed: %s", error)
            return {"status": "failed", "error": error}
        if isinstance(exc, ConfigError) and os.environ.get("HYDRA_FULL_ERROR") != "1":
            print(f"error: {exc}", file=sys.stderr)
            sys.exit(2)
        raise


def main() -> None:
    """Console script; exit status 2 for a config that does not compose, as hybrid-sysid, and 128 + the signal's
    number for SIGTERM or SIGINT (before the evaluation starts there is nothing to record)."""
    try:
        with interruptible():
            hydra_main()
    except Interrupted as exc:
        sys.exit(128 + exc.signum)
    except SystemExit as exc:
        if exc.code == 1 and not _task_started:
            sys.exit(2)
        raise


if __name__ == "__main__":
    main()
