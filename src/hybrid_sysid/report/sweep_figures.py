"""Figures comparing the rows of a sweep summary (e.g. labelled vs hybrid): robustness and learning curves."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import NullLocator  # noqa: E402
import pandas as pd  # noqa: E402

LABELS = {"mean_rel_dev": "mean relative deviation", "std_rel_dev": "std of relative deviation"}


def row_label(keys, values) -> str:
    """'objective=hybrid, road=A'; 'all' for the single row of a sweep where nothing but the seed varies."""
    keys, values = list(keys), [str(v) for v in values]
    if keys == ["all"] and values == ["all"]:
        return "all"
    return ", ".join(f"{k}={v if v != '' else '(default)'}" for k, v in zip(keys, values)) or "all"


def _save(fig, path: Path, title: str) -> None:
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110, format="png")  # explicit: callers may write to a temporary name
    plt.close(fig)


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
            ax.errorbar(x, y, yerr=err, marker="o", ms=4, capsize=3,
                        label=row_label(table.index.names, label if isinstance(label, tuple) else (label,)))
        if positive and len(noises) > 1:
            ax.set_xscale("symlog", linthresh=min(positive), linscale=0.5)
        ax.set_xticks(x, [f"{n:g}" for n in x])  # ticks at the levels evaluated, not at decades
        ax.xaxis.set_minor_locator(NullLocator())
        ax.set_yscale("log")
        ax.set(xlabel="noise std [m/s^2]", ylabel=LABELS.get(metric, metric), title=param)
        ax.grid(True, which="both", alpha=0.3)
    axes[0, 0].legend(fontsize="small")
    _save(fig, path, f"robustness: {split} split, mean ± std over seeds")


def learning_curves_compared(curves: pd.DataFrame, path: Path, metric: str = "mean_rel_dev",
                             split: str = "test") -> None:
    """From the runs' curves.csv rows (with a 'label' column naming the table row): the metric on the split
    at noise 0 (or the lowest level recorded), mean over seeds per step, one line per label, one panel per
    parameter."""
    sub = curves[curves["split"] == split]
    noise = 0.0 if sub.empty or (sub["noise_std"] == 0).any() else sub["noise_std"].min()
    sub = sub[sub["noise_std"] == noise]
    mean = sub.groupby(["label", "parameter", "step"])[metric].mean()
    params = sorted(curves["parameter"].unique())
    fig, axes = plt.subplots(1, len(params), figsize=(5.5 * len(params), 4.2), sharey=True, squeeze=False)
    for ax, param in zip(axes[0], params):
        for label in sorted(sub["label"].unique()):
            if (label, param) in mean.index.droplevel("step"):
                line = mean.loc[(label, param)]
                ax.plot(line.index, line.to_numpy(), marker="o", ms=3, label=label)
        ax.set(xlabel="step", ylabel=LABELS.get(metric, metric), title=param, yscale="log")
        ax.grid(True, which="both", alpha=0.3)
    if axes[0, 0].lines:
        axes[0, 0].legend(fontsize="small")
    _save(fig, path, f"learning curves: {split} split, noise {noise:g}, mean over seeds")
