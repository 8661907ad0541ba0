"""Figures of one run, in the style of the paper's Figs. 6-29 (matplotlib, PNG, no screen needed), drawn from the
run's predictions.csv and curves.csv."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from hybrid_sysid.model.metrics import PARAMETERS
from hybrid_sysid.report.plotting import curves_figure, save_figure


def predictions_figure(test: pd.DataFrame, path: Path, title: str) -> None:
    """One row per test noise level; per parameter, the predictions against the sorted true values and the
    histogram of relative deviation (the paper's Figs. 10-13 and 22-29), for one window per recording and, when
    the run averaged K windows, for the largest K beside it. One figure, so a run draws it in about a second."""
    levels = sorted(test["noise_std"].unique())
    ks = sorted({1, int(test["windows"].max())})
    colours = {ks[0]: "tab:red", ks[-1]: "tab:blue"}
    fig, axes = plt.subplots(len(levels), 2 * len(PARAMETERS), figsize=(16, 2.6 * len(levels) + 0.6), squeeze=False)
    for row, std in enumerate(levels):
        for j, name in enumerate(PARAMETERS):
            curve, hist = axes[row, 2 * j], axes[row, 2 * j + 1]
            for k in ks:
                sub = test[(test["noise_std"] == std) & (test["windows"] == k)]
                true, est = sub[f"{name}_true"].to_numpy(), sub[f"{name}_pred"].to_numpy()
                order = np.argsort(true, kind="stable")
                dev = np.abs(true - est) / true
                label = f"K = {k}: mean {dev.mean():.2%}"
                curve.plot(est[order], ".", color=colours[k], ms=2, label=label)
                hist.hist(dev, bins=40, color=colours[k], alpha=0.5, label=label)
            curve.plot(true[order], "-", color="tab:green", lw=1.2)
            curve.set(ylabel=name, title=f"noise std {std:g} m/s^2: {name} (green: true)")
            hist.set(title=f"relative deviation of {name}")
            hist.legend(fontsize="small")
    for ax in axes[-1, 0::2]:
        ax.set_xlabel("test recording (sorted by true value)")
    save_figure(fig, path, title)


def write_run_figures(run_dir) -> None:
    """figures/ of a run directory: test predictions at every noise level (test_predictions.png), and the learning
    curves (mean
    relative deviation against step, one line per split and noise level)."""
    run_dir = Path(run_dir)
    predictions = pd.read_csv(run_dir / "predictions.csv")
    curves = pd.read_csv(run_dir / "curves.csv")
    figures = run_dir / "figures"
    figures.mkdir(exist_ok=True)
    test = predictions[predictions.split == "test"]
    if len(test):
        predictions_figure(test, figures / "test_predictions.png", "test split: predictions and relative deviation")
    if len(curves):
        curves = curves.sort_values(["split", "noise_std", "step"], kind="stable")
        labels = [f"{s}, noise {n:g}" for s, n in zip(curves["split"], curves["noise_std"])]
        curves_figure(curves.assign(label=labels), figures / "learning_curves.png", "learning curves")
