"""objective=cross_segment: the labelled objective's L1 to the fit of the rest of the recording (errors-in-variables or
least squares: tests/data/test_outside_eiv.py), each row weighed by that fit's standard error. References: the
formula in numpy, the labelled objective on clean recordings, and a run whose labels are garbage (the same weights
to the bit)."""

import math

import numpy as np
import pytest
import torch

from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.datamodule import QuarterCarDataModule
from hybrid_sysid.model.cross_segment import CrossSegmentObjective
from hybrid_sysid.model.objectives import LabelledObjective
from hybrid_sysid.training.run import train

BAND = {"low_hz": 4.0, "high_hz": 20.0, "taps": 101}
SCALE = [8.0, 1200.0]
DT = 0.005


def objective(**kwargs):
    return CrossSegmentObjective(p_scale=SCALE, filter=BAND, dt=DT, **kwargs)


def test_the_loss_is_the_weighted_l1_with_undefined_rows_left_out():
    rng = np.random.default_rng(0)
    pred = rng.uniform([4, 600], [12, 1800], size=(6, 2))
    p_out = rng.uniform([4, 600], [12, 1800], size=(6, 2))
    se = rng.uniform(0.001, 0.3, size=(6, 2))
    p_out[2], se[2] = np.nan, np.inf  # an outside fit that is not defined
    batch = {"p_out": torch.tensor(p_out), "se_out": torch.tensor(se), "params": torch.full((6, 2), torch.nan)}
    loss = objective(floor=0.02)(torch.tensor(pred, requires_grad=True), batch)
    w = np.where(np.isfinite(p_out), 1 / (se + 0.02), 0.0)
    w = w / w.mean(axis=0)  # mean 1 over the batch, per parameter
    err = np.where(np.isfinite(p_out), np.abs(pred - np.nan_to_num(p_out)) / SCALE, 0.0)
    assert loss.item() == pytest.approx((w * err).sum(axis=1).mean(), rel=1e-12)
    loss.backward()  # finite gradients, whatever the undefined row


def test_unweighted_every_defined_row_counts_alike():
    rng = np.random.default_rng(1)
    pred = rng.uniform([4, 600], [12, 1800], size=(6, 2))
    p_out = rng.uniform([4, 600], [12, 1800], size=(6, 2))
    se = rng.uniform(0.001, 0.3, size=(6, 2))
    p_out[4, 1], se[4, 1] = np.nan, np.inf
    batch = {"p_out": torch.tensor(p_out), "se_out": torch.tensor(se)}
    loss = objective(weighted=False)(torch.tensor(pred), batch)
    defined = np.isfinite(p_out)
    w = defined / defined.mean(axis=0)
    err = np.where(defined, np.abs(pred - np.nan_to_num(p_out)) / SCALE, 0.0)
    assert loss.item() == pytest.approx((w * err).sum(axis=1).mean(), rel=1e-12)
    with pytest.raises(ConfigError, match="weighted"):
        objective(weighted="no")


@pytest.mark.parametrize("target", ["eiv", "ls"])
def test_on_clean_recordings_it_is_the_labelled_objective(target):
    spec = DatasetSpec(n_roads=6, n_masses=4, n_steps=800, seed=5, seat_spread=0.3)
    obj = objective(target=target)
    dm = QuarterCarDataModule(spec, window=200, seed=0, outside_fir=obj.outside_fir, outside_target=obj.outside_target)
    batch = dm.eval_batch("train", 0.0)
    pred = batch["params"] * torch.tensor([1.1, 0.95])
    # every clean outside fit is exact to rounding, far below the floor: equal weights, the labels' L1
    expected = LabelledObjective(SCALE)(pred, batch).item()
    assert obj(pred, batch).item() == pytest.approx(expected, rel=1e-4)
    assert obj.uses_labels is False and obj.monitor == "val/loss" and obj.fir is None
    assert len(obj.outside_fir) == 101 and obj.outside_target == target


def test_bad_settings_are_named():
    with pytest.raises(ConfigError, match=r"^floor = 0\.0 is not allowed: must be > 0"):
        objective(floor=0.0)
    with pytest.raises(ConfigError, match=r"^dt is missing"):
        CrossSegmentObjective(p_scale=SCALE, filter=BAND)
    with pytest.raises(ConfigError, match=r"^filter\.taps = 100 is not allowed"):
        CrossSegmentObjective(p_scale=SCALE, filter={**BAND, "taps": 100}, dt=DT)
    with pytest.raises(KeyError, match="outside_fir"):
        objective()(torch.ones(2, 2), {"params": torch.ones(2, 2)})


# a tiny run: a window and a band-pass that leave the 400-step recordings of data=tiny a segment outside every
# window; trained over a noise range, so the outside fits carry each row's noise
TINY = [
    "data=tiny",
    "trainer=debug",
    "objective=cross_segment",
    "data.window=100",
    "objective.filter.taps=61",
    "noise.train_std=0.005",
    "noise.train_std_max=0.02",
]


def test_a_run_never_reads_labels_and_selects_on_val_loss(make_cfg, tmp_path, poison_labels):
    clean = train(make_cfg(*TINY), tmp_path / "clean", [])
    poison_labels()
    poisoned = train(make_cfg(*TINY, f"data.cache_dir={tmp_path / 'other'}"), tmp_path / "poisoned", [])
    assert clean["status"] == "completed" and clean["steps"] == 20
    assert clean["monitor"] == poisoned["monitor"] == "val/loss"
    assert math.isfinite(clean["best_score"]) and clean["best_score"] == poisoned["best_score"]
    a, b = (
        torch.load(tmp_path / d / "checkpoints" / "best.ckpt", weights_only=True)["state_dict"]
        for d in ("clean", "poisoned")
    )
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    assert clean["results"] != poisoned["results"]  # the poison reached the labels: the scores, which use them, differ
