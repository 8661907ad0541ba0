"""Matplotlib set up to write PNG files without a screen (the backend is chosen at the first figure, so this
import may follow pyplot's), and the drawing helpers the run and sweep figures share."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402


def save_figure(fig, path: Path, title: str) -> None:
    """Title, lay out, write as PNG and close."""
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110, format="png")  # explicit: callers may write to a temporary name
    plt.close(fig)


def curves_figure(
    curves: pd.DataFrame, path: Path, title: str, y: str = "mean_rel_dev", ylabel: str = "mean relative deviation"
) -> None:
    """One panel per parameter, one line per ``label`` (in order of first appearance): y against step, log y.
    curves: columns label, parameter, step and y."""
    params = sorted(curves["parameter"].unique())
    fig, axes = plt.subplots(1, len(params), figsize=(5.5 * len(params), 4.2), sharey=True, squeeze=False)
    for ax, param in zip(axes[0], params):
        for label, line in curves[curves["parameter"] == param].groupby("label", sort=False):
            ax.plot(line["step"], line[y], marker="o", ms=3, label=label)
        ax.set(xlabel="step", ylabel=ylabel, title=param, yscale="log")
        ax.grid(True, which="both", alpha=0.3)
    if axes[0, 0].lines:
        axes[0, 0].legend(fontsize="small")
    save_figure(fig, path, title)
