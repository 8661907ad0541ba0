"""Windows, noise and batches of the data module."""

from itertools import islice
from types import SimpleNamespace

import numpy as np
import pytest
import torch

from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.datamodule import QuarterCarDataModule

SPEC = DatasetSpec(n_roads=6, n_masses=5, n_steps=400, seed=1)


def make(**kwargs):
    dm = QuarterCarDataModule(SPEC, window=100, batch_size=8, **kwargs)
    dm.setup("fit")
    return dm


@pytest.fixture(scope="module")
def dm():
    return make()


def window_start(dm, row, seat_window):
    """Where in the recording this window was cut (exact float32 match)."""
    full = dm.dataset.seat_acc[row]
    n = len(seat_window)
    starts = [s for s in range(len(full) - n + 1) if np.array_equal(full[s : s + n], seat_window)]
    assert len(starts) == 1
    return starts[0]


def test_training_batches_are_windows_of_training_recordings(dm):
    starts = []
    seen = []
    stream = dm.train_windows
    for batch in stream.one_pass(0):
        assert batch["signals"].shape[1:] == (2, 100)
        for i, row in enumerate(batch["index"].numpy()):
            assert row in dm.split.train
            s = window_start(dm, row, batch["signals"][i, 0].numpy())
            np.testing.assert_array_equal(batch["signals"][i, 1].numpy(), dm.dataset.body_acc[row, s : s + 100])
            np.testing.assert_array_equal(batch["rel_vel"][i].numpy(), dm.dataset.rel_vel[row, s : s + 100])
            np.testing.assert_allclose(batch["params"][i].numpy(), dm.dataset.params[row], rtol=1e-6)
            starts.append(s)
        seen.extend(batch["index"].tolist())
    assert sorted(seen) == sorted(dm.split.train.tolist())  # one pass = each training recording once
    assert len(set(starts)) > len(starts) // 2  # starts spread over the valid range


def test_each_pass_draws_new_windows_and_a_seed_repeats_them():
    a, b = make(seed=5), make(seed=5)
    it = iter(a.train_dataloader())
    a1 = next(it)
    for _ in range(a.train_windows.batches_per_pass - 1):
        next(it)
    a2 = next(it)  # first batch of the second pass
    b1 = next(iter(b.train_dataloader()))
    assert torch.equal(a2["signals"], next(iter(a.train_windows.one_pass(1)))["signals"])
    assert torch.equal(a1["signals"], b1["signals"])
    assert not torch.equal(a1["signals"], a2["signals"])
    assert not torch.equal(a1["signals"], next(iter(make(seed=6).train_dataloader()))["signals"])


def test_evaluation_windows_are_fixed_and_noise_is_seeded(dm):
    clean = dm.eval_batch("test", 0.0)
    assert set(clean["index"].tolist()) == set(dm.split.test.tolist())
    again = make().eval_batch("test", 0.0)
    assert torch.equal(clean["signals"], again["signals"])
    noisy = dm.eval_batch("test", 0.1)
    diff = (noisy["signals"] - clean["signals"]).numpy()
    assert diff.std() == pytest.approx(0.1, rel=0.05)
    assert abs(diff.mean()) < 0.01 and abs(np.corrcoef(diff[:, 0].ravel(), diff[:, 1].ravel())[0, 1]) < 0.05
    assert torch.equal(noisy["signals"], make().eval_batch("test", 0.1)["signals"])
    other_seed = make(seed=2).eval_batch("test", 0.1)["signals"]
    assert not torch.equal(noisy["signals"], other_seed)


def test_test_loaders_follow_the_noise_levels(dm):
    loaders = [dm.eval_dataloader("test", s) for s in (0.0, 0.01, 0.1)]
    stds = [(next(iter(ld))["signals"] - next(iter(loaders[0]))["signals"]).std().item() for ld in loaders]
    np.testing.assert_allclose(stds, [0.0, 0.01, 0.1], rtol=0.05, atol=1e-9)


def test_batches_satisfy_the_seat_equation(dm):
    batch = dm.eval_batch("val", 0.0)
    p1, p2 = batch["params"][:, :1], batch["params"][:, 1:]
    rebuilt = -p1 * batch["rel_vel"] - p2 * batch["rel_disp"]
    seat = batch["signals"][:, 0]
    assert ((rebuilt - seat).pow(2).mean() / seat.pow(2).mean()).item() < 1e-8


def test_training_noise_is_added_when_asked():
    clean = next(iter(make(seed=3).train_dataloader()))
    noisy = next(iter(make(seed=3, train_std=0.05).train_dataloader()))
    assert torch.equal(clean["index"], noisy["index"])
    assert (noisy["signals"] - clean["signals"]).std().item() == pytest.approx(0.05, rel=0.1)


@pytest.mark.parametrize("steps, accumulate", [(4, 1), (2, 3)])
def test_a_resumed_stream_continues_where_the_checkpoint_left_it(steps, accumulate):
    # the state a checkpoint saves after `steps` optimiser steps of `accumulate` batches each, loaded into a
    # fresh data module: its stream goes on with the batches the uninterrupted one draws next
    a = make(seed=4)
    assert a.state_dict() == {}  # outside a Trainer there is no position to save
    a.trainer = SimpleNamespace(global_step=steps, accumulate_grad_batches=accumulate, global_rank=0)
    taken = steps * accumulate
    assert taken > a.train_windows.batches_per_pass  # resumed in a later pass than the first
    uninterrupted = list(islice(iter(a.train_dataloader()), taken + 3))
    b = make(seed=4)
    b.load_state_dict(a.state_dict())
    resumed = list(islice(iter(b.train_dataloader()), 3))
    for want, got in zip(uninterrupted[taken:], resumed):
        assert torch.equal(got["index"], want["index"]) and torch.equal(got["signals"], want["signals"])
    assert not torch.equal(resumed[0]["signals"], uninterrupted[0]["signals"])


@pytest.mark.parametrize("cached", [False, True])
def test_simulating_the_data_leaves_torchs_thread_count_as_the_run_set_it(tmp_path, cached):
    """The simulation's parallel kernel shares an OpenMP runtime with torch; a run that pins one thread must
    still train on one thread after simulating (cold cache) as after loading (warm cache)."""
    if cached:
        QuarterCarDataModule(SPEC, window=100, batch_size=8, cache_dir=tmp_path).prepare_data()
    torch.set_num_threads(1)  # the autouse fixture in conftest.py restores the count after the test
    dm = QuarterCarDataModule(SPEC, window=100, batch_size=8, cache_dir=tmp_path)
    dm.prepare_data()
    dm.setup("fit")
    assert torch.get_num_threads() == 1
