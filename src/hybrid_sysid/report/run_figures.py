"""Figures of one run, in the style of the paper's Figs. 6-29 (matplotlib, PNG, no screen needed), drawn from the
run's predictions.csv and curves.csv; and the two drawing helpers the sweep figures share."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from hybrid_sysid.model.metrics import PARAMETERS  # noqa: E402


def save_figure(fig, path: Path, title: str) -> None:
    """Title, lay out, write as PNG and close."""
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110, format="png")  # explicit: callers may write to a temporary name
    plt.close(fig)


def curves_figure(curves: pd.DataFrame, path: Path, title: str, y: str = "mean_rel_dev",
                  ylabel: str = "mean relative deviation") -> None:
    """One panel per parameter, one line per ``label`` (in order of first appearance): y against step, log y.
    curves: columns label, parameter, step and y."""
    params = sorted(curves["parameter"].unique()) or list(PARAMETERS)  # empty curves: empty panels, no crash
    fig, axes = plt.subplots(1, len(params), figsize=(5.5 * len(params), 4.2), sharey=True, squeeze=False)
    for ax, param in zip(axes[0], params):
        for label, line in curves[curves["parameter"] == param].groupby("label", sort=False):
            ax.plot(line["step"], line[y], marker="o", ms=3, label=label)
        ax.set(xlabel="step", ylabel=ylabel, title=param, yscale="log")
        ax.grid(True, which="both", alpha=0.3)
    if axes[0, 0].lines:
        axes[0, 0].legend(fontsize="small")
    save_figure(fig, path, title)


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
