"""Figures comparing the rows of a sweep's table (e.g. labelled vs hybrid): robustness and learning curves."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd
from matplotlib.ticker import NullLocator

from hybrid_sysid.report.plotting import curves_figure, save_figure
from hybrid_sysid.report.tables import METRICS, row_label


def robustness_figure(table: pd.DataFrame, path: Path, metric: str = "mean_rel_dev", split: str = "test") -> None:
    """Metric against noise std, one line per table row, one panel per parameter; error bars: std over seeds.
    x is symlog, linear below the smallest non-zero noise, so the clean level (0) is on the axis."""
    cells = [c for c in table.columns if c[2] == "mean"]
    params = sorted({p for _, p, _ in cells})
    noises = sorted({n for n, _, _ in cells})
    positive = [n for n in noises if n > 0]
    fig, axes = plt.subplots(1, len(params), figsize=(5.5 * len(params), 4.2), sharey=True, squeeze=False)
    for ax, param in zip(axes[0], params):
        x = [n for n in noises if (n, param, "mean") in table.columns]
        for label, row in table.iterrows():
            y = row[[(n, param, "mean") for n in x]].astype(float).to_numpy()
            err = row[[(n, param, "std") for n in x]].astype(float).fillna(0.0).to_numpy()
            ax.errorbar(
                x,
                y,
                yerr=err,
                marker="o",
                ms=4,
                capsize=3,
                label=row_label(table.index.names, label if isinstance(label, tuple) else (label,)),
            )
        noise_axis(ax, x, positive, METRICS[metric], param)
    axes[0, 0].legend(fontsize="small")
    save_figure(fig, path, f"robustness: {split} split, mean ± std over seeds")


def noise_axis(ax, x, positive, ylabel: str, title: str) -> None:
    """x (noise std) symlog, linear below the smallest non-zero noise so the clean level (0) is on the axis, ticks
    at the levels evaluated; y log."""
    if positive and len(x) > 1:
        ax.set_xscale("symlog", linthresh=min(positive), linscale=0.5)
    ax.set_xticks(x, [f"{n:g}" for n in x])  # ticks at the levels evaluated, not at decades
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_yscale("log")
    ax.set(xlabel="noise std [m/s^2]", ylabel=ylabel, title=title)
    ax.grid(True, which="both", alpha=0.3)


def tuning_figure(table: pd.DataFrame, path: Path, k: int = 1, metric: str = "mean_rel_dev") -> None:
    """experiment=tuned: the metric against noise std, one colour per objective, dashed with its default values
    and solid with its tuned ones, one panel per parameter, at one K; error bars: std over seeds. ``table`` has
    the row levels objective and tuning (and K when several were evaluated)."""
    if "K" in table.index.names:
        table = table.xs(k, level="K")
    cells = [c for c in table.columns if c[2] == "mean"]
    params = sorted({p for _, p, _ in cells})
    fig, axes = plt.subplots(1, len(params), figsize=(5.5 * len(params), 4.2), sharey=True, squeeze=False)
    # with one objective swept it is no row level: one colour
    rows = [
        {"objective": "", **dict(zip(table.index.names, label if isinstance(label, tuple) else (label,)))}
        for label in table.index
    ]
    colours = {o: f"C{i}" for i, o in enumerate(dict.fromkeys(r["objective"] for r in rows))}
    for ax, param in zip(axes[0], params):
        x = sorted(n for n, p, _ in cells if p == param)
        for keys, (_, row) in zip(rows, table.iterrows()):
            y = row[[(n, param, "mean") for n in x]].astype(float).to_numpy()
            err = row[[(n, param, "std") for n in x]].astype(float).fillna(0.0).to_numpy()
            ax.errorbar(
                x,
                y,
                yerr=err,
                marker="o",
                ms=4,
                capsize=3,
                color=colours[keys["objective"]],
                linestyle="--" if keys["tuning"] == "default" else "-",
                label=", ".join(v for v in (keys["objective"], keys["tuning"]) if v),
            )
        noise_axis(ax, x, [n for n in x if n > 0], METRICS[metric], param)
    axes[0, 0].legend(fontsize="small")
    save_figure(fig, path, f"tuning: test split, K = {k}, mean ± std over seeds (dashed: default values)")


def learning_curves_compared(
    curves: pd.DataFrame, path: Path, metric: str = "mean_rel_dev", split: str = "test"
) -> None:
    """From the runs' curves.csv rows (with a 'label' column naming the table row): the metric on the split
    at noise 0 (or the lowest level recorded), mean over seeds per step, one line per label, one panel per
    parameter."""
    sub = curves[curves["split"] == split]
    noise = 0.0 if sub.empty or (sub["noise_std"] == 0).any() else sub["noise_std"].min()
    mean = sub[sub["noise_std"] == noise].groupby(["label", "parameter", "step"], as_index=False)[metric].mean()
    curves_figure(
        mean,
        path,
        f"learning curves: {split} split, noise {noise:g}, mean over seeds",
        y=metric,
        ylabel=METRICS[metric],
    )


def transfer_figure(table: pd.DataFrame, path: Path, noise: float = 0.0, k: int = 1) -> None:
    """experiment=transfer: one panel per scenario, one group of bars per row (source evaluated there, adapted,
    hybrid from scratch, oracle), p1 and p2 side by side at one noise level and K; error bars: std over seeds.
    ``table`` has the row levels scenario and row (and K when several were evaluated)."""
    levels = list(table.index.names)
    if "K" in levels:
        table = table.xs(k, level="K")
    params = [p for n, p, s in table.columns if s == "mean" and n == noise]
    scenarios = list(dict.fromkeys(table.index.get_level_values("scenario")))
    fig, axes = plt.subplots(1, len(scenarios), figsize=(3.6 * len(scenarios) + 1, 4.2), sharey=True, squeeze=False)
    width = 0.8 / max(len(params), 1)
    for ax, scenario in zip(axes[0], scenarios):
        sub = table.xs(scenario, level="scenario")
        x = range(len(sub))
        for j, param in enumerate(params):
            mean = 100 * sub[(noise, param, "mean")].astype(float).to_numpy()
            err = 100 * sub[(noise, param, "std")].astype(float).fillna(0.0).to_numpy()
            ax.bar([i + (j - (len(params) - 1) / 2) * width for i in x], mean, width, yerr=err, capsize=3, label=param)
        ax.set_xticks(list(x), [str(r) for r in sub.index], rotation=30, ha="right", fontsize="small")
        ax.set_xlim(-0.5, max(len(sub), 3) - 0.5)  # bars as wide in a one-row panel as in the others
        ax.set(title=scenario, yscale="log")
        ax.grid(True, axis="y", which="both", alpha=0.3)
    axes[0, 0].set_ylabel("mean relative deviation [%]")
    axes[0, 0].legend(fontsize="small")
    save_figure(fig, path, f"transfer: test split, noise std {noise:g}, K = {k}, mean ± std over seeds")
