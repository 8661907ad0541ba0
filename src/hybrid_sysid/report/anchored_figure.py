"""What experiment=anchored adds to its table's report (report.extras): the error against noise, one line per
estimator, the least-squares rows dashed, one row of panels per fault and one panel per parameter. Its other
addition, the label-free anchored estimators' targets, is report.anchored_targets."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import pandas as pd

from hybrid_sysid.report.plotting import PERCENT, figure_legend, noise_axis, save_figure
from hybrid_sysid.report.stats import K_LEVEL
from hybrid_sysid.report.tables import METRICS

ESTIMATOR, FAULT = "estimator", "fault"  # the row keys of its sweep (conf/estimator, conf/fault)
FLOOR = 1e-3  # percent: least squares is exact on clean windows, and a log axis has no zero
CLASSICAL = ("ls", "eiv")  # the estimators without a network (conf/estimator), drawn dashed


def anchored_figure(table: pd.DataFrame, path: Path, k: int = 1) -> None:
    """Mean relative deviation in percent against the noise level, one line per estimator (the classical fits
    dashed), error bars the std over seeds, the Cramér-Rao bound dotted; values below FLOOR are drawn at it.
    ``table``: row levels estimator and optionally fault and K; columns (noise, parameter, statistic)."""
    if K_LEVEL in table.index.names:
        table = table.xs(k, level=K_LEVEL)
    faults = list(dict.fromkeys(table.index.get_level_values(FAULT))) if FAULT in table.index.names else [None]
    levels = sorted({n for n, _, s in table.columns if s == "mean"})
    params = sorted({p for _, p, s in table.columns if s == "mean"})
    fig, axes = plt.subplots(
        len(faults), len(params), figsize=(5.5 * len(params), 3.6 * len(faults)), squeeze=False, layout="constrained"
    )
    for row, fault in zip(axes, faults):
        sub = table if fault is None else table.xs(fault, level=FAULT)
        for ax, param in zip(row, params):
            for name in dict.fromkeys(sub.index.get_level_values(ESTIMATOR)):
                line = sub[sub.index.get_level_values(ESTIMATOR) == name]
                mean = [PERCENT * float(line[(n, param, "mean")].iloc[0]) for n in levels]
                err = [PERCENT * float(line[(n, param, "std")].fillna(0.0).iloc[0]) for n in levels]
                style = "--" if str(name).startswith(CLASSICAL) else "-"
                ax.errorbar(
                    range(len(levels)),
                    [max(m, FLOOR) for m in mean],
                    yerr=err,
                    ls=style,
                    marker="o",
                    ms=3,
                    capsize=2,
                    label=str(name),
                )
            bound = table.attrs.get("bound")
            if bound is not None and not bound.empty and k in bound.index:
                # pooled over the faults' runs: each fault's clean windows differ from the others' by its draws only
                values = [PERCENT * float(bound.loc[k].get((n, param), float("nan"))) for n in levels]
                ax.plot(range(len(levels)), [max(v, FLOOR) for v in values], "k:", lw=1.2, label="Cramér-Rao bound")
            title = param if fault is None else f"{fault}: {param}"
            noise_axis(ax, levels, METRICS["mean_rel_dev"], title)
    figure_legend(fig, ncol=4)
    save_figure(fig, path, f"anchored: test split, K = {k}, mean ± std over seeds (below {FLOOR:g}% drawn at it)")
