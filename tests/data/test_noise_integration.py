"""Noise where a sensor puts it: integrated from t0 with the signals (or each window on its own), and the
band-passed signals of the seat equation that the filtered hybrid objective reads."""

import numpy as np
import pytest

from hybrid_sysid.data import DatasetSpec
from hybrid_sysid.data.datamodule import QuarterCarDataModule, start_state
from hybrid_sysid.data.splits import SPLITS
from hybrid_sysid.physics import integrate, integrate_trapezoid, relative_states
from hybrid_sysid.physics.filters import bandpass_taps, fir_valid

SPEC = DatasetSpec(n_roads=6, n_masses=4, n_steps=600, seed=2)
CONTINUOUS = DatasetSpec(n_roads=6, n_masses=4, n_steps=600, seed=2, measurement="continuous")
FIR = bandpass_taps(4.0, 20.0, 151, SPEC.dt)


def make(integration="t0", fir=FIR, spec=SPEC, **kw):
    dm = QuarterCarDataModule(spec, window=300, batch_size=8, seed=0, integration=integration, fir=fir, **kw)
    dm.setup()
    return dm


def test_start_state_has_the_covariance_of_integrated_white_noise():
    """Reference: the integrator run over explicit noise before the window (Monte Carlo, 40000 draws)."""
    dt, s, n = SPEC.dt, 150, 40000
    rng = np.random.default_rng(0)
    noise = rng.standard_normal((n, 2, s + 1))
    vel, pos = integrate(noise[:, 0] - noise[:, 1], dt)
    want = np.stack([vel[:, s], pos[:, s - 1]], axis=1)  # V before step s, X one step before
    got = start_state(np.full(n, s), dt, rng.standard_normal((n, 2)))
    np.testing.assert_allclose(np.cov(got.T), np.cov(want.T), rtol=0.05)
    assert not start_state(np.zeros(3, dtype=int), dt, np.ones((3, 2))).any()  # nothing before t0


@pytest.mark.parametrize("s", [1, 2, 150])
def test_trapezoid_start_state_has_the_covariance_of_integrated_white_noise(s):
    """Reference: the trapezoid rule run over explicit noise up to the window's first sample (Monte Carlo,
    40000 draws). Its states at s are the drawn (V, X) plus (dt / 2, dt^2 / 4) times the first sample's noise."""
    dt, n = CONTINUOUS.dt, 40000
    rng = np.random.default_rng(s)
    noise = rng.standard_normal((n, 2, s + 1))
    d = noise[:, 0] - noise[:, 1]
    vel, pos = integrate_trapezoid(d, dt)
    first = d[:, s]
    # the first sample's share of the states at s: what a unit more of it changes there
    more_v, more_x = integrate_trapezoid(d + (np.arange(s + 1) == s), dt)
    np.testing.assert_allclose(more_v[:, s] - vel[:, s], dt / 2, rtol=1e-9)
    np.testing.assert_allclose(more_x[:, s] - pos[:, s], dt**2 / 4, rtol=1e-6)
    want = np.stack([vel[:, s] - dt / 2 * first, pos[:, s] - dt**2 / 4 * first], axis=1)
    got = start_state(np.full(n, s), dt, rng.standard_normal((n, 2)), "trapezoid")
    np.testing.assert_allclose(np.cov(got.T), np.cov(want.T), rtol=0.05)
    assert not start_state(np.zeros(3, dtype=int), dt, np.ones((3, 2)), "trapezoid").any()


def test_continuous_noise_carries_the_trapezoid_rules_state():
    """Measurement "continuous", integration t0: noisy minus clean regressors = the window's own noise integrated
    from zero (the recording's rule) plus the states at the window's first sample: a constant v_s in rel_vel and
    x_s + k dt v_s in rel_disp (k = 0 at that sample)."""
    dm = make(fir=None, spec=CONTINUOUS)
    for clean, noisy in (
        (dm.eval_batch("test", 0.0), dm.eval_batch("test", 0.05)),
        (dm.eval_batch("test", 0.0, windows=4), dm.eval_batch("test", 0.05, windows=4)),
    ):
        noise = (noisy["signals"] - clean["signals"]).numpy().astype(np.float64)
        own_v, own_d = relative_states(noise[:, 0], noise[:, 1], CONTINUOUS.dt, "continuous")
        off_v = (noisy["rel_vel"] - clean["rel_vel"]).numpy() - own_v
        off_d = (noisy["rel_disp"] - clean["rel_disp"]).numpy() - own_d
        v_s = off_v[:, :1]
        np.testing.assert_allclose(off_v, np.broadcast_to(v_s, off_v.shape), atol=1e-6)
        x_s = off_d - CONTINUOUS.dt * np.arange(300) * v_s
        np.testing.assert_allclose(x_s, np.broadcast_to(x_s[:, :1], x_s.shape), atol=1e-6)
        assert (np.abs(v_s) > 0).all()


def test_continuous_k_windows_are_the_series_long_integration_in_their_interior():
    """Reference: the recording's whole noise series (drawn as the data module draws it) re-integrated from t0
    by relative_states, the recording's own rule, gain correction included. In a window's interior the velocity
    agrees to float32 rounding; the displacement once its constant takes the correction's dt^2 (d_s + d_{s+1} -
    d_0 - d_1) / 24 (the series corrects sample s with d_{s-1}, the window cannot)."""
    dm = make(fir=None, spec=CONTINUOUS)
    k, std, w, dt = 8, 0.05, 300, CONTINUOUS.dt
    clean, noisy = dm.eval_batch("test", 0.0, windows=k), dm.eval_batch("test", std, windows=k)
    rows = dm.rows("test")
    series = np.random.default_rng([dm.seed, SPLITS.index("test"), 300]).standard_normal(
        (len(rows), 2, CONTINUOUS.n_steps), dtype=np.float32
    )
    series = std * series.astype(np.float64)
    ref_v, ref_d = relative_states(series[:, 0], series[:, 1], dt, "continuous")
    d = series[:, 0] - series[:, 1]
    noise = (noisy["signals"] - clean["signals"]).numpy()
    dv = (noisy["rel_vel"] - clean["rel_vel"]).numpy()
    dd = (noisy["rel_disp"] - clean["rel_disp"]).numpy()
    seat = clean["signals"][:, 0].numpy()
    starts = set()
    for b in range(len(seat)):
        i = b // k
        recording = np.lib.stride_tricks.sliding_window_view(dm.dataset.seat_acc[rows[i]], w)
        (s,) = np.flatnonzero((recording == seat[b]).all(axis=1))
        starts.add(int(s))
        np.testing.assert_allclose(noise[b], series[i, :, s : s + w], rtol=0, atol=1e-6)  # the series drawn
        np.testing.assert_allclose(dv[b, 1:-1], ref_v[i, s + 1 : s + w - 1], rtol=0, atol=1e-8)
        shift = dt**2 / 24 * (d[i, s] + d[i, s + 1] - d[i, 0] - d[i, 1])
        np.testing.assert_allclose(dd[b, 2:-2], ref_d[i, s + 2 : s + w - 2] + shift, rtol=0, atol=1e-8)
    assert len(starts) > 3 * k


def test_noise_in_the_regressors_carries_the_state_it_had_reached():
    """Integration t0: noisy minus clean regressors = the window's own noise integrated from zero plus a constant
    (rel_vel) and a ramp of slope dt * that constant (rel_disp): the noise before the window, never zero."""
    dm = make()
    clean, noisy = dm.eval_batch("test", 0.0), dm.eval_batch("test", 0.05)
    noise = (noisy["signals"] - clean["signals"]).numpy().astype(np.float64)
    own_v, own_d = relative_states(noise[:, 0], noise[:, 1], SPEC.dt)
    off_v = (noisy["rel_vel"] - clean["rel_vel"]).numpy() - own_v
    off_d = (noisy["rel_disp"] - clean["rel_disp"]).numpy() - own_d
    v0 = off_v[:, :1]
    np.testing.assert_allclose(off_v, np.broadcast_to(v0, off_v.shape), atol=1e-6)
    k = np.arange(1, 301)
    ramp = off_d - SPEC.dt * k * v0
    np.testing.assert_allclose(ramp, np.broadcast_to(ramp[:, :1], ramp.shape), atol=1e-6)
    assert (np.abs(v0) > 0).all()


def test_k_windows_take_their_start_state_from_the_recordings_noise_series():
    """K > 1: two windows of one recording carry states of ONE noise series: where they overlap, their noisy
    regressors differ from the clean ones by the same amount."""
    dm = make()
    k = 8
    clean, noisy = dm.eval_batch("test", 0.0, windows=k), dm.eval_batch("test", 0.05, windows=k)
    dv = (noisy["rel_vel"] - clean["rel_vel"]).numpy().reshape(-1, k, 300)
    starts = [
        [
            int(np.flatnonzero((dm.dataset.seat_acc[r] == s[0]))[0])
            for s in clean["signals"][i * k : (i + 1) * k, 0].numpy()
        ]
        for i, r in enumerate(dm.rows("test"))
    ]
    checked = 0
    for i, st in enumerate(starts):
        for a in range(k):
            for b in range(a + 1, k):
                lag = st[b] - st[a]
                if 0 < lag < 300:
                    np.testing.assert_allclose(dv[i, a, lag:], dv[i, b, : 300 - lag], atol=1e-5)
                    checked += 1
    assert checked > 0


@pytest.mark.parametrize("integration", ["t0", "window"])
def test_filtered_signals_are_the_band_pass_of_the_batchs_own_signals(integration):
    """Reference: numpy's FFT convolution (fir_valid) of the batch's full-window seat z'', rel_vel, rel_disp.
    The filter removes the states at the window's start, so both integrations give the same filtered signals."""
    dm = make(integration)
    for batch in (
        dm.eval_batch("test", 0.0),
        dm.eval_batch("test", 0.03),
        next(iter(make(integration, train_std=0.03).train_dataloader())),
    ):
        sources = (batch["signals"][:, 0], batch["rel_vel"], batch["rel_disp"])
        for key, source in zip(("seat_f", "rel_vel_f", "rel_disp_f"), sources):
            want = fir_valid(source.numpy().astype(np.float64), FIR)
            got = batch[key].numpy()
            assert got.shape == (len(source), 300 - 150)
            np.testing.assert_allclose(got, want, rtol=0, atol=2e-4 * np.abs(want).max())
    other = make("window" if integration == "t0" else "t0").eval_batch("test", 0.03)
    for key in ("seat_f", "rel_vel_f", "rel_disp_f"):
        np.testing.assert_allclose(
            other[key].numpy(),
            dm.eval_batch("test", 0.03)[key].numpy(),
            rtol=0,
            atol=1e-4 * other[key].abs().max().item(),
        )


def test_window_integration_starts_every_window_from_zero():
    dm = make("window", fir=None)
    batch = dm.eval_batch("test", 0.02)
    acc = batch["signals"].numpy().astype(np.float64)
    vel, disp = relative_states(acc[:, 0], acc[:, 1], SPEC.dt)
    np.testing.assert_allclose(batch["rel_vel"].numpy(), vel, atol=1e-6)
    np.testing.assert_allclose(batch["rel_disp"].numpy(), disp, atol=1e-7)


def test_validation_windows_carry_the_training_noise():
    for std in (0.0, 0.02):
        dm = make(train_std=std)
        val = next(iter(dm.val_dataloader()))
        clean = dm.eval_batch("val", 0.0)
        noise = (val["signals"] - clean["signals"]).numpy()
        assert noise.std() == pytest.approx(std, rel=0.1, abs=1e-12)


def test_bad_integration_is_refused():
    with pytest.raises(ValueError, match=r"^integration = 'x' is not allowed: one of t0, window"):
        QuarterCarDataModule(SPEC, window=300, integration="x")
