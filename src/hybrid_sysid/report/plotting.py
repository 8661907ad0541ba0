"""Matplotlib set up to write PNG files without a screen (the backend is chosen at the first figure, so this
import may follow pyplot's), and what the run and sweep figures share: percent on every error axis (the tables
are in percent), one legend per figure, below its panels, and the noise axis as the levels evaluated."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.ticker import LogFormatter, NullLocator  # noqa: E402

PERCENT = 100.0  # a relative deviation (a fraction, as recorded) times this is what the tables and figures show
NOISE_LABEL = "noise std [m/s^2]: the levels evaluated, evenly spaced (not to scale)"
LINESTYLES = ("-", "--", ":", "-.")  # by K in increasing order: K = 1 solid, the next K (e.g. 8) dashed


def percent(label: str) -> str:
    """An axis label for a relative deviation shown in percent: 'mean relative deviation [%]'."""
    return f"{label} [%]"


def panels(n: int, width: float = 5.5, height: float = 4.2, sharey: bool = True):
    """A figure of n panels in a row, laid out (constrained) to leave room for its one legend below them."""
    return plt.subplots(1, n, figsize=(width * n, height), sharey=sharey, squeeze=False, layout="constrained")


def figure_legend(fig, ncol: int | None = None, handles=None):
    """The figure's one legend, below its panels: ``handles`` (artists with labels) if given, else every labelled
    line, bar or error bar of its panels, each label once, in order of first appearance. ``ncol``: columns
    (entries fill a column before the next); default as many as fit in one row of up to 4. None when nothing is
    labelled."""
    entries = {}
    if handles is not None:
        entries = {h.get_label(): h for h in handles}
    for ax in fig.axes if handles is None else ():
        for handle, label in zip(*ax.get_legend_handles_labels()):
            entries.setdefault(label, handle)
    if not entries:
        return None
    return fig.legend(
        list(entries.values()),
        list(entries),
        loc="outside lower center",
        ncol=ncol or min(len(entries), 4),
        fontsize="small",
    )


class _PlainLog(LogFormatter):
    """Log-axis tick labels as plain numbers (2, 5, 10, 20), not powers of ten: the axis reads as percent."""

    def _num_to_string(self, x, vmin, vmax):
        return f"{x:.3g}"


def percent_log_axis(ax, ylabel: str) -> None:
    """y: a relative deviation in percent on a log scale, its ticks labelled as plain numbers."""
    ax.set_yscale("log")
    ax.yaxis.set_major_formatter(_PlainLog())
    ax.yaxis.set_minor_formatter(_PlainLog(labelOnlyBase=False))
    ax.set_ylabel(percent(ylabel))


def noise_axis(ax, levels, ylabel: str, title: str) -> None:
    """x: the noise levels evaluated as evenly spaced categories (position i is levels[i], whatever the gaps
    between them: the label says so), ticked with their values; y: the metric in percent, log scale."""
    ax.set_xticks(range(len(levels)), [f"{n:g}" for n in levels])
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_xlim(-0.5, len(levels) - 0.5)
    ax.set(xlabel=NOISE_LABEL, title=title)
    percent_log_axis(ax, ylabel)
    ax.grid(True, which="both", alpha=0.3)


def save_figure(fig, path: Path, title: str) -> None:
    """Title, lay out (unless the figure has its own layout engine), write as PNG and close."""
    fig.suptitle(title)
    if fig.get_layout_engine() is None:
        fig.tight_layout()
    fig.savefig(path, dpi=110, format="png")  # explicit: callers may write to a temporary name
    plt.close(fig)


def curves_figure(
    curves: pd.DataFrame, path: Path, title: str, y: str = "mean_rel_dev", ylabel: str = "mean relative deviation"
) -> None:
    """One panel per parameter, one line per ``label`` (in order of first appearance): y (a relative deviation)
    in percent against step, log y, one legend for the figure. curves: columns label, parameter, step and y."""
    params = sorted(curves["parameter"].unique())
    fig, axes = panels(len(params))
    for ax, param in zip(axes[0], params):
        for label, line in curves[curves["parameter"] == param].groupby("label", sort=False):
            ax.plot(line["step"], PERCENT * line[y], marker="o", ms=3, label=label)
        ax.set(xlabel="step", title=param)
        percent_log_axis(ax, ylabel)
        ax.grid(True, which="both", alpha=0.3)
    figure_legend(fig)
    save_figure(fig, path, title)
