"""The paper's relative deviation |p - p_pred| / p (eq. 24), summarised per parameter."""

from __future__ import annotations

import numpy as np

PARAMETERS = ("p1", "p2")


def relative_deviation(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """|p - p_pred| / p (eq. 24) element by element; the scores, tables and figures all compute it here.

    Parameters
    ----------
    pred, true : array_like
        Estimates and true p: (n, 2) per window and parameter, or (n,) of one parameter.

    Returns
    -------
    numpy.ndarray
        float64, of their shape.
    """
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


# E|Z| and the median of |Z| for a standard normal Z: an efficient unbiased estimator's error is Gaussian with the
# Cramér-Rao standard deviation, so its mean relative deviation is MEAN_ABS times the bound's standard deviation
MEAN_ABS = float(np.sqrt(2.0 / np.pi))
MEDIAN_ABS = 0.6744897501960817


def bound_fields(pred: np.ndarray, true: np.ndarray, noise_std: float, crb_both, crb_output) -> list[dict]:
    """Per parameter, what an efficient unbiased estimator would score on these recordings at this noise:

    ``bound``: the expected mean relative deviation, sqrt(2 / pi) sigma times the mean over recordings of the
    Cramér-Rao relative standard deviation ``crb_both`` (n, 2) per unit noise, both channels noisy; ``bound_output``:
    the same with noise on the seat alone (``crb_output``); ``efficiency``: the median over recordings of
    |p - p_pred| / p divided by its bound's standard deviation sigma s_i, over the same median for a Gaussian
    (0.674), so 1 for an efficient estimator and above 1 for one that wastes information; None without noise.
    A recording without excitation has an infinite bound, and so has the mean."""
    dev = relative_deviation(pred, true)
    rows = []
    for i in range(len(PARAMETERS)):
        both, output = np.asarray(crb_both)[:, i], np.asarray(crb_output)[:, i]
        efficiency = None
        if noise_std > 0:
            bounded = np.isfinite(both) & (both > 0)  # a recording without excitation has nothing to compare with
            ratio = dev[bounded, i] / (noise_std * both[bounded])
            ratio = ratio[np.isfinite(ratio)]
            efficiency = float(np.median(ratio) / MEDIAN_ABS) if len(ratio) else None
        rows.append(
            {
                "bound": float(MEAN_ABS * noise_std * both.mean()),
                "bound_output": float(MEAN_ABS * noise_std * output.mean()),
                "efficiency": efficiency,
            }
        )
    return rows
