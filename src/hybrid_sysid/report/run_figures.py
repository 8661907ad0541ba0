"""Figures of one run, in the style of the paper's Figs. 6-29 (matplotlib, PNG, no screen needed), drawn from the
run's predictions.csv and curves.csv."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from hybrid_sysid.core.files import write_atomic
from hybrid_sysid.model.metrics import PARAMETERS, relative_deviation
from hybrid_sysid.report.plotting import PERCENT, curves_figure, figure_legend, percent, save_figure
from hybrid_sysid.runs.layout import CURVES, FIGURES, PREDICTIONS
from hybrid_sysid.runs.rundir import RunDir


def predictions_figure(test: pd.DataFrame, path: Path, title: str) -> None:
    """One row per test noise level; per parameter, the predictions against the sorted true values and the
    histogram of relative deviation in percent, on bins shared by the Ks (the paper's Figs. 10-13 and 22-29),
    for one window per recording and, when the run averaged K windows, for the largest K beside it; each
    histogram names the mean deviation per K. One legend for the figure (which colour is which K, and the true
    values). One figure, so a run draws it in about a second."""
    levels = sorted(test["noise_std"].unique())
    ks = sorted({1, int(test["windows"].max())})
    colours = {ks[0]: "tab:red", ks[-1]: "tab:blue"}
    fig, axes = plt.subplots(
        len(levels), 2 * len(PARAMETERS), figsize=(16, 2.6 * len(levels) + 1.0), squeeze=False, layout="constrained"
    )
    for row, std in enumerate(levels):
        at = test[test["noise_std"] == std]
        for j, name in enumerate(PARAMETERS):
            curve, hist = axes[row, 2 * j], axes[row, 2 * j + 1]
            devs = {}
            for k in ks:
                sub = at[at["windows"] == k]
                true, est = sub[f"{name}_true"].to_numpy(), sub[f"{name}_pred"].to_numpy()
                order = np.argsort(true, kind="stable")
                devs[k] = PERCENT * relative_deviation(est, true)
                curve.plot(est[order], ".", color=colours[k], ms=2, label=f"K = {k}")
            edges = np.histogram_bin_edges(np.concatenate(list(devs.values())), bins=40)
            for k, dev in devs.items():
                hist.hist(dev, bins=edges, color=colours[k], alpha=0.5, label=f"K = {k}")
            hist.text(
                0.98,
                0.95,
                "\n".join(f"K = {k}: mean {dev.mean():.2f}%" for k, dev in devs.items()),
                transform=hist.transAxes,
                ha="right",
                va="top",
                fontsize="small",
            )
            curve.plot(true[order], "-", color="tab:green", lw=1.2, label="true value")
            curve.set(ylabel=name, title=f"noise std {std:g} m/s^2: {name}")
            hist.set(title=f"relative deviation of {name} [%]", ylabel="recordings")
    for ax in axes[-1, 0::2]:
        ax.set_xlabel("test recording (sorted by true value)")
    for ax in axes[-1, 1::2]:
        ax.set_xlabel(percent("relative deviation"))
    handles = [Patch(color=colours[k], alpha=0.6, label=f"K = {k}") for k in ks]
    figure_legend(fig, handles=[*handles, Line2D([], [], color="tab:green", lw=1.2, label="true value")])
    save_figure(fig, path, title)


def write_run_figures(run_dir) -> None:
    """figures/ of a run directory: test predictions at every noise level (test_predictions.png), and the learning
    curves (mean relative deviation in percent against step, one line per split and noise level)."""
    run = RunDir(run_dir)
    predictions, curves = run.read_table(PREDICTIONS), run.read_table(CURVES)
    figures = run / FIGURES
    figures.mkdir(exist_ok=True)
    test = predictions[predictions.split == "test"]
    # each figure drawn into a temporary file that then replaces it: a run ended while drawing keeps the figure
    # it had, never a truncated one
    if len(test):
        title = "test split: predictions and relative deviation"
        write_atomic(figures / "test_predictions.png", lambda p: predictions_figure(test, p, title))
    if len(curves):
        curves = curves.sort_values(["split", "noise_std", "step"], kind="stable")
        labels = [f"{s}, noise {n:g}" for s, n in zip(curves["split"], curves["noise_std"])]
        labelled = curves.assign(label=labels)
        write_atomic(figures / "learning_curves.png", lambda p: curves_figure(labelled, p, "learning curves"))
