"""What the experiments that chain runs inside one job share (experiment=transfer, experiment=tuned): a config
group's preset file as a node."""

from __future__ import annotations

from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from hybrid_sysid.config import CONF_DIR
from hybrid_sysid.core.checks import bad


def preset(group: str, choice: str, key: str) -> DictConfig:
    """The file conf/<group>/<choice>.yaml as a node; ConfigError naming ``key`` if there is none."""
    path = Path(CONF_DIR) / group / f"{choice}.yaml"
    if not path.is_file():
        options = sorted(p.stem for p in path.parent.glob("*.yaml"))
        bad(key, choice, f"a {group} preset: one of {', '.join(options)}")
    return OmegaConf.load(path)
