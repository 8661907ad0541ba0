"""The paper's relative deviation |p - p_pred| / p (eq. 24), summarised per parameter."""

from __future__ import annotations

import numpy as np

PARAMETERS = ("p1", "p2")


def relative_deviation(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """(n, 2) -> (n, 2): |p - p_pred| / p."""
    pred, true = np.asarray(pred, dtype=np.float64), np.asarray(true, dtype=np.float64)
    return np.abs(true - pred) / np.abs(true)


def summarise(pred: np.ndarray, true: np.ndarray, **labels) -> list[dict]:
    """One long-form row per parameter: labels + mean_rel_dev, std_rel_dev, n."""
    dev = relative_deviation(pred, true)
    return [
        {
            **labels,
            "parameter": name,
            "mean_rel_dev": float(dev[:, i].mean()),
            "std_rel_dev": float(dev[:, i].std()),
            "n": int(dev.shape[0]),
        }
        for i, name in enumerate(PARAMETERS)
    ]
