"""The trackers' and callbacks' checks (conf/logger, conf/callbacks): each names a class this package allows, the
library it needs is installed, and what it is given builds, before any directory."""

from __future__ import annotations

import importlib.util

from omegaconf import DictConfig

from hybrid_sysid.config.stores import check_store
from hybrid_sysid.config.targets import build, check_target
from hybrid_sysid.core.checks import ConfigError, bad, check_choice
from hybrid_sysid.core.install import install_command
from hybrid_sysid.core.options import MONITORS

# a logger class -> the modules it can run on (any one of them); they come with the "loggers" extra
LOGGER_MODULES = {"TensorBoardLogger": ("tensorboard", "tensorboardX"), "MLFlowLogger": ("mlflow",)}
# a callback class -> the module it needs; it comes with the "rich" extra
CALLBACK_MODULES = {"RichProgressBar": "rich", "RichModelSummary": "rich"}


def validate_loggers(cfg: DictConfig) -> None:
    """Each configured logger names a class, and the library it needs is installed."""
    for name, lg in (cfg.get("logger") or {}).items():
        target = str(lg.get("_target_", "")) if isinstance(lg, DictConfig) else ""
        if not target:
            bad(f"logger.{name}", lg, "a mapping with the _target_ of a Lightning logger (see conf/logger)")
        check_target(target, f"logger.{name}")
        needs = next((mods for cls, mods in LOGGER_MODULES.items() if target.endswith("." + cls)), ())
        if needs and not any(importlib.util.find_spec(m) for m in needs):
            raise ConfigError(
                f"logger.{name}",
                allowed=f"it needs the {needs[0]} package, not installed: {install_command('loggers')}",
            )
        if target.endswith(".MLFlowLogger"):
            check_store(str(lg.get("tracking_uri") or ""), f"logger.{name}.tracking_uri")


def validate_callbacks(cfg: DictConfig) -> None:
    """Each configured callback (conf/callbacks) names an allowed class, the library it needs is installed, and
    a monitor it watches is one trainer.monitor may name (auto: the run's own)."""
    for name, cb in (cfg.get("callbacks") or {}).items():
        target = str(cb.get("_target_", "")) if isinstance(cb, DictConfig) else ""
        if not target:
            bad(f"callbacks.{name}", cb, "a mapping with the _target_ of a Lightning callback (see conf/callbacks)")
        check_target(target, f"callbacks.{name}")
        module = CALLBACK_MODULES.get(target.rsplit(".", 1)[-1])
        if module and not importlib.util.find_spec(module):
            raise ConfigError(
                f"callbacks.{name}", allowed=f"it needs the {module} package, not installed: {install_command('rich')}"
            )
        if "monitor" in cb:
            check_choice(f"callbacks.{name}.monitor", cb.monitor, MONITORS)
        # built here, as the run builds it, so an argument the class refuses (EarlyStopping's mode, an unknown
        # argument) is one line before any directory, not a traceback after the data's simulation
        fill = {"monitor": MONITORS[1]} if cb.get("monitor") == "auto" else {}
        try:
            build(cb, f"callbacks.{name}", **fill)
        except ConfigError:
            raise
        except Exception as exc:  # noqa: BLE001 - Lightning raises its MisconfigurationException, ValueError...
            kind = target.rsplit(".", 1)[-1]
            raise ConfigError(f"callbacks.{name}", allowed=f"{kind} refuses its arguments: {exc}") from None
        depth = cb.get("max_depth", -1)  # a model summary checks it only when training starts
        if not (isinstance(depth, int) and not isinstance(depth, bool) and depth >= -1):
            bad(f"callbacks.{name}.max_depth", depth, "an integer >= -1 (-1: every layer, 0: no summary)")
