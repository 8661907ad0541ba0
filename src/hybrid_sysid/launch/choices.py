"""Group choices a command may not combine. ``estimator=`` names a network with its objective, or a baseline
(conf/estimator), and Hydra lets a ``model=``, ``objective=`` or ``baseline=`` given beside it win: the run
would train something else under the estimator's name, and a sweep's table would label its row so. A baseline
(``baseline=``) has no network: a ``model=`` or ``objective=`` beside it is read by nothing, yet the record's
overrides keep it, and a report's row would say ``hybrid`` for the least-squares fit."""

from __future__ import annotations

from omegaconf import DictConfig

from hybrid_sysid.core.checks import bad
from hybrid_sysid.core.overrides import parse_override

SET_BY_ESTIMATOR = ("model", "objective", "baseline")
UNREAD_BY_BASELINE = ("model", "objective")  # what a baseline run never builds (training/run.py)


def group_of(key: str) -> str:
    """The config group an override's key chooses: ``+model@x`` chooses model, ``model.optim.lr`` none."""
    return parse_override(key).group


def given_choices(config: DictConfig) -> dict[str, str]:
    """Group -> its value as chosen on the command line or swept by the sweep's parameters (a preset's too); a
    deletion (``~objective``) chooses nothing."""
    given = {}
    for override in map(parse_override, config.hydra.overrides.task):
        if not override.deletes:
            given[override.group] = override.value or ""
    for key, value in (config.hydra.sweeper.get("params") or {}).items():
        given.setdefault(group_of(str(key)), str(value))
    return given


def check_choices(config: DictConfig) -> None:
    """The command's group choices, before any directory: check_estimator, then check_baseline."""
    check_estimator(config)
    check_baseline(config)


def check_estimator(config: DictConfig) -> None:
    """An estimator, chosen or swept, with one of the groups it sets chosen or swept too: one ConfigError."""
    given = given_choices(config)
    estimator = given.get("estimator", config.hydra.runtime.choices.get("estimator"))
    clash = [f"{k}=" for k in SET_BY_ESTIMATOR if k in given]
    if estimator is not None and clash:
        bad(
            "estimator",
            estimator,
            f"beside {', '.join(clash)}: the estimator sets its network and objective (or its baseline) itself; "
            "give estimator= alone, or model= and objective= without it",
        )


def check_baseline(config: DictConfig) -> None:
    """A baseline, chosen, swept or set by a preset, with a model or objective chosen or swept beside it: one
    ConfigError naming that group. A sweep holding one baseline among its values is refused,
    since its baseline jobs would carry the unread choice into their rows; no baseline chosen: nothing to check."""
    given = given_choices(config)
    baseline = given.get("baseline", config.hydra.runtime.choices.get("baseline"))
    if baseline is None or str(baseline).strip() in ("null", ""):  # ~baseline, or none chosen
        return
    for group in UNREAD_BY_BASELINE:
        if group in given:
            bad(
                group,
                given[group],
                f"beside baseline={baseline}: a baseline has no network, so it reads no model or objective, and "
                f"its record would be labelled by them; give baseline= alone, or {group}= without it",
            )
