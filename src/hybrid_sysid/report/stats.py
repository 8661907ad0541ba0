"""The statistics of a comparison table: the Student t interval of a mean over seeds, and the paired test of two
rows on the per-recording relative deviations they share (scipy.stats; the deviations: tables.paired_deviations)."""

from __future__ import annotations

import math

import numpy as np

CONFIDENCE = 0.95  # of the interval over seeds
ALPHA = 0.05  # the paired test's level for †
K_LEVEL = "K"  # the row level of test-time windows per recording, when several are present
NO_KEYS = "all"  # the single row label when no override varies across runs


def scipy_stats():
    """scipy.stats, imported when a table first needs it (0.7 s of import)."""
    from scipy import stats  # deferred

    return stats


def t_interval(values) -> tuple[float, float]:
    """The CONFIDENCE Student t interval of the mean of values (NaN, NaN with fewer than two), within [0, inf).

    The values are mean relative deviations, never negative, and so is their true mean: cutting the interval at 0
    leaves its coverage as it was (it holds the mean exactly when the uncut one does), and a table no longer shows
    a negative error (two seeds far apart once gave [-29.74, 95.58])."""
    v = np.asarray(values, dtype=float)
    if len(v) < 2:
        return math.nan, math.nan
    if np.ptp(v) == 0:  # seeds that agree (a baseline without randomness): the interval is the value itself
        return float(v[0]), float(v[0])
    stats = scipy_stats()
    low, high = stats.t.interval(CONFIDENCE, len(v) - 1, loc=v.mean(), scale=stats.sem(v))
    return max(float(low), 0.0), float(high)


def wilcoxon_p(a, b) -> float:
    """Two-sided p-value of the Wilcoxon signed-rank test of paired samples; 1 when they are equal."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    if not np.any(d):
        return 1.0
    return float(scipy_stats().wilcoxon(a, b).pvalue)


def paired_p(paired: dict | None, label_a, label_b, col) -> float | None:
    """The paired test's p-value between two rows in a column, None when either lacks per-recording data or
    they do not share their recordings."""
    if not paired or label_a not in paired or label_b not in paired:
        return None
    a, b = paired[label_a], paired[label_b]
    if col not in a.columns or col not in b.columns:
        return None
    a, b = a[col].dropna(), b[col].dropna()
    if len(a) < 2 or not a.index.sort_values().equals(b.index.sort_values()):
        return None
    return wilcoxon_p(a.sort_index().to_numpy(), b.sort_index().to_numpy())
