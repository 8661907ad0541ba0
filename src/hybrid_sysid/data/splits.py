"""Which recordings train, validate and test: a split by road, so no test road is seen in training."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hybrid_sysid.core.checks import ConfigError

# the order is part of the seeds: a split's index seeds its evaluation windows and noise
SPLITS = ("train", "val", "test")


@dataclass(frozen=True)
class Split:
    """Which roads go where: test roads never appear in train or val."""

    train: np.ndarray  # recording indices
    val: np.ndarray
    test: np.ndarray


def split_by_road(n_roads: int, n_masses: int, train_fraction: float, val_fraction: float) -> Split:
    """The first roads train (the last of them validate), the rest test, as in the paper (80 / 20 roads)."""
    if not 0.0 < train_fraction < 1.0:
        raise ConfigError(f"data.train_fraction = {train_fraction} is not allowed: must lie in (0, 1)")
    if not 0.0 <= val_fraction < 1.0:
        raise ConfigError(f"data.val_fraction = {val_fraction} is not allowed: must lie in [0, 1)")
    n_trainval = int(round(train_fraction * n_roads))
    n_val = max(1, int(round(val_fraction * n_trainval))) if val_fraction > 0 else 0
    n_train = n_trainval - n_val
    if n_train < 1 or n_trainval >= n_roads:
        raise ConfigError(
            f"data.n_roads = {n_roads} is too few for data.train_fraction = {train_fraction} and "
            f"data.val_fraction = {val_fraction}: need at least one training, one test"
            + (" and one validation road" if val_fraction > 0 else " road")
        )

    def recordings(r0, r1):
        return np.arange(r0 * n_masses, r1 * n_masses)

    val = recordings(n_train, n_trainval) if n_val else recordings(0, n_train)  # no val roads: val on train
    return Split(train=recordings(0, n_train), val=val, test=recordings(n_trainval, n_roads))
