"""Figures of one run, in the style of the paper's Figs. 6-29 (matplotlib, PNG, no screen needed), drawn from the
run's predictions.csv and curves.csv."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from hybrid_sysid.model.metrics import PARAMETERS
from hybrid_sysid.report.plotting import curves_figure, save_figure


def predictions_figure(pred: pd.DataFrame, path: Path, title: str) -> None:
    """Per parameter: predictions against the sorted true values (left), histogram of relative deviation (right)."""
    fig, axes = plt.subplots(2, 2, figsize=(11, 7))
    for row, name in enumerate(PARAMETERS):
        true, est = pred[f"{name}_true"].to_numpy(), pred[f"{name}_pred"].to_numpy()
        order = np.argsort(true, kind="stable")
        ax = axes[row, 0]
        ax.plot(est[order], ".", color="tab:red", ms=2, label="prediction")
        ax.plot(true[order], "-", color="tab:green", lw=1.5, label="true")
        ax.set(xlabel="recording (sorted by true value)", ylabel=name)
        ax.legend(loc="upper left")
        dev = np.abs(true - est) / true
        ax = axes[row, 1]
        ax.hist(dev, bins=50, color="tab:blue")
        ax.set(xlabel=f"relative deviation of {name}", ylabel="count",
               title=f"mean {dev.mean():.2%}, std {dev.std():.2%}")
    save_figure(fig, path, title)


def write_run_figures(run_dir) -> None:
    """figures/ of a run directory: test predictions per noise level and K, and the learning curves (mean
    relative deviation against step, one line per split and noise level)."""
    run_dir = Path(run_dir)
    predictions = pd.read_csv(run_dir / "predictions.csv")
    curves = pd.read_csv(run_dir / "curves.csv")
    figures = run_dir / "figures"
    figures.mkdir(exist_ok=True)
    test = predictions[predictions.split == "test"]
    for (std, k), sub in test.groupby(["noise_std", "windows"], sort=True):
        name = f"test_noise{std:g}" + ("" if k == 1 else f"_windows{k}")
        title = f"test, noise std {std:g} m/s^2" + ("" if k == 1 else f", mean of {k} windows")
        predictions_figure(sub, figures / f"{name}.png", title)
    if len(curves):
        curves = curves.sort_values(["split", "noise_std", "step"], kind="stable")
        labels = [f"{s}, noise {n:g}" for s, n in zip(curves["split"], curves["noise_std"])]
        curves_figure(curves.assign(label=labels), figures / "learning_curves.png", "learning curves")
