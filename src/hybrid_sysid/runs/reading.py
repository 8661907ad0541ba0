"""Reading what run directories hold: which directories are runs, and their YAML files within core.files' limits
(a received file is data: bounded in size, depth and expanded aliases)."""

from __future__ import annotations

from pathlib import Path

import yaml
from omegaconf import DictConfig, ListConfig, OmegaConf

from hybrid_sysid.core.files import read_yaml_text
from hybrid_sysid.runs import layout


def find_runs(path: Path) -> list[Path]:
    """Every directory at or below ``path`` holding a record: a run, a sweep's jobs, a chain's sub-runs."""
    path = Path(path)
    found = {path.resolve()} if (path / layout.RECORD).is_file() else set()
    found.update(p.parent.resolve() for p in path.rglob(layout.RECORD) if p.is_file())
    return sorted(found)


def read_yaml(path: Path):
    """A YAML file as plain data; None when it is missing, damaged or beyond core.files' limits (a report then
    knows less of the run)."""
    try:
        return yaml.safe_load(read_yaml_text(path))
    except (OSError, ValueError, yaml.YAMLError):  # UnicodeDecodeError and core.files' refusals are ValueErrors
        return None


def load_config(path: Path) -> DictConfig | ListConfig:
    """A received YAML file as OmegaConf reads it, within core.files' limits (size, regular file, depth, aliases
    expanded): what OmegaConf.load would do without them."""
    return OmegaConf.create(read_yaml_text(path))
