"""Figures comparing the rows of a sweep's table (e.g. labelled vs hybrid): robustness and learning curves
(an experiment's own figures: hybrid_sysid.experiments). Relative deviations in percent, as in the tables; one
legend per figure."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from hybrid_sysid.report.plotting import (
    LINESTYLES,
    PERCENT,
    curves_figure,
    figure_legend,
    noise_axis,
    panels,
    save_figure,
)
from hybrid_sysid.report.stats import K_LEVEL
from hybrid_sysid.report.tables import BOUND_LABEL, METRICS, row_label

DODGE = 0.3  # the width over which the rows' points at one noise level are spread, so error bars do not hide


def row_dicts(table: pd.DataFrame) -> list[dict]:
    """Each row of the table as {level: value}."""
    names = [str(n) for n in table.index.names]
    return [dict(zip(names, label if isinstance(label, tuple) else (label,))) for label in table.index]


def _offsets(n: int) -> np.ndarray:
    """x offsets of n rows around each noise level's position, within ±DODGE / 2."""
    return (np.arange(n) - (n - 1) / 2) * (DODGE / (n - 1) if n > 1 else 0.0)


def draw_rows(ax, table, param, levels, styles, labels) -> None:
    """One errorbar line per table row in a panel: the mean over seeds in percent at each noise level's position,
    error bars the std over seeds. styles: per row (colour, linestyle)."""
    x = [i for i, n in enumerate(levels) if (n, param, "mean") in table.columns]
    shown = [levels[i] for i in x]
    for offset, (colour, linestyle), label, (_, row) in zip(_offsets(len(table)), styles, labels, table.iterrows()):
        y = row[[(n, param, "mean") for n in shown]].astype(float).to_numpy()
        err = row[[(n, param, "std") for n in shown]].astype(float).fillna(0.0).to_numpy()
        ax.errorbar(
            np.asarray(x, dtype=float) + offset,
            PERCENT * y,
            yerr=PERCENT * err,
            marker="o",
            ms=4,
            capsize=3,
            color=colour,
            linestyle=linestyle,
            label=label,
        )


def draw_bound(ax, bound: pd.DataFrame, param: str, levels) -> None:
    """The Cramér-Rao bound (report.tables.bound_table) in percent at each noise level: black and dashed for the
    smallest K, dotted for the next; what no unbiased estimator beats on these windows."""
    for i, (k, row) in enumerate(bound.iterrows()):
        x = [j for j, n in enumerate(levels) if (n, param) in row.index and np.isfinite(row[(n, param)])]
        if not x:
            continue
        y = [PERCENT * row[(levels[j], param)] for j in x]
        label = BOUND_LABEL + (f", K = {k}" if len(bound) > 1 else "")
        ax.plot(x, y, color="black", linestyle=("--", ":")[min(i, 1)], linewidth=1.2, label=label, zorder=5)


# one line and one legend entry per table row: beyond this many the legend covers the panels and the lines
# cannot be told apart (experiment=anchored has 80 rows; its own figure draws them a fault per panel)
MAX_ROWS = 24


def fits_one_figure(table: pd.DataFrame) -> bool:
    """Whether robustness_figure can draw the table legibly (at most MAX_ROWS rows)."""
    return len(table) <= MAX_ROWS


def robustness_figure(table: pd.DataFrame, path: Path, metric: str = "mean_rel_dev", split: str = "test") -> None:
    """The metric in percent against noise std, one line per table row, one panel per parameter; error bars: std
    over seeds. One colour per row without its K (e.g. per objective), one line style per K (K = 1 solid, the
    next K dashed); the noise levels evenly spaced, and the rows' points spread a little around each."""
    cells = [c for c in table.columns if c[2] == "mean"]
    params = sorted({p for _, p, _ in cells})
    levels = sorted({n for n, _, _ in cells})
    keys = row_dicts(table)
    hue = [tuple((k, v) for k, v in r.items() if k != K_LEVEL) for r in keys]
    colours = {h: f"C{i}" for i, h in enumerate(dict.fromkeys(hue))}
    ks = sorted({r[K_LEVEL] for r in keys}) if K_LEVEL in table.index.names else []
    styles = [
        (colours[h], LINESTYLES[ks.index(r[K_LEVEL]) % len(LINESTYLES)] if ks else "-") for h, r in zip(hue, keys)
    ]
    labels = [row_label(table.index.names, list(r.values())) for r in keys]
    fig, axes = panels(len(params))
    bound = table.attrs.get("bound")
    for ax, param in zip(axes[0], params):
        draw_rows(ax, table, param, levels, styles, labels)
        if bound is not None and not bound.empty and metric == "mean_rel_dev":
            draw_bound(ax, bound, param, levels)
        noise_axis(ax, levels, METRICS[metric], param)
    # rows of one colour are next to each other in the table: one legend column per colour, its K down it
    grouped = ks and len(labels) == len(colours) * len(ks) and len(colours) <= 4
    figure_legend(fig, ncol=len(colours) if grouped else None)
    note = f"; solid: K = {ks[0]:g}, dashed: K = {ks[1]:g}" if len(ks) > 1 else ""
    save_figure(fig, path, f"robustness: {split} split, mean ± std over seeds{note}")


def learning_curves_compared(
    curves: pd.DataFrame, path: Path, metric: str = "mean_rel_dev", split: str = "test"
) -> None:
    """From the runs' curves.csv rows (with a 'label' column naming the table row): the metric in percent on the
    split at noise 0 (or the lowest level recorded), mean over seeds per step, one line per label, one panel per
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
