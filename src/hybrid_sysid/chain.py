"""What the experiments that chain runs inside one job share (experiment=transfer, experiment=tuned): a config
group's file as a node, and the .hydra files that make a sub-run directory a run of hybrid-sysid for
hybrid-sysid-eval, load_estimator and the sweep summary."""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import CONF_DIR, ConfigError
from hybrid_sysid.records import write_yaml_atomic


def group(name: str, choice: str, key: str) -> DictConfig:
    """A config group's file (conf/<name>/<choice>.yaml) as a node; ConfigError naming ``key`` if absent."""
    path = Path(CONF_DIR) / name / f"{choice}.yaml"
    if not path.is_file():
        options = sorted(p.stem for p in path.parent.glob("*.yaml"))
        raise ConfigError(f"{key}: {name} = {choice!r} is not allowed: one of {', '.join(options)}")
    return OmegaConf.load(path)


def write_run_files(run_dir: Path, cfg: DictConfig, overrides: list[str]) -> None:
    """run_dir/.hydra/config.yaml and overrides.yaml, as Hydra writes them for a job before it starts."""
    write_yaml_atomic(run_dir / ".hydra" / "config.yaml", OmegaConf.to_container(cfg))
    write_yaml_atomic(run_dir / ".hydra" / "overrides.yaml", list(overrides))
