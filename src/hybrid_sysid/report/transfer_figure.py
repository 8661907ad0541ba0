"""What experiment=transfer and experiment=field add to their tables' report (report.extras): a bar figure with
one panel per scenario, and marks that compare the rows (source evaluated there, adapted, from scratch, oracle,
a baseline) within each scenario. The paper's figures are of its car alone, so they are not set beside these."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd

from hybrid_sysid.report.plotting import PERCENT, figure_legend, percent, save_figure
from hybrid_sysid.report.stats import K_LEVEL
from hybrid_sysid.report.tables import METRICS

SCENARIO, ROW = "scenario", "row"  # the row keys of its sub-runs (experiments.transfer)
GROUP_INCHES = 0.8  # the width of one row's group of bars


def transfer_figure(table: pd.DataFrame, path: Path, noise: float = 0.0, k: int = 1) -> None:
    """experiment=transfer and field: one panel per scenario, one group of bars per row (source evaluated there,
    adapted with each objective, from scratch, oracle, a baseline: as many as the table has), p1 and p2 side by
    side at one noise level and K, in percent; error bars: std over seeds. ``table`` has the row levels scenario
    and row (and K when several were evaluated)."""
    if K_LEVEL in table.index.names:
        table = table.xs(k, level=K_LEVEL)
    params = [p for n, p, s in table.columns if s == "mean" and n == noise]
    scenarios = list(dict.fromkeys(table.index.get_level_values("scenario")))
    # each panel as wide as its rows (a one-row panel as three), so every group of bars has the same width
    slots = [max(len(table.xs(s, level="scenario")), 3) for s in scenarios]
    fig, axes = plt.subplots(
        1,
        len(scenarios),
        figsize=(GROUP_INCHES * sum(slots) + 1.2, 4.2),
        sharey=True,
        squeeze=False,
        layout="constrained",
        gridspec_kw={"width_ratios": slots},
    )
    width = 0.8 / max(len(params), 1)
    for ax, scenario in zip(axes[0], scenarios):
        sub = table.xs(scenario, level="scenario")
        x = range(len(sub))
        for j, param in enumerate(params):
            mean = PERCENT * sub[(noise, param, "mean")].astype(float).to_numpy()
            err = PERCENT * sub[(noise, param, "std")].astype(float).fillna(0.0).to_numpy()
            ax.bar([i + (j - (len(params) - 1) / 2) * width for i in x], mean, width, yerr=err, capsize=3, label=param)
        ax.set_xticks(list(x), [str(r) for r in sub.index], rotation=30, ha="right", fontsize="small")
        ax.set_xlim(-0.5, max(len(sub), 3) - 0.5)  # bars as wide in a one-row panel as in the others
        ax.set(title=scenario, yscale="log")
        ax.grid(True, axis="y", which="both", alpha=0.3)
    axes[0, 0].set_ylabel(percent(METRICS["mean_rel_dev"]))
    figure_legend(fig)
    save_figure(fig, path, f"transfer: test split, noise std {noise:g}, K = {k}, mean ± std over seeds")
