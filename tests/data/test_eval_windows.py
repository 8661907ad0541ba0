"""K evaluation windows per recording: K = 1 is one seeded window per recording, K > 1 windows are distinct,
seeded, and a model's predictions on them are averaged per recording."""

import numpy as np
import pandas as pd
import pytest
import torch
from torch import nn

from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.datamodule import QuarterCarDataModule
from hybrid_sysid.model.module import IdentificationModule

SPEC = DatasetSpec(n_roads=6, n_masses=5, n_steps=400, seed=1)


def make(seed=0):
    dm = QuarterCarDataModule(SPEC, window=100, batch_size=8, eval_batch_size=7, seed=seed)
    dm.setup()
    return dm


@pytest.fixture(scope="module")
def dm():
    return make()


def starts_of(dm, batch):
    """Where each window of the batch was cut from its recording (clean batches: exact float32 match)."""
    out = []
    for row, seat in zip(batch["index"].numpy(), batch["signals"][:, 0].numpy()):
        full = dm.dataset.seat_acc[row]
        hits = [s for s in range(len(full) - len(seat) + 1) if np.array_equal(full[s : s + len(seat)], seat)]
        assert len(hits) == 1
        out.append(hits[0])
    return np.array(out)


def relative_states_by_loop(seat, body, dt):
    """Symplectic Euler from rest, step by step (v_k from a_0..a_{k-1}, x_k = x_{k-1} + dt v_k), then the
    consistent pairing with the body's velocity one step on: rel_vel_k - dt y''_k (docs/discretisation.md)."""
    vel, disp = np.zeros_like(seat), np.zeros_like(seat)
    v, x = np.zeros(len(seat)), np.zeros(len(seat))
    for k in range(seat.shape[1]):
        x = x + dt * v
        vel[:, k], disp[:, k] = v - dt * body[:, k], x
        v = v + dt * (seat[:, k] - body[:, k])
    return vel, disp


@pytest.mark.parametrize("split, std", [("val", 0.0), ("test", 0.0), ("test", 0.01), ("train", 0.1)])
def test_k1_is_one_seeded_window_per_recording_with_the_noise_asked_for(dm, split, std):
    batch = dm.eval_batch(split, std)  # K = 1, the default
    again = make().eval_batch(split, std, windows=1)  # another data module of the same seed
    assert batch.keys() == again.keys()
    assert all(torch.equal(batch[key], again[key]) for key in batch)
    rows = dm.rows(split)
    np.testing.assert_array_equal(batch["index"].numpy(), rows)  # each recording once, in the split's order
    clean = dm.eval_batch(split, 0.0)
    starts = starts_of(dm, clean)  # each window found once, inside its recording
    assert len(np.unique(starts)) > len(rows) // 2  # spread over the recording, not one offset for all
    assert not np.array_equal(starts, starts_of(dm, make(seed=1).eval_batch(split, 0.0)))  # the seed draws them
    ds = dm.dataset
    for i, (row, s) in enumerate(zip(rows, starts)):
        for key, arr in (("rel_vel", ds.rel_vel), ("rel_disp", ds.rel_disp)):
            np.testing.assert_array_equal(clean[key][i].numpy(), arr[row, s : s + 100])
        np.testing.assert_array_equal(clean["signals"][i, 1].numpy(), ds.body_acc[row, s : s + 100])
    noise = (batch["signals"] - clean["signals"]).numpy().astype(np.float64)
    if std == 0:
        assert not noise.any()
        return
    assert noise.std() == pytest.approx(std, rel=0.1)
    assert abs(noise.mean()) < 0.1 * std
    # the noise enters the hybrid objective's regressors as the window re-integrates it, on top of the state
    # the noise before the window had reached: a constant velocity v0 and the displacement it carries on
    vel, disp = relative_states_by_loop(noise[:, 0], noise[:, 1], SPEC.dt)
    extra_v = (batch["rel_vel"] - clean["rel_vel"]).numpy() - vel
    v0 = extra_v[:, :1]
    np.testing.assert_allclose(extra_v, np.broadcast_to(v0, vel.shape), rtol=0, atol=1e-5 * np.abs(vel).max())
    extra_d = (batch["rel_disp"] - clean["rel_disp"]).numpy() - disp - SPEC.dt * np.arange(1, 101) * v0
    np.testing.assert_allclose(
        extra_d, np.broadcast_to(extra_d[:, :1], disp.shape), rtol=0, atol=1e-5 * np.abs(disp).max()
    )


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
    with pytest.raises(
        ValueError,
        match=r"^windows = .* is not allowed: a non-empty list of integers K "
        r"in \[1, data.n_steps - data.window \+ 1 = 301\]",
    ):
        dm.eval_batch("test", 0.0, windows=k)


class FakeNet(nn.Module):
    """Deterministic, no parameters to learn: (mean |seat|, RMS body) of the window."""

    def forward(self, signals):
        return torch.stack([signals[:, 0].abs().mean(-1), signals[:, 1].pow(2).mean(-1).sqrt()], dim=-1)


def test_predictions_are_averaged_over_each_recordings_k_windows(dm):
    model = IdentificationModule(FakeNet(), nn.L1Loss())
    for k in (1, 5):
        pred, true = model.predict_split(dm, "test", 0.02, windows=k)
        batch = dm.eval_batch("test", 0.02, windows=k)  # by hand, grouped by the batch's own recording index
        sig = batch["signals"].numpy().astype(np.float64)
        per_window = pd.DataFrame(
            {"row": batch["index"].numpy(), "a": np.abs(sig[:, 0]).mean(-1), "b": np.sqrt((sig[:, 1] ** 2).mean(-1))}
        )
        want = per_window.groupby("row", sort=False)[["a", "b"]].mean().loc[dm.rows("test")].to_numpy()
        assert pred.shape == true.shape == (len(dm.rows("test")), 2)
        np.testing.assert_allclose(pred, want, rtol=1e-5)
        np.testing.assert_array_equal(true, dm.dataset.params[dm.rows("test")].astype(np.float32))
    one, _ = model.predict_split(dm, "test", 0.02, windows=1)
    single = FakeNet()(dm.eval_batch("test", 0.02)["signals"]).numpy().astype(np.float64)
    np.testing.assert_array_equal(one, single)  # K = 1: exactly the single window's prediction
