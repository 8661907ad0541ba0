"""Argument checks of the networks and objectives: a ValueError naming the argument, the value and what is
allowed, raised where the object is built."""

from __future__ import annotations

import math


def check_pair(name: str, value) -> tuple[float, float]:
    """A (p1, p2) pair: two finite values > 0."""
    pair = tuple(float(v) for v in value)
    if len(pair) != 2 or not all(math.isfinite(v) and v > 0 for v in pair):
        raise ValueError(f"{name} = {value} is invalid; it must be two finite values > 0 (p1, p2)")
    return pair


def check_int(name: str, value, low: int) -> int:
    if isinstance(value, bool) or int(value) != value or value < low:
        raise ValueError(f"{name} = {value} is invalid; it must be an integer >= {low}")
    return int(value)
