"""physics.eiv with a fault's fix: each fix recovers the true p on clean windows the simulator recorded with that
fault, and under noise on both channels it is at least as accurate as least squares with the same fix
(baselines.fixes) on the same windows.

References: the simulator's clean consistent recordings with the faults of physics.sensors put on them (gains, a
fractional delay read from true samples only), its hardening seat spring, the exact continuous recordings of
physics.exact, the true (p1, p2) and the drawn faults; least squares with each fix, and the plain fit, computed in
each test on the same windows; the spread of the estimates over seeded noise draws.
"""

from functools import lru_cache

import numpy as np
import pytest

from hybrid_sysid.baselines.fixes import fit_gain, fit_hardening, fit_skew
from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.physics import (
    QuarterCar,
    continuous_recordings,
    relative_states,
    road_amplitudes,
    road_phases,
    road_profiles,
    seat_car,
    simulate,
    wave_numbers,
)
from hybrid_sysid.physics.eiv import fit_eiv
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.physics.sensors import FaultDraws, apply

DT, SPEED, WINDOW, N_STEPS = 0.005, 15.0, 500, 1200
CAR = QuarterCar()
FIR = bandpass_taps(4.0, 20.0, 151, DT)
SKEW_MAX = 0.01  # sensor=skewed
KAPPA = 35000.0  # car=hardening_seat


@lru_cache(maxsize=None)
def recordings(classes="BCDE", n_masses=6, kappa=0.0, seed=0):
    """Clean consistent seat and body (n, N_STEPS) with C3 and K3 spread by 30%, and the true p."""
    rng = np.random.default_rng(seed)
    n = len(classes) * n_masses
    road = road_profiles(list(classes), N_STEPS, DT, SPEED, rng=seed)[np.repeat(np.arange(len(classes)), n_masses)]
    m3 = rng.integers(50, 201, size=n).astype(float)
    car = seat_car(
        QuarterCar(seat_hardening=kappa), n, CAR.c3 * rng.uniform(0.7, 1.3, n), CAR.k3 * rng.uniform(0.7, 1.3, n)
    )
    seat, body = simulate(road, m3, DT, car, measurement="consistent")
    return seat, body, np.stack(car.parameters(m3), axis=1)


def faulted(fault, seed=1, **kwargs):
    """Windows of recordings with each recording's own fault drawn as the dataset draws it: (seat, body, p, the
    fault's true value). A window starts at 100 or later and ends 100 before the recording does, so the skew's
    delay reads true samples only, as the dataset's padding makes it do."""
    rng = np.random.default_rng(seed)
    seat, body, p = recordings(**({"kappa": KAPPA} if fault == "hardening" else {}), **kwargs)
    n = len(seat)
    draws = FaultDraws(np.ones((n, 2)), np.zeros(n), None)
    truth = None
    if fault == "gain":
        draws = draws._replace(gains=rng.uniform(0.97, 1.03, (n, 2)))
        truth = draws.gains[:, 0] / draws.gains[:, 1]
    elif fault == "skew":
        draws = draws._replace(skews=rng.uniform(-SKEW_MAX, SKEW_MAX, n))
        truth = draws.skews
    seat, body = apply(seat, body, draws, DT, half_width=12)
    starts = rng.integers(100, N_STEPS - WINDOW - 100, size=n)
    take = starts[:, None] + np.arange(WINDOW)
    return np.take_along_axis(seat, take, 1), np.take_along_axis(body, take, 1), p, truth


def least_squares(fix, seat, body):
    """The least-squares fit with the same fix (estimator=ls_fix's), the window's regressors from its start."""
    if fix == "gain":
        return fit_gain(seat, body, DT, "consistent", FIR)
    if fix == "skew":
        return fit_skew(seat, body, DT, "consistent", FIR, 0.02)
    return fit_hardening(seat, *relative_states(seat, body, DT, "consistent"), FIR)


def rel_error(p, truth):
    return np.abs(p / truth - 1)


@pytest.mark.parametrize(
    "fix, fault_tol, p_tol",
    [
        ("gain", 1e-10, 1e-10),  # measured worst 1e-14 on g, 1e-13 on p: the model is exact
        ("skew", 3e-8, 3e-6),  # tau in seconds; measured worst 7e-9 s and 2.6e-7 on p1: the advance's interpolation
        ("hardening", 1e-8, 1e-10),  # kappa relative; measured worst 5e-11 and 4e-12 on p
    ],
)
def test_each_fix_recovers_p_and_the_fault_on_clean_faulty_windows(fix, fault_tol, p_tol):
    seat, body, p, truth = faulted(fix)
    plain = fit_eiv(seat, body, DT, p0=p)
    ls = least_squares(fix, seat, body)
    fit = fit_eiv(seat, body, DT, p0=ls, fix=fix, skew_max=0.02)
    assert rel_error(plain.p, p).max() > 1e-3  # the fault biases the plain fit
    assert fit.converged.all()
    assert rel_error(fit.p, p).max() < p_tol
    # no less exact than least squares with the same fix (its worst on p1: gain 5e-13, skew 8e-4, hardening 0.1)
    assert (rel_error(fit.p, p).max(axis=0) <= rel_error(ls, p).max(axis=0) + 1e-12).all()
    if fix == "hardening":
        assert fit.fault == pytest.approx(np.full(len(p), KAPPA), rel=fault_tol)
    else:
        assert np.abs(fit.fault - truth).max() < fault_tol
    assert fit.se.shape == (len(p), 2) and np.isfinite(fit.se).all()


def test_the_fixes_on_exact_continuous_recordings_and_on_data_without_the_fault():
    rng = np.random.default_rng(4)
    n, classes = 6, "CDE"
    m3 = rng.uniform(50.0, 200.0, n)
    seat, body = continuous_recordings(
        road_amplitudes(list(classes), 300),
        road_phases(len(classes), 300, rng),
        wave_numbers(300) * SPEED,
        np.arange(n) % len(classes),
        m3,
        N_STEPS,
        DT,
    )
    p = np.stack(CAR.parameters(m3), axis=1)
    window = slice(300, 300 + WINDOW)
    gains = rng.uniform(0.97, 1.03, (n, 2))
    skews = rng.uniform(-SKEW_MAX, SKEW_MAX, n)
    late = apply(seat, body, FaultDraws(np.ones((n, 2)), skews, None), DT, half_width=12)[1]
    cases = {  # the continuous model is exact to 1e-10 (physics.eiv), the skew's advance to 1e-7
        "gain": (gains[:, :1] * seat[:, window], gains[:, 1:] * body[:, window], 1e-8),  # measured 2.6e-10
        "skew": (seat[:, window], late[:, window], 3e-6),  # measured 7e-8
        "hardening": (seat[:, window], body[:, window], 1e-8),  # a linear spring; measured 2.5e-10
    }
    for fix, (s, u, tol) in cases.items():
        fit = fit_eiv(s, u, DT, p0=1.05 * p, model="continuous", fix=fix)
        assert rel_error(fit.p, p).max() < tol, fix
    assert np.abs(fit.fault).max() < 1.0  # kappa, 1/m^2 (measured 1.4e-3): a stiffening below 1e-6 at 1 mm
    # a fix on consistent windows without its fault: p to rounding (measured 1.2e-13)
    seat, body, p, _ = faulted("none")
    for fix in ("gain", "skew", "hardening"):
        fit = fit_eiv(seat, body, DT, p0=p, fix=fix)
        assert rel_error(fit.p, p).max() < 1e-10, fix


@pytest.mark.parametrize("fix", ["gain", "skew", "hardening"])
def test_under_noise_each_fix_is_at_least_as_accurate_as_least_squares_with_it(fix):
    seat, body, p, _ = faulted(fix, seed=2, n_masses=10)
    noise = np.random.default_rng([5, len(fix)]).standard_normal((2, *seat.shape))
    seat, body = seat + 0.01 * noise[0], body + 0.01 * noise[1]
    ls = least_squares(fix, seat, body)
    fit = fit_eiv(seat, body, DT, p0=ls, fix=fix, skew_max=0.02)
    eiv_dev, ls_dev = rel_error(fit.p, p).mean(axis=0), rel_error(ls, p).mean(axis=0)
    # measured eiv / ls, p1 and p2: gain 0.54 and 0.55, skew 0.92 and 0.70, hardening 0.90 and 0.46
    assert (eiv_dev < ls_dev).all(), (eiv_dev, ls_dev)


@pytest.mark.parametrize("fix", ["gain", "skew"])
def test_the_standard_error_with_a_fix_is_the_spread_over_noise_draws(fix):
    seat, body, p, _ = faulted(fix, classes="D", n_masses=1)
    draws = 300
    noise = np.random.default_rng(11).standard_normal((2, draws, WINDOW))
    fit = fit_eiv(seat + 0.01 * noise[0], body + 0.01 * noise[1], DT, p0=p, fix=fix)
    # measured se / spread, p1 and p2: gain 1.01 and 1.00, skew 0.98 and 1.05 (the plain fit's: 1.05 and 1.05)
    assert np.median(fit.se, axis=0) == pytest.approx(np.log(fit.p).std(axis=0), rel=0.1)


def test_a_bad_fix_or_skew_max_is_one_line_naming_the_key():
    seat, body, p, _ = faulted("none")
    with pytest.raises(ConfigError, match=r"^fix = 'drift' is not allowed: one of none, gain, skew, hardening$"):
        fit_eiv(seat, body, DT, fix="drift")
    with pytest.raises(ConfigError, match="^skew_max"):
        fit_eiv(seat, body, DT, fix="skew", skew_max=-0.01)
    with pytest.raises(ConfigError, match="^seat"):  # the skew's edges leave too few samples
        fit_eiv(seat[:, :30], body[:, :30], DT, fix="skew")
