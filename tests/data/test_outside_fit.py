"""The fit over the samples of a recording outside each window (objective=cross_segment's target): against numpy's
least squares on the masked, np.convolve-filtered samples; its mask excludes exactly the window's support; a
recording too short to leave a segment is one line naming the keys."""

import numpy as np
import pytest

from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.datamodule import QuarterCarDataModule
from hybrid_sysid.data.outside import OutsideFit
from hybrid_sysid.data.spec import MIN_FILTERED, outside_samples
from hybrid_sysid.physics import relative_states
from hybrid_sysid.physics.filters import bandpass_taps

SPEC = DatasetSpec(n_roads=6, n_masses=4, n_steps=800, seed=2, seat_spread=0.3)
W, TAPS = 200, 101
FIR = bandpass_taps(4.0, 20.0, TAPS, SPEC.dt)


def make(**kwargs):
    dm = QuarterCarDataModule(SPEC, window=W, batch_size=8, seed=3, outside_fir=FIR, **kwargs)
    dm.setup("fit")
    return dm


@pytest.fixture(scope="module")
def dm():
    return make(train_std=0.01, train_std_max=0.05)


def reference(seat, body, start):
    """p and its relative standard errors by numpy's lstsq and the textbook formula, over the np.convolve-filtered
    samples whose support (inputs j .. j + taps - 1) shares no sample with the window, found by set intersection."""
    rel_vel, rel_disp = relative_states(seat, body, SPEC.dt, SPEC.measurement)
    y, v, d = (np.convolve(x, FIR, mode="valid") for x in (seat, rel_vel, rel_disp))
    window = set(range(start, start + W))
    keep = np.array([not window & set(range(j, j + TAPS)) for j in range(len(y))])
    a = np.stack([-v[keep], -d[keep]], axis=1)
    p, *_ = np.linalg.lstsq(a, y[keep], rcond=None)
    s2 = np.sum((y[keep] - a @ p) ** 2) / (keep.sum() - 2)
    return p, np.sqrt(s2 * np.diag(np.linalg.inv(a.T @ a))) / np.abs(p)


def test_training_batches_carry_the_outside_fit_of_each_rows_noise(dm):
    stream = dm.train_windows
    batch = next(iter(stream.one_pass(0)))
    rng = np.random.default_rng([3, 1000])  # the pass's order and starts
    order = rng.permutation(stream.rows)
    starts = rng.integers(0, SPEC.n_steps - W + 1, size=len(order))[:8]
    assert np.array_equal(batch["index"].numpy(), order[:8])
    # each row's std from its window: the noise there is that std times the batch's window draw
    clean = np.stack([dm.dataset.seat_acc[r, s : s + W] for r, s in zip(order[:8], starts)])
    draw = np.random.default_rng([3, 2000, 0]).standard_normal((8, 2, W))
    stds = np.median((batch["signals"][:, 0].numpy().astype(np.float64) - clean) / draw[:, 0], axis=1)
    assert ((stds > 0.01) & (stds < 0.05)).all() and np.ptp(stds) > 0.005
    normals = np.random.default_rng([3, 3000, 0]).standard_normal((8, 2, SPEC.n_steps))
    for i, (row, start) in enumerate(zip(order[:8], starts)):
        seat = dm.dataset.seat_acc[row].astype(np.float64) + stds[i] * normals[i, 0]
        body = dm.dataset.body_acc[row].astype(np.float64) + stds[i] * normals[i, 1]
        p, se = reference(seat, body, start)
        np.testing.assert_allclose(batch["p_out"][i].numpy(), p, rtol=1e-5)
        np.testing.assert_allclose(batch["se_out"][i].numpy(), se, rtol=1e-4)


def test_evaluation_batches_carry_it_too_clean_it_is_the_true_p(dm):
    clean = dm.eval_batch("val", 0.0)
    # clean, consistent recordings: only the float32 rounding of the stored signals is left
    np.testing.assert_allclose(clean["p_out"].numpy(), dm.dataset.params[clean["index"].numpy()], rtol=1e-4)
    noisy = dm.eval_batch("val", 0.02)
    starts = [
        next(s for s in range(SPEC.n_steps - W + 1) if np.array_equal(dm.dataset.rel_vel[r, s : s + W], v))
        for r, v in zip(clean["index"].numpy(), clean["rel_vel"].numpy())
    ]
    g = np.random.default_rng([3, 1, 3000])  # the seed and the split's code (val: 1)
    normals = g.standard_normal((len(starts), 2, SPEC.n_steps), dtype=np.float32)
    for i in (0, len(starts) - 1):
        row = clean["index"][i].item()
        seat = dm.dataset.seat_acc[row].astype(np.float64) + 0.02 * normals[i, 0]
        body = dm.dataset.body_acc[row].astype(np.float64) + 0.02 * normals[i, 1]
        np.testing.assert_allclose(noisy["p_out"][i].numpy(), reference(seat, body, starts[i])[0], rtol=1e-5)
    # K windows of a recording fit with its one outside draw, each outside its own window
    k4 = dm.eval_batch("val", 0.02, limit=2, windows=4)
    assert k4["p_out"].shape == (8, 2) and np.array_equal(k4["p_out"][0].numpy(), noisy["p_out"][0].numpy())
    assert len(np.unique(k4["p_out"][:4, 0].numpy())) == 4


def test_the_fit_ignores_the_window_and_reads_everything_else():
    rng = np.random.default_rng(0)
    seat, body = rng.standard_normal((2, 1, 700)).astype(np.float32)
    fit = OutsideFit(seat, body, SPEC.dt, SPEC.measurement, W, FIR)
    start = 250
    base = fit.fit([0], [start])["p_out"].numpy()
    # the Blackman window's end taps are 0 (1e-34): the taps that count span taps - 2 samples, so a spike in
    # the sample just before or after the window reaches no kept sample, one sample further does (through taps
    # of 1e-6: a relative change of a few 1e-7)
    cases = [(start - 1, False), (start, False), (start + W - 1, False), (start + W, False)]
    for where, moves in cases + [(start - 2, True), (start + W + 1, True)]:
        s2, b2 = seat.copy(), body.copy()
        s2[0, where] += 5.0  # a spike in both channels: integrated, it shifts rel_vel and rel_disp from here on
        b2[0, where] -= 3.0
        p = OutsideFit(s2, b2, SPEC.dt, SPEC.measurement, W, FIR).fit([0], [start])["p_out"].numpy()
        change = np.abs(p / base - 1).max()
        assert change > 1e-8 if moves else change < 1e-11, (where, change)
    # the mask against set intersection, at the ends and in the middle
    for s in (0, 7, 250, 700 - W):
        window = set(range(s, s + W))
        expected = [not window & set(range(j, j + TAPS)) for j in range(700 - TAPS + 1)]
        assert np.array_equal(fit.mask([s])[0].astype(bool), expected)


def test_a_row_whose_fit_is_undefined_is_nan():
    seat = np.zeros((1, 700), dtype=np.float32)  # no motion: no regressor
    out = OutsideFit(seat, seat, SPEC.dt, SPEC.measurement, W, FIR).fit([0], [300])
    assert np.isnan(out["p_out"].numpy()).all() and np.isinf(out["se_out"].numpy()).all()


def test_the_fewest_outside_samples_is_that_of_the_worst_placed_window():
    for n_steps, window, taps in ((800, 200, 101), (500, 100, 151), (700, 400, 51)):
        fir = np.ones(taps)
        fit = OutsideFit(np.zeros((1, n_steps)), np.zeros((1, n_steps)), SPEC.dt, SPEC.measurement, window, fir)
        fewest = min(int(fit.mask([s]).sum()) for s in range(n_steps - window + 1))
        assert outside_samples(n_steps, window, taps) == fewest


def test_a_recording_too_short_to_leave_a_segment_is_one_line():
    need = W + 2 * (TAPS - 1) + 2 * (TAPS + MIN_FILTERED - 1)
    ok = DatasetSpec(n_roads=6, n_masses=4, n_steps=need, seed=2)
    QuarterCarDataModule(ok, window=W, outside_fir=FIR)  # at the limit: accepted
    short = DatasetSpec(n_roads=6, n_masses=4, n_steps=need - 1, seed=2)
    with pytest.raises(ConfigError) as err:
        QuarterCarDataModule(short, window=W, outside_fir=FIR)
    message = str(err.value)
    assert message.startswith(f"n_steps = {need - 1} is not allowed: must be >= data.window") and "\n" not in message
    assert "objective.filter.taps" in message and str(need) in message


def test_the_config_names_the_keys(make_cfg):
    from hybrid_sysid.config.validation import validate

    with pytest.raises(ConfigError) as err:
        validate(make_cfg("data=tiny", "objective=cross_segment"))
    message = str(err.value)
    assert message.startswith("data.n_steps = 400 is not allowed: must be >= data.window + 2 (objective.filter.taps")
    assert "\n" not in message
    validate(make_cfg("data=tiny", "objective=cross_segment", "data.window=100", "objective.filter.taps=61"))


@pytest.mark.parametrize("target", ["ls", "eiv"])
def test_recordings_of_several_lengths_padded_with_zeros_are_each_fitted_over_their_own_samples(dm, target):
    """A user's recordings of several lengths come zero-padded to the longest (data.recordings): each row's fit
    equals the fit of that recording alone, unpadded (numpy's lstsq for "ls"; a fit built on the short recordings
    alone for "eiv"), with and without noise."""
    lengths = np.array([800, 620, 800, 700, 620])
    seat = dm.dataset.seat_acc[:5].copy()
    body = dm.dataset.body_acc[:5].copy()
    for i, n in enumerate(lengths):
        seat[i, n:], body[i, n:] = 0.0, 0.0
    padded = OutsideFit(seat, body, SPEC.dt, SPEC.measurement, W, FIR, target, lengths=lengths)
    rows, starts = np.array([1, 0, 4, 3, 1]), np.array([30, 500, 420, 0, 211])
    normals = np.random.default_rng(5).standard_normal((5, 2, 800))
    for std in (0.0, 0.02):
        got = padded.fit(rows, starts, std, normals)
        for i, (row, start) in enumerate(zip(rows, starts)):
            n = lengths[row]
            s = seat[row : row + 1, :n].astype(np.float64) + std * normals[i : i + 1, 0, :n]
            b = body[row : row + 1, :n].astype(np.float64) + std * normals[i : i + 1, 1, :n]
            if target == "ls":
                p, se = reference(s[0], b[0], start)
            else:
                alone = OutsideFit(s, b, SPEC.dt, SPEC.measurement, W, FIR, target).fit([0], [start])
                p, se = alone["p_out"][0].numpy(), alone["se_out"][0].numpy()
            np.testing.assert_allclose(got["p_out"][i].numpy(), p, rtol=1e-7)
            np.testing.assert_allclose(got["se_out"][i].numpy(), se, rtol=1e-6)
    # padding read as samples would move the fit of a short recording: the unpadded fit differs from it
    blind = OutsideFit(seat, body, SPEC.dt, SPEC.measurement, W, FIR, target).fit([1], [30])["p_out"].numpy()
    assert np.abs(blind / padded.fit([1], [30])["p_out"].numpy() - 1).max() > 1e-3
