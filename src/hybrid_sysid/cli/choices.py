"""Group choices a command may not combine. ``estimator=`` names a network with its objective, or a baseline
(conf/estimator), and Hydra lets a ``model=``, ``objective=`` or ``baseline=`` given beside it win: the run
would train something else under the estimator's name, and a sweep's table would label its row so."""

from __future__ import annotations

from omegaconf import DictConfig

from hybrid_sysid.core.checks import bad

SET_BY_ESTIMATOR = ("model", "objective", "baseline")


def group_of(key: str) -> str:
    """The config group an override's key chooses: ``+model@x`` chooses model, ``model.optim.lr`` none."""
    return key.lstrip("+~").split("@")[0]


def check_estimator(config: DictConfig) -> None:
    """An estimator, chosen or swept, with one of the groups it sets chosen or swept too: one ConfigError."""
    given = {}  # group -> its value, from the command line and the sweep's parameters
    for override in map(str, config.hydra.overrides.task):
        key, _, value = override.partition("=")
        given[group_of(key)] = value
    for key, value in (config.hydra.sweeper.get("params") or {}).items():
        given.setdefault(group_of(str(key)), str(value))
    estimator = given.get("estimator", config.hydra.runtime.choices.get("estimator"))
    clash = [f"{k}=" for k in SET_BY_ESTIMATOR if k in given]
    if estimator is not None and clash:
        bad(
            "estimator",
            estimator,
            f"beside {', '.join(clash)}: the estimator sets its network and objective (or its baseline) itself; "
            "give estimator= alone, or model= and objective= without it",
        )
