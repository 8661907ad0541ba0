"""K evaluation windows per recording: K = 1 is the old single window, K > 1 windows are distinct, seeded, and
a model's predictions on them are averaged per recording."""

import numpy as np
import pandas as pd
import pytest
import torch
from torch import nn

from hybrid_sysid.data import SPLITS, DatasetSpec
from hybrid_sysid.data.datamodule import QCMDataModule
from hybrid_sysid.model.module import ParameterEstimator

SPEC = DatasetSpec(n_roads=6, n_masses=5, n_steps=400, seed=1)


def make(seed=0):
    dm = QCMDataModule(SPEC, window=100, batch_size=8, eval_batch_size=7, seed=seed)
    dm.setup()
    return dm


@pytest.fixture(scope="module")
def dm():
    return make()


def old_eval_batch(dm, split, noise_std):
    """The evaluation batch as the data module cut it before K existed (copied from that version)."""
    rows = dm.rows(split)
    rng = np.random.default_rng([dm.seed, SPLITS.index(split)])
    starts = rng.integers(0, dm.data.n_steps - dm.window + 1, size=len(rows))
    base = rng.standard_normal((len(rows), 2, dm.window)) if noise_std > 0 else None
    return dm.data.batch(rows, starts, None if base is None else noise_std * base)


def starts_of(dm, batch):
    """Where each window of the batch was cut from its recording (clean batches: exact float32 match)."""
    out = []
    for row, seat in zip(batch["index"].numpy(), batch["signals"][:, 0].numpy()):
        full = dm.dataset.seat_acc[row]
        hits = [s for s in range(len(full) - len(seat) + 1) if np.array_equal(full[s:s + len(seat)], seat)]
        assert len(hits) == 1
        out.append(hits[0])
    return np.array(out)


@pytest.mark.parametrize("split, std", [("val", 0.0), ("test", 0.0), ("test", 0.01), ("train", 0.1)])
def test_k1_is_the_previous_evaluation_bit_for_bit(dm, split, std):
    want = old_eval_batch(dm, split, std)
    for got in (dm.eval_batch(split, std), make().eval_batch(split, std, windows=1)):
        assert got.keys() == want.keys()
        for key in want:
            assert torch.equal(got[key], want[key]), key


def test_k_windows_are_distinct_reproducible_and_nested(dm):
    k = 6
    clean = dm.eval_batch("test", 0.0, windows=k)
    rows = dm.rows("test")
    assert clean["signals"].shape == (len(rows) * k, 2, 100)
    np.testing.assert_array_equal(clean["index"].numpy(), np.repeat(rows, k))  # recording by recording
    starts = starts_of(dm, clean).reshape(len(rows), k)
    assert all(len(set(s)) == k for s in starts)  # distinct within a recording
    np.testing.assert_array_equal(starts[:, 0], starts_of(dm, dm.eval_batch("test", 0.0)))  # window 0: K = 1's
    assert len(np.unique(starts[:, 1:])) > len(rows)  # spread, not one offset for all
    noisy = dm.eval_batch("test", 0.05, windows=k)
    again = make().eval_batch("test", 0.05, windows=k)
    for key in noisy:
        assert torch.equal(noisy[key], again[key]), key
    fewer = dm.eval_batch("test", 0.05, windows=3)  # the K = 3 windows are the first three of the K = 6 ones
    assert torch.equal(fewer["signals"], noisy["signals"].reshape(len(rows), k, 2, 100)[:, :3].reshape(-1, 2, 100))
    noise = (noisy["signals"] - clean["signals"]).numpy().astype(np.float64).reshape(len(rows), k, 2, -1)
    assert noise.std() == pytest.approx(0.05, rel=0.05)
    # one noise realisation per recording: where two windows overlap, they carry the same noise sample
    shared = 0
    for i in range(len(rows)):
        series = {}
        for j in range(k):
            for t in range(noise.shape[-1]):
                got = noise[i, j, :, t]
                want = series.setdefault(starts[i, j] + t, got)
                np.testing.assert_allclose(got, want, rtol=0, atol=1e-6)
                shared += got is not want
    assert shared > 0  # the test data has overlapping windows, so the check above was exercised
    other = make(seed=1).eval_batch("test", 0.05, windows=k)
    assert not torch.equal(other["signals"], noisy["signals"])


def test_limit_keeps_the_first_recordings_windows(dm):
    full = dm.eval_batch("test", 0.01, windows=4)
    part = dm.eval_batch("test", 0.01, limit=3, windows=4)
    assert torch.equal(part["signals"], full["signals"][:12])


@pytest.mark.parametrize("k", [0, -1, 302, 2.0, True])
def test_bad_k_is_named(dm, k):
    with pytest.raises(ValueError, match=r"evaluation.windows = .* is not allowed: every K must be an integer "
                                         r"in \[1, data.n_steps - data.window \+ 1 = 301\]"):
        dm.eval_batch("test", 0.0, windows=k)


class FakeNet(nn.Module):
    """Deterministic, no parameters to learn: (mean |seat|, RMS body) of the window."""

    def forward(self, signals):
        return torch.stack([signals[:, 0].abs().mean(-1), signals[:, 1].pow(2).mean(-1).sqrt()], dim=-1)


def test_predictions_are_averaged_over_each_recordings_k_windows(dm):
    model = ParameterEstimator(FakeNet(), nn.L1Loss())
    for k in (1, 5):
        pred, true = model.predict_split(dm, "test", 0.02, windows=k)
        batch = dm.eval_batch("test", 0.02, windows=k)  # by hand, grouped by the batch's own recording index
        sig = batch["signals"].numpy().astype(np.float64)
        per_window = pd.DataFrame({"row": batch["index"].numpy(), "a": np.abs(sig[:, 0]).mean(-1),
                                   "b": np.sqrt((sig[:, 1] ** 2).mean(-1))})
        want = per_window.groupby("row", sort=False)[["a", "b"]].mean().loc[dm.rows("test")].to_numpy()
        assert pred.shape == true.shape == (len(dm.rows("test")), 2)
        np.testing.assert_allclose(pred, want, rtol=1e-5)
        np.testing.assert_array_equal(true, dm.dataset.params[dm.rows("test")].astype(np.float32))
    one, _ = model.predict_split(dm, "test", 0.02, windows=1)
    old = FakeNet()(old_eval_batch(dm, "test", 0.02)["signals"]).numpy().astype(np.float64)
    np.testing.assert_array_equal(one, old)  # K = 1: exactly the single-window prediction
