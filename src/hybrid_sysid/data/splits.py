"""Which recordings train, validate and test: a split by road, so no test road is seen in training, and by road
class, so every class of the data is in every split."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hybrid_sysid.core.checks import bad, check_number
from hybrid_sysid.core.options import SPLITS

# the order is part of the seeds: a split's index seeds its evaluation windows and noise


@dataclass(frozen=True)
class Split:
    """Which roads go where: test roads never appear in train or val."""

    train: np.ndarray  # recording indices, ascending
    val: np.ndarray
    test: np.ndarray


def _counts(n_roads: int, train_fraction: float, val_fraction: float) -> tuple[int, int]:
    """(training + validation roads, validation roads) of ``n_roads``: the paper's 80 / 20 roads at 0.8."""
    n_trainval = int(round(train_fraction * n_roads))
    n_val = max(1, int(round(val_fraction * n_trainval))) if val_fraction > 0 else 0
    return n_trainval, n_val


def split_by_road(n_roads: int, n_masses: int, train_fraction: float, val_fraction: float, road_class=None) -> Split:
    """Test roads never train. ``road_class`` (the class letter of each road): the roads of each class are split
    by the fractions on their own, so each class is in train, validation and test and a per-class table has every
    class in every split (a split by position left data=default without a D road among its test roads). Without
    it, or when a class has too few roads to be in all three, the first roads train (the last of them validate)
    and the rest test, as in the paper (80 / 20 roads)."""
    check_number("train_fraction", train_fraction, 0, 1, low_open=True, high_open=True)
    check_number("val_fraction", val_fraction, 0, 1, high_open=True)
    n_trainval, n_val = _counts(n_roads, train_fraction, val_fraction)
    n_train = n_trainval - n_val
    if n_train < 1 or n_trainval >= n_roads:
        bad(
            "n_roads",
            n_roads,
            f"too few for train_fraction = {train_fraction:g} and val_fraction = {val_fraction:g}: need at least "
            "one training, one test" + (" and one validation road" if val_fraction > 0 else " road"),
        )
    roads = np.arange(n_roads)
    if road_class is None:
        groups = [roads]
        trainval = [n_trainval]
    else:
        road_class = np.asarray(road_class)
        if len(road_class) != n_roads:
            bad("road_class", f"{len(road_class)} entries", f"one class per road, {n_roads}")
        _, first = np.unique(road_class, return_index=True)
        groups = [roads[road_class == road_class[i]] for i in sorted(first)]
        trainval = _per_class(np.array([len(g) for g in groups]), n_trainval)
        need = 3 if val_fraction > 0 else 2
        if min(len(g) for g in groups) < need:  # a class this small cannot be in every split
            groups, trainval = [roads], [n_trainval]
    parts: dict[str, list] = {s: [] for s in SPLITS}
    for g, tv in zip(groups, trainval):
        if len(groups) > 1:
            tv = int(np.clip(tv, need - 1, len(g) - 1))
        v = min(max(1, int(round(val_fraction * tv))), tv - 1) if val_fraction > 0 else 0
        parts["train"].append(g[: tv - v])
        parts["val"].append(g[tv - v : tv])
        parts["test"].append(g[tv:])

    def recordings(split):
        chosen = np.sort(np.concatenate(parts[split]))
        return (chosen[:, None] * n_masses + np.arange(n_masses)).ravel()

    train, test = recordings("train"), recordings("test")
    val = recordings("val") if n_val else train  # no val roads: val on train
    return Split(train=train, val=val, test=test)


def _per_class(sizes: np.ndarray, total: int) -> np.ndarray:
    """Training + validation roads of each class, in proportion to its size and adding up to ``total``: the
    largest remainders get the roads that rounding leaves (ties to the class whose first road comes first)."""
    quota = sizes * (total / sizes.sum())
    base = np.floor(quota).astype(int)
    extra = np.argsort(-(quota - base), kind="stable")[: total - base.sum()]
    base[extra] += 1
    return base
