"""noise.train_std_max: each training window's noise std log-uniform in [train_std, train_std_max], validation at
their geometric mean; without it the batches are those of the stream as it was drawn before the key existed."""

import math

import numpy as np
import pytest
from scipy import stats

from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.datamodule import QuarterCarDataModule
from hybrid_sysid.data.spec import BatchSettings
from hybrid_sysid.data.windows import start_state

SPEC = DatasetSpec(n_roads=6, n_masses=5, n_steps=400, seed=1)
LO, HI = 0.003, 0.1


def make(**kwargs):
    dm = QuarterCarDataModule(SPEC, window=100, batch_size=8, seed=4, **kwargs)
    dm.setup("fit")
    return dm


def stream_before_the_key(data, rows, batch_size, seed, noise_std, e):
    """RandomWindows.one_pass as it was written before noise.train_std_max: the reference of bit-identity."""
    rng = np.random.default_rng([seed, 1000 + e])
    order = rng.permutation(rows)
    starts = rng.integers(0, data.n_steps - data.window + 1, size=len(order))
    for b in range(-(-len(rows) // batch_size)):
        sl = slice(b * batch_size, (b + 1) * batch_size)
        noise_rng = np.random.default_rng([seed, 2000 + e, b])
        noise = noise_std * noise_rng.standard_normal((len(order[sl]), 2, data.window))
        state = noise_std * start_state(starts[sl], data.dt, noise_rng.standard_normal((len(order[sl]), 2)), data.rule)
        yield data.batch(order[sl], starts[sl], noise, state)


def test_without_the_key_the_batches_are_those_drawn_before_it():
    dm = make(train_std=0.01)
    s = dm.train_windows
    for e in (0, 1):
        for new, old in zip(s.one_pass(e), stream_before_the_key(s.data, s.rows, 8, 4, 0.01, e)):
            assert new.keys() == old.keys()
            assert all(np.array_equal(new[k].numpy(), old[k].numpy()) for k in new)
    assert dm.batch_settings.val_std == 0.01


def test_each_window_draws_its_std_log_uniformly_in_the_range():
    fixed, ranged = make(train_std=LO), make(train_std=LO, train_std_max=HI)
    stds = []
    for e in range(40):
        rng = np.random.default_rng([4, 1000 + e])  # the pass's order and starts, as the stream draws them
        order = rng.permutation(fixed.train_windows.rows)
        starts = rng.integers(0, SPEC.n_steps - 100 + 1, size=len(order))
        for j, (a, b) in enumerate(zip(fixed.train_windows.one_pass(e), ranged.train_windows.one_pass(e))):
            assert np.array_equal(a["index"], b["index"])  # the same windows: order and starts are untouched
            rows, st = order[j * 8 : (j + 1) * 8], starts[j * 8 : (j + 1) * 8]
            clean = np.stack([fixed.dataset.seat_acc[r, s : s + 100] for r, s in zip(rows, st)]).astype(np.float64)
            na, nb = (x["signals"][:, 0].numpy() - clean for x in (a, b))
            # the same standard normals, scaled by each window's own std instead of train_std
            slope = (na * nb).sum(axis=1) / (na * na).sum(axis=1)
            assert np.abs(nb - slope[:, None] * na).max() < 2e-5  # float32 rounding of the signals, times the slope
            stds.append(slope * LO)
    stds = np.concatenate(stds)
    assert len(stds) > 300 and (stds >= LO * 0.999).all() and (stds <= HI * 1.001).all()
    u = (np.log(stds) - math.log(LO)) / (math.log(HI) - math.log(LO))
    assert stats.kstest(u, "uniform").pvalue > 0.01  # log-uniform
    assert stats.kstest((stds - LO) / (HI - LO), "uniform").pvalue < 1e-6  # and not uniform in the std itself


def test_validation_windows_carry_the_geometric_mean():
    dm = make(train_std=LO, train_std_max=HI)
    assert dm.batch_settings.val_std == pytest.approx(math.sqrt(LO * HI))
    first = next(iter(dm.val_dataloader()))
    expected = dm.eval_batch("val", math.sqrt(LO * HI))
    assert np.array_equal(first["signals"].numpy(), expected["signals"][: len(first["signals"])].numpy())


@pytest.mark.parametrize(
    "train_std, train_std_max, words",
    [
        (0.01, 0.01, "train_std_max = 0.01 is not allowed: must lie in (0.01, "),
        (0.01, 0.005, "train_std_max = 0.005 is not allowed: must lie in (0.01, "),
        (0.0, 0.1, "train_std_max = 0.1 is not allowed: null unless train_std > 0"),
        (0.01, math.inf, "train_std_max = inf is not allowed"),
        (0.01, math.nan, "train_std_max = nan is not allowed"),
    ],
)
def test_a_bad_range_is_one_line_naming_the_key(train_std, train_std_max, words):
    with pytest.raises(ConfigError) as err:
        BatchSettings(8, train_std, train_std_max).validate()
    assert str(err.value).startswith(words) and "\n" not in str(err.value)


def test_the_config_places_it_under_noise(make_cfg):
    from hybrid_sysid.config.validation import validate

    with pytest.raises(ConfigError, match=r"^noise\.train_std_max = 0\.005 is not allowed: must lie in \(0\.01, "):
        validate(make_cfg("data=tiny", "noise.train_std=0.01", "noise.train_std_max=0.005"))
    assert make_cfg("data=tiny").noise.train_std_max is None
