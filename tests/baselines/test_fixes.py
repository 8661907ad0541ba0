"""baselines.fixes: each fault's one-parameter fix recovers the true p of the seat equation on clean windows where
the plain band-passed fit is biased by the fault (the truth: the car's C3 / m3, K3 / m3)."""

import numpy as np
import pytest

from hybrid_sysid.baselines.fixes import fit_gain, lstsq_columns
from hybrid_sysid.physics import QuarterCar, road_profiles, simulate
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.physics.seat_fit import fit_windows

DT, N, W = 0.005, 1200, 500


@pytest.fixture(scope="module")
def recordings():
    m3 = np.array([60.0, 110.0, 180.0])
    seat, body = simulate(road_profiles(["C", "D", "E"], N, DT, 15.0, rng=5), m3, DT, measurement="consistent")
    truth = np.stack(QuarterCar().parameters(m3), axis=1)
    return seat, body, truth


def windows(x, start=300):
    return x[:, start : start + W]


def test_lstsq_columns_is_numpys_lstsq_after_the_filter():
    rng = np.random.default_rng(0)
    cols = [rng.standard_normal((2, 400)).cumsum(axis=1) for _ in range(3)]
    y = 2.0 * cols[0] - 0.5 * cols[1] + 0.1 * rng.standard_normal((2, 400))
    fir = bandpass_taps(4.0, 20.0, 51, DT)
    got = lstsq_columns(cols, y, fir)
    for i in range(2):
        a = np.stack([np.convolve(c[i], fir, "valid") for c in cols], axis=1)
        ref = np.linalg.lstsq(a, np.convolve(y[i], fir, "valid"), rcond=None)[0]
        assert got[i] == pytest.approx(ref, rel=1e-8)


def test_the_gain_fix_recovers_p_that_unequal_gains_bias(recordings):
    seat, body, truth = recordings
    fir = bandpass_taps(4.0, 20.0, 151, DT)
    seat_g, body_g = 1.03 * windows(seat), 0.97 * windows(body)
    plain = fit_windows(seat_g, body_g, DT, "consistent", fir).p
    fixed = fit_gain(seat_g, body_g, DT, "consistent", fir)
    assert np.abs(plain / truth - 1).max() > 5e-3  # the fault is visible to the plain fit
    assert fixed == pytest.approx(truth, rel=1e-5)


def test_the_baseline_estimates_a_recording_with_its_fix_and_refuses_a_fix_it_cannot_apply(recordings):
    from hybrid_sysid.baselines import LeastSquaresFit
    from hybrid_sysid.core.checks import ConfigError

    seat, body, truth = recordings
    ls = LeastSquaresFit(span="window", filter="bandpass", dt=DT, fix="gain")
    got = ls.estimate(1.03 * seat[1], 0.97 * body[1], DT, "consistent", window=W, windows=3)
    assert got == pytest.approx(np.tile(truth[1], (3, 1)), rel=1e-4)  # the edges integrate from each window's start
    with pytest.raises(ConfigError, match="fix"):
        LeastSquaresFit(span="series", filter="bandpass", dt=DT, fix="gain")
    with pytest.raises(ConfigError, match="fix"):
        LeastSquaresFit(span="window", filter="bandpass", dt=DT, fix="drift")


def test_the_skew_fix_recovers_p_that_a_body_sensor_offset_biases(recordings):
    from hybrid_sysid.baselines.fixes import fit_skew
    from hybrid_sysid.physics.sensors import fractional_delay

    seat, body, truth = recordings
    fir = bandpass_taps(4.0, 20.0, 151, DT)
    late = fractional_delay(body, np.array([1.6, -1.3, 0.7]))  # 8, -6.5 and 3.5 ms of offset, recording-long
    plain = fit_windows(windows(seat), windows(late), DT, "consistent", fir).p
    fixed = fit_skew(windows(seat), windows(late), DT, "consistent", fir, skew_max=0.02)
    assert np.abs(plain / truth - 1).max() > 0.02
    # the grid of 21 offsets over +-20 ms is 2 ms apart; the parabola's vertex lands within a fraction of that
    assert np.abs(fixed / truth - 1).max() < 2e-3


def test_the_skew_search_delays_equal_the_faults_own_interpolator():
    from hybrid_sysid.baselines.fixes import delayed_copies
    from hybrid_sysid.physics.sensors import fractional_delay

    x = np.random.default_rng(3).standard_normal((4, 300)).cumsum(axis=1)  # a drifting edge, unlike the middle
    delays = np.array([-4.6, -2.0, -0.3, 0.0, 0.5, 3.7])
    for delay, got in zip(delays, delayed_copies(x, delays, half_width=16), strict=True):
        want = fractional_delay(x, np.full(len(x), delay), half_width=16)
        assert np.abs(got - want).max() < 1e-12 * np.abs(want).max()


def test_the_hardening_fix_recovers_the_small_amplitude_stiffness():
    from hybrid_sysid.baselines.fixes import fit_hardening
    from hybrid_sysid.physics import relative_states

    m3 = np.array([60.0, 180.0])
    car = QuarterCar(seat_hardening=35000.0)
    road = road_profiles(["E", "E"], N, DT, 15.0, rng=7)  # the roughest roads: the largest strokes
    seat, body = simulate(road, m3, DT, car=car, measurement="consistent")
    rel_vel, rel_disp = relative_states(seat, body, DT, "consistent")
    truth = np.stack(car.parameters(m3), axis=1)
    fir = bandpass_taps(4.0, 20.0, 151, DT)
    plain = fit_windows(windows(seat), windows(body), DT, "consistent", fir).p
    fixed = fit_hardening(*(windows(x) for x in (seat, rel_vel, rel_disp)), fir)
    assert (plain[:, 1] / truth[:, 1] - 1).min() > 0.02  # a stiffer spring than K3: p2 read too high
    # the cube of the window's detrended displacement stands in for the true stroke's: close, not exact
    assert np.abs(fixed / truth - 1).max() < 0.25 * np.abs(plain / truth - 1).max()
