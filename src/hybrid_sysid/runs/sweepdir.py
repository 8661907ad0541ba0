"""A sweep directory: Hydra's record of the sweep (multirun.yaml) read as a config or as plain data."""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.core.files import write_atomic
from hybrid_sysid.runs import layout
from hybrid_sysid.runs.rundir import load_config, read_yaml


class SweepDir:
    def __init__(self, path: str | Path):
        self.path = Path(path)

    @property
    def config_file(self) -> Path:
        return self.path / layout.SWEEP_CONFIG

    def saved_config(self) -> DictConfig | None:
        """multirun.yaml as a config; None when it is absent or cannot be read."""
        try:
            cfg = load_config(self.config_file)
        except Exception:  # noqa: BLE001 - absent or damaged: the sweep's own guards still hold
            return None
        return cfg if isinstance(cfg, DictConfig) else None

    def saved_values(self) -> dict:
        """multirun.yaml as plain data (interpolations unresolved), {} when absent or damaged."""
        values = read_yaml(self.config_file)
        return values if isinstance(values, dict) else {}

    def write_config(self, cfg: DictConfig) -> None:
        write_atomic(self.config_file, lambda p: OmegaConf.save(cfg, p))


def sweep_dir_of(run_dir: Path) -> Path | None:
    """The nearest directory at or above run_dir holding a multirun.yaml (a run of experiment=tuned sits two
    levels below its job), None for a run outside a sweep."""
    for d in (Path(run_dir), *Path(run_dir).parents):
        if (d / layout.SWEEP_CONFIG).is_file():
            return d
    return None
