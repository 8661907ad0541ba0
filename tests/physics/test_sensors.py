"""physics.sensors: the sensor faults against independent references (scipy.signal, shifted arrays, the analytic
shift of a band-limited signal), their draws, their refusals, and the compiled twin against the numpy path."""

import numpy as np
import pytest
import scipy.signal

from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.physics.compiled_sensors import apply_faults
from hybrid_sysid.physics.sensors import FaultDraws, SensorFaults, apply, fractional_delay, lowpass

DT = 0.005


def sines(t, top_cycles, seed=0, n=40):
    """A band-limited test signal at times t (samples): n sines of random phase below ``top_cycles`` per sample."""
    rng = np.random.default_rng(seed)
    freq, phase = rng.uniform(0, top_cycles, n), rng.uniform(0, 2 * np.pi, n)
    return np.sin(2 * np.pi * freq[:, None] * np.asarray(t, dtype=float)[None, :] + phase[:, None]).sum(axis=0)


def test_lowpass_is_scipys_butterworth_row_by_row():
    rng = np.random.default_rng(1)
    x = rng.standard_normal((5, 700))
    cutoffs = np.array([3.0, 12.5, 20.0, 40.0, 90.0])  # up to near Nyquist (100 Hz)
    out = lowpass(x, cutoffs, DT)
    for row, fc, got in zip(x, cutoffs, out):
        b, a = scipy.signal.butter(2, fc, fs=1 / DT)
        want = scipy.signal.lfilter(b, a, row)
        assert np.max(np.abs(got - want)) < 1e-12 * np.max(np.abs(want))


@pytest.mark.parametrize("f", [1.0, 5.0, 15.0])
def test_lowpass_is_the_analogue_filter_at_the_prewarped_frequencies(f):
    # the bilinear transform maps f to (2 / dt) tan(pi f dt) rad/s of the analogue Butterworth whose cut-off is
    # pre-warped the same way: the recorded sine's gain and phase lag are that filter's there
    fc = 30.0
    t = np.arange(4000) * DT
    out = lowpass(np.sin(2 * np.pi * f * t)[None], fc, DT)[0]
    late = slice(2000, None)  # after the start-up transient; a whole number of periods
    measured = 2j * np.mean(out[late] * np.exp(-2j * np.pi * f * t[late]))  # H, as out = Im(H e^{j w t})
    warp = lambda hz: 2 / DT * np.tan(np.pi * hz * DT)  # noqa: E731
    b, a = scipy.signal.butter(2, warp(fc), analog=True)
    want = scipy.signal.freqs(b, a, [warp(f)])[1][0]
    assert abs(measured - want) < 1e-6
    if f == 1.0:  # well below the cut-off the lag is a delay of about sqrt(2) / (2 pi fc) seconds
        assert -np.angle(measured) / (2 * np.pi * f) == pytest.approx(np.sqrt(2) / warp(fc), rel=1e-3)


@pytest.mark.parametrize("delay", [0, 3, -2, 7])
def test_an_integer_delay_is_the_shifted_array(delay):
    x = np.random.default_rng(2).standard_normal((3, 200))
    out = fractional_delay(x, np.full(3, float(delay)))
    shifted = np.roll(x, delay, axis=1)
    inner = slice(max(delay, 0), 200 + min(delay, 0))  # where np.roll did not wrap around
    np.testing.assert_array_equal(out[:, inner], shifted[:, inner])


def test_a_fractional_delay_is_the_analytic_shift_of_a_band_limited_signal():
    t = np.arange(3000)
    delays = np.array([0.37, -1.5, 2.25, -0.49, 9.8])
    x = np.tile(sines(t, 0.2), (len(delays), 1))  # below 0.4 of the Nyquist frequency
    exact = np.stack([sines(t - d, 0.2) for d in delays])  # out[k] = x(k - d): d > 0 is late
    for half_width, tolerance in ((32, 1e-12), (16, 1e-10), (12, 1e-7)):
        edge = half_width + 10  # the samples that read beyond the array: half_width + ceil(|d|)
        got = fractional_delay(x, delays, half_width)
        err = np.max(np.abs(got - exact)[:, edge:-edge]) / np.max(np.abs(exact))
        assert err < tolerance, (half_width, err)


def test_draws_are_in_range_and_one_fault_does_not_move_anothers():
    n = 500
    faults = SensorFaults(gain_spread=0.03, skew_max=0.01, lowpass_range_hz=(20.0, 40.0))
    d = faults.draw(n, np.random.default_rng(5))
    assert d.gains.shape == (n, 2) and d.skews.shape == (n,) and d.cutoffs.shape == (n, 2)
    assert np.all(np.abs(d.gains - 1) <= 0.03) and np.ptp(d.gains) > 0.05
    assert np.all(np.abs(d.skews) <= 0.01) and np.ptp(d.skews) > 0.018
    assert np.all((d.cutoffs >= 20) & (d.cutoffs <= 40)) and np.ptp(d.cutoffs) > 19
    gain_only = SensorFaults(gain_spread=0.03).draw(n, np.random.default_rng(5))
    np.testing.assert_array_equal(gain_only.gains, d.gains)
    assert gain_only.cutoffs is None and np.all(gain_only.skews == 0)
    fixed = SensorFaults(lowpass_hz=(25.0, 35.0)).draw(3, np.random.default_rng(5))
    np.testing.assert_array_equal(fixed.cutoffs, [[25.0, 35.0]] * 3)
    assert np.all(fixed.gains == 1.0)


def test_apply_is_lowpass_then_gain_then_the_bodys_delay():
    rng = np.random.default_rng(3)
    seat, body = rng.standard_normal((2, 4, 600))
    draws = FaultDraws(rng.uniform(0.97, 1.03, (4, 2)), rng.uniform(-0.01, 0.01, 4), rng.uniform(20, 40, (4, 2)))
    got_seat, got_body = apply(seat, body, draws, DT)
    for i in range(4):
        filt = [
            scipy.signal.lfilter(*scipy.signal.butter(2, draws.cutoffs[i, j], fs=1 / DT), x[i])
            for j, x in enumerate((seat, body))
        ]
        np.testing.assert_allclose(got_seat[i], draws.gains[i, 0] * filt[0], rtol=0, atol=1e-12)
        want = fractional_delay(draws.gains[i, 1] * filt[1][None], draws.skews[i : i + 1] / DT)[0]
        np.testing.assert_allclose(got_body[i], want, rtol=0, atol=1e-12)


def test_the_compiled_faults_equal_the_numpy_ones_bit_for_bit():
    rng = np.random.default_rng(4)
    seat, body = rng.standard_normal((2, 37, 300))
    for faults in (
        SensorFaults(gain_spread=0.03, skew_max=0.01, lowpass_range_hz=(20.0, 40.0)),
        SensorFaults(skew_max=0.02),
        SensorFaults(lowpass_hz=(10.0, 30.0)),
    ):
        draws = faults.draw(37, np.random.default_rng(6))
        for half_width in (12, 32):
            for want, got in zip(
                apply(seat, body, draws, DT, half_width), apply_faults(seat, body, draws, DT, half_width)
            ):
                np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize(
    "faults, window, key, words",
    [
        (SensorFaults(gain_spread=-0.1), None, "sensor.gain_spread", "[0, 1)"),
        (SensorFaults(gain_spread=1.0), None, "sensor.gain_spread", "[0, 1)"),
        (SensorFaults(skew_max=-0.001), None, "sensor.skew_max", ">= 0"),
        (SensorFaults(skew_max=2.5), 500, "sensor.skew_max", "beyond the window"),
        (SensorFaults(lowpass_hz=(20.0, 100.0)), None, "sensor.lowpass_hz", "Nyquist"),
        (SensorFaults(lowpass_hz=(0.0, 30.0)), None, "sensor.lowpass_hz", "(0, 100)"),
        (SensorFaults(lowpass_range_hz=(40.0, 20.0)), None, "sensor.lowpass_range_hz", "lo <= hi"),
        (SensorFaults(lowpass_hz=(20.0, 30.0), lowpass_range_hz=(20.0, 40.0)), None, "sensor.lowpass_range_hz", "null"),
    ],
)
def test_bad_values_are_one_line_errors_naming_the_key(faults, window, key, words):
    with pytest.raises(ConfigError) as info:
        faults.validate(DT, window)
    text = str(info.value)
    assert info.value.key == key and text.startswith(key) and words in text and "\n" not in text


def test_off_by_default_and_a_config_list_is_one_key():
    assert not SensorFaults().active
    assert SensorFaults(skew_max=0.001).active and SensorFaults(lowpass_hz=[20, 30]).active
    assert SensorFaults(lowpass_hz=[20, 30]) == SensorFaults(lowpass_hz=(20.0, 30.0))
    SensorFaults(skew_max=2.49).validate(DT, 500)  # just inside the window
