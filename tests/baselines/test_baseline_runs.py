"""A baseline is a config group of its own: `baseline=ls_window` runs through train() without Lightning and writes
the same record, predictions and figures as a network run."""

import json

import numpy as np
import pandas as pd
import pytest

from hybrid_sysid.report.run_figures import write_run_figures
from hybrid_sysid.training.build import build_datamodule
from hybrid_sysid.training.run import train

TINY = ["data=tiny", "noise.eval_std=[0.0,0.05]", "evaluation.windows=[1,3]"]


@pytest.fixture(scope="module")
def window_run(compose_cfg, tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("ls_window") / "run"
    cfg = compose_cfg("baseline=ls_window", *TINY)
    return cfg, train(cfg, run_dir, overrides=["baseline=ls_window", *TINY]), run_dir


def direct_fit(dm, split, std, k):
    """Independent reference: numpy lstsq per evaluation window, mean over each recording's windows."""
    batch = dm.eval_batch(split, std, windows=k)
    seat, v, d = (batch[key].numpy().astype(np.float64) for key in ("signals", "rel_vel", "rel_disp"))
    p = np.stack(
        [np.linalg.lstsq(np.stack([-v[i], -d[i]], axis=1), seat[i, 0], rcond=None)[0] for i in range(len(seat))]
    )
    return p.reshape(-1, k, 2).mean(axis=1)


def test_ls_window_run_writes_a_completed_record_equal_to_a_direct_computation(window_run):
    cfg, record, run_dir = window_run
    on_disk = json.loads((run_dir / "metrics.json").read_text())
    assert on_disk == json.loads(json.dumps(record))
    assert on_disk["status"] == "completed" and on_disk["error"] is None and on_disk["steps"] == 0
    assert on_disk["train_seconds"] >= 0 and on_disk["best_checkpoint"] is None
    assert not (run_dir / "checkpoints").exists()  # no Lightning
    keys = {(r["split"], r["noise_std"], r["windows"], r["parameter"]) for r in on_disk["results"]}
    assert keys == {
        (s, n, k, p)
        for s, n, k in [
            ("train", 0.0, 1),
            ("val", 0.0, 1),
            ("test", 0.0, 1),
            ("test", 0.0, 3),
            ("test", 0.05, 1),
            ("test", 0.05, 3),
        ]
        for p in ("p1", "p2")
    }
    dm = build_datamodule(cfg)
    dm.setup()
    rows = dm.rows("test")
    true = dm.dataset.params[rows].astype(np.float32).astype(np.float64)  # labels as the batches carry them
    for r in on_disk["results"]:
        if r["split"] != "test":
            continue
        i = ("p1", "p2").index(r["parameter"])
        dev = np.abs(direct_fit(dm, "test", r["noise_std"], r["windows"])[:, i] - true[:, i]) / true[:, i]
        assert r["n"] == len(rows)
        # clean: both are rounding-level (~1e-8), compare absolutely; noisy: the same fit, to rounding
        assert r["mean_rel_dev"] == pytest.approx(dev.mean(), rel=1e-5, abs=1e-7)
        assert r["std_rel_dev"] == pytest.approx(dev.std(), rel=1e-5, abs=1e-7)
    clean = [r["mean_rel_dev"] for r in on_disk["results"] if r["noise_std"] == 0.0]
    assert max(clean) < 1e-6


def test_ls_window_run_writes_predictions_curves_and_figures(window_run):
    _, record, run_dir = window_run
    pred = pd.read_csv(run_dir / "predictions.csv")
    assert {"split", "noise_std", "windows", "recording", "p1_true", "p1_pred"} <= set(pred.columns)
    for r in record["results"]:
        sub = pred[(pred.split == r["split"]) & (pred.noise_std == r["noise_std"]) & (pred.windows == r["windows"])]
        p = r["parameter"]
        dev = (sub[f"{p}_true"] - sub[f"{p}_pred"]).abs() / sub[f"{p}_true"]
        assert len(sub) == r["n"] and dev.mean() == pytest.approx(r["mean_rel_dev"], rel=1e-6, abs=1e-12)
    assert len(pd.read_csv(run_dir / "curves.csv")) == 0  # no learning curve, header only
    write_run_figures(run_dir)  # the app draws them from the two files once train() returns
    for name in ("test_predictions.png",):
        assert (run_dir / "figures" / name).stat().st_size > 10_000


@pytest.mark.parametrize("model", ["ls_series", "ls_bandpass"])
def test_series_baselines_run_and_ignore_k(compose_cfg, tmp_path, model):
    record = train(compose_cfg(f"baseline={model}", *TINY), tmp_path / "run", overrides=[f"baseline={model}"])
    assert record["status"] == "completed" and record["steps"] == 0
    test = {
        (r["noise_std"], r["windows"], r["parameter"]): r["mean_rel_dev"]
        for r in record["results"]
        if r["split"] == "test"
    }
    for (std, _k, p), value in test.items():
        assert value == test[(std, 1, p)]  # series spans see no windows
        if std == 0.0:
            assert value < (1e-4 if model == "ls_series" else 1e-6)
