"""Road profiles against the paper's eq. 2-6 and the spectrum they imply."""

import numpy as np
import pytest

from hybrid_sysid.physics import road_profiles, wave_amplitudes, wave_numbers

# 1000 steps x 0.01 s x 10 m/s = 100 m = one period of w1 = 0.02 pi: every wave fits a whole number of times
PERIOD = dict(n_steps=1000, dt=0.01, speed=10.0)


def theory_variance(road_class):
    return np.sum(wave_amplitudes(road_class, 300) ** 2) / 2


def test_wave_numbers_follow_the_paper():
    w = wave_numbers(300)
    assert w[0] == pytest.approx(0.02 * np.pi)
    assert w[-1] == pytest.approx(6 * np.pi)
    np.testing.assert_allclose(np.diff(w), 0.02 * np.pi, rtol=1e-12)


def test_matches_eq2_evaluated_directly():
    classes = ["A", "C", "E"]
    road = road_profiles(classes, 500, 0.004, 15.0, rng=np.random.default_rng(7))
    phases = np.random.default_rng(7).uniform(0, 2 * np.pi, size=(3, 300))  # the same draw, eq. 2 by hand
    s = 15.0 * 0.004 * np.arange(500)
    w = np.linspace(0.02 * np.pi, 6 * np.pi, 300)
    dw = w[1] - w[0]
    for j, c in enumerate(classes):
        k = "ABCDE".index(c) * 2
        amp = np.sqrt(2.0**k * 1e-6 * w**-2 * dw / np.pi)
        direct = (amp[None, :] * np.sin(w[None, :] * s[:, None] - phases[j][None, :])).sum(axis=1)
        np.testing.assert_allclose(road[j], direct, rtol=1e-9, atol=1e-12 * np.abs(direct).max())


def test_ensemble_variance_is_half_the_sum_of_squared_amplitudes():
    # over 73 m (not a whole period) the time average alone is biased; the ensemble average is not
    road = road_profiles(["C"] * 2000, 100, 0.05, 14.6, rng=1)
    ensemble_var = np.mean(road**2)
    assert ensemble_var == pytest.approx(theory_variance("C"), rel=0.05)


def test_periodogram_falls_with_slope_minus_two():
    road = road_profiles(["D"], rng=2, **PERIOD)[0]
    power = np.abs(np.fft.rfft(road)) ** 2
    bins = np.arange(1, 301)  # FFT bin i is wave number i * 0.02 pi = w_i over the 100 m period
    slope = np.polyfit(np.log(wave_numbers(300)), np.log(power[bins]), 1)[0]
    assert slope == pytest.approx(-2.0, abs=0.02)
    assert power[301:].max() < 1e-12 * power[1]  # nothing above wM


@pytest.mark.parametrize("lo, hi", [("A", "B"), ("B", "C"), ("C", "D"), ("D", "E")])
def test_each_class_step_multiplies_the_spectrum_by_four(lo, hi):
    var_lo = np.var(road_profiles([lo] * 5, rng=3, **PERIOD), axis=1)
    var_hi = np.var(road_profiles([hi] * 5, rng=4, **PERIOD), axis=1)
    # over a whole period the variance no longer depends on the phases
    np.testing.assert_allclose(var_lo, theory_variance(lo), rtol=1e-6)
    np.testing.assert_allclose(var_hi / var_lo, 4.0, rtol=1e-6)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(road_classes=["F"]), r"road_classes = \['F'\] is not allowed: each class must be one of A, B, C, D, E"),
        (dict(dt=0.0), "dt = 0.0 is not allowed: must be > 0"),
        (dict(speed=-1.0), "speed = -1.0 is not allowed: must be > 0"),
    ],
)
def test_bad_input_is_named(kwargs, match):
    args = dict(road_classes=["A"], n_steps=10, dt=0.01, speed=10.0) | kwargs
    with pytest.raises(ValueError, match=match):
        road_profiles(**args)
