"""A trained model (or a baseline) scored on the data: relative deviations per split, noise level and K, the
predictions behind them, per road class, and the tables a run prints."""

from __future__ import annotations

import numpy as np
import pandas as pd

from hybrid_sysid.core import stop
from hybrid_sysid.data.datamodule import QuarterCarDataModule
from hybrid_sysid.model.base import SplitPredictor
from hybrid_sysid.model.metrics import PARAMETERS, bound_fields, summarise
from hybrid_sysid.physics.eiv import crb_relative_std, eiv_model


def score(
    model: SplitPredictor, dm: QuarterCarDataModule, noise_levels, windows=(1,)
) -> tuple[list[dict], pd.DataFrame]:
    """Relative deviations per split, noise level and K (test predictions averaged over K windows per
    recording; train and val on one window), plus one prediction row per recording and evaluation.

    ``model``: a network's IdentificationModule or a baseline (model.base.SplitPredictor). A data module with a
    ``reference`` (a user's recordings, data.recordings) names in every row what the deviations are measured
    against: "labels", or the fit over the whole recording where the recordings have none."""
    results, frames, bounds = [], [], {}
    reference = getattr(dm, "reference", None)
    labels = {} if reference is None else {"reference": reference}
    evals = [("train", 0.0, 1), ("val", 0.0, 1)] + [("test", float(s), int(k)) for s in noise_levels for k in windows]
    for split, std, k in evals:
        stop.check()  # a safe point (core.stop)
        pred, true = model.predict_split(dm, split, std, windows=k)
        rows = summarise(pred, true, split=split, noise_std=std, windows=k, **labels)
        if split == "test":
            if k not in bounds:
                bounds[k] = recording_bounds(dm, split, k)
            for row, fields in zip(rows, bound_fields(pred, true, std, *bounds[k])):
                row.update(fields)
        results += rows
        frames.append(
            pd.DataFrame(
                {
                    "split": split,
                    "noise_std": std,
                    "windows": k,
                    **recording_columns(dm, split),
                    "p1_true": true[:, 0],
                    "p1_pred": pred[:, 0],
                    "p2_true": true[:, 1],
                    "p2_pred": pred[:, 1],
                }
            )
        )
    return results, pd.concat(frames, ignore_index=True)


def recording_columns(dm, split: str) -> dict:
    """predictions.csv's recording, road_class and m3 of a split's recordings: the data module's own (a user's
    recordings keep their names), else the simulated dataset's."""
    own = getattr(dm, "recording_columns", None)
    if own is not None:
        return own(split)
    rows = dm.rows(split)
    return {"recording": rows, "road_class": dm.dataset.road_class[rows], "m3": dm.dataset.m3[rows]}


def recording_bounds(dm: QuarterCarDataModule, split: str, windows: int) -> tuple[np.ndarray, np.ndarray]:
    """Per recording of ``split``, the Cramér-Rao relative standard deviation of (p1, p2) per unit noise std (n, 2),
    with noise on both channels (the simulator's ratio, 1) and on the seat alone: computed on the split's clean
    evaluation windows at the true p (physics.eiv), the model the recording's (physics.eiv.eiv_model).

    With K windows per recording, their information adds as if their noise were independent: an estimator that
    averages K overlapping windows of one noisy recording cannot do better, so the bound stays a bound."""
    batch = dm.eval_batch(split, 0.0, windows=windows)
    seat, body = (batch["signals"][:, i].numpy().astype(np.float64) for i in (0, 1))
    p = batch["params"].numpy().astype(np.float64)
    spec = dm.dataset.spec
    out = []
    for ratio in (1.0, 0.0):
        s = crb_relative_std(seat, body, p, spec.dt, noise_ratio=ratio, model=eiv_model(spec.measurement))
        with np.errstate(divide="ignore"):
            out.append(1.0 / np.sqrt((1.0 / s**2).reshape(-1, windows, len(PARAMETERS)).sum(axis=1)))
    return out[0], out[1]


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
    text = (table * 100).round(2).rename(columns=lambda c: f"{c} mean rel. dev. [%]").to_string()
    if "reference" in df and (df.reference != "labels").any():  # a user's recordings without labels
        text = f"deviations from the {df.reference.iloc[0]} (no labels), not from true values\n{text}"
    return text
