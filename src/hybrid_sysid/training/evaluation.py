"""A trained model (or a baseline) scored on the data: relative deviations per split, noise level and K, the
predictions behind them, per road class, and the tables a run prints."""

from __future__ import annotations

import pandas as pd

from hybrid_sysid.core import stop
from hybrid_sysid.data.datamodule import QuarterCarDataModule
from hybrid_sysid.model.base import SplitPredictor
from hybrid_sysid.model.metrics import summarise


def score(
    model: SplitPredictor, dm: QuarterCarDataModule, noise_levels, windows=(1,)
) -> tuple[list[dict], pd.DataFrame]:
    """Relative deviations per split, noise level and K (test predictions averaged over K windows per
    recording; train and val on one window), plus one prediction row per recording and evaluation.

    ``model``: a network's IdentificationModule or a baseline (model.base.SplitPredictor)."""
    results, frames = [], []
    evals = [("train", 0.0, 1), ("val", 0.0, 1)] + [("test", float(s), int(k)) for s in noise_levels for k in windows]
    for split, std, k in evals:
        stop.check()  # a safe point (core.stop)
        pred, true = model.predict_split(dm, split, std, windows=k)
        results += summarise(pred, true, split=split, noise_std=std, windows=k)
        rows = dm.rows(split)
        frames.append(
            pd.DataFrame(
                {
                    "split": split,
                    "noise_std": std,
                    "windows": k,
                    "recording": rows,
                    "road_class": dm.dataset.road_class[rows],
                    "m3": dm.dataset.m3[rows],
                    "p1_true": true[:, 0],
                    "p1_pred": pred[:, 0],
                    "p2_true": true[:, 1],
                    "p2_pred": pred[:, 1],
                }
            )
        )
    return results, pd.concat(frames, ignore_index=True)


def by_road_class(predictions: pd.DataFrame) -> list[dict]:
    """Test relative deviations per road class, noise level and K (metrics.json's "by_road_class"): under
    noise the smooth classes, whose signals are smallest, carry most of the error."""
    rows = []
    test = predictions[predictions.split == "test"]
    for (std, k, cls), g in test.groupby(["noise_std", "windows", "road_class"], sort=True):
        pred, true = g[["p1_pred", "p2_pred"]].to_numpy(), g[["p1_true", "p2_true"]].to_numpy()
        rows += summarise(pred, true, split="test", noise_std=float(std), windows=int(k), road_class=str(cls))
    return rows


def class_table(rows: list[dict]) -> str:
    if not rows:
        return ""
    table = pd.DataFrame(rows).pivot_table(
        index=["noise_std", "windows"], columns=["parameter", "road_class"], values="mean_rel_dev"
    )
    return "test mean rel. dev. [%] per road class\n" + (table * 100).round(2).to_string()


def console_table(results: list[dict]) -> str:
    df = pd.DataFrame(results)
    df = df[df.split != "val"]
    index = ["split", "noise_std"] + (["windows"] if df.get("windows", pd.Series([1])).ne(1).any() else [])
    table = df.pivot_table(index=index, columns="parameter", values="mean_rel_dev")
    return (table * 100).round(2).rename(columns=lambda c: f"{c} mean rel. dev. [%]").to_string()
