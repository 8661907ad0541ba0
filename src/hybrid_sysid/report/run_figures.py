"""Figures of one run, in the style of the paper's Fig. 6-29 (matplotlib, PNG, no screen needed), drawn from the
run's predictions.csv and curves.csv."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from hybrid_sysid.model.metrics import PARAMETERS  # noqa: E402


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
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def learning_curves_figure(curves: pd.DataFrame, path: Path, title: str = "learning curves") -> None:
    """Mean relative deviation against step, per parameter, one line per (split, noise level)."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for ax, name in zip(axes, PARAMETERS):
        sub = curves[curves["parameter"] == name]
        for (split, std), g in sub.groupby(["split", "noise_std"], sort=True):
            ax.plot(g["step"], g["mean_rel_dev"], marker="o", ms=3, label=f"{split}, noise {std:g}")
        ax.set(xlabel="step", ylabel="mean relative deviation", title=name, yscale="log")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend()
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_run_figures(run_dir) -> None:
    """figures/ of a run directory: test predictions per noise level and K, and the learning curves."""
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
        learning_curves_figure(curves, figures / "learning_curves.png")
