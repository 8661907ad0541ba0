"""physics.eiv: the errors-in-variables fit of (p1, p2) and its Cramer-Rao bound, against references built here.

References: the simulator's clean consistent windows and an independent recursion (scipy's lfilter of the transfer
function the module docstring derives from quarter_car.step) with their true p; the same frequency-domain criterion
written here afresh and minimised by scipy's least_squares; the time-domain output error with free initial
conditions; the exact continuous recordings of physics.exact; Monte Carlo over seeded noise; the Fisher information
of the time-domain likelihood by finite differences; the prior's moments in closed form.
"""

import warnings
from functools import lru_cache

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.signal import lfilter

from hybrid_sysid.physics import (
    QuarterCar,
    continuous_recordings,
    road_amplitudes,
    road_phases,
    road_profiles,
    seat_car,
    simulate,
    wave_numbers,
)
from hybrid_sysid.physics.eiv import crb_relative_std, fit_eiv, log_p_prior
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.physics.seat_fit import fit_windows

DT, SPEED, N_WAVES, WINDOW = 0.005, 15.0, 300, 500
CAR = QuarterCar()
FIR = bandpass_taps(4.0, 20.0, 151, DT)
PRIOR = (50, 200, CAR.c3, CAR.k3, 0.3)  # the data's draws of m3, C3 and K3 (seat_spread 30%)


def transfer(p, dt):
    """(b, a) of S / U for the consistent recording of the symplectic step, in lfilter's convention."""
    p1, p2 = p
    return np.array([p1 * dt, p2 * dt * dt - p1 * dt]), np.array([1.0, p1 * dt + p2 * dt * dt - 2.0, 1.0 - p1 * dt])


@lru_cache(maxsize=None)
def consistent_recordings(classes="CDE", n_masses=4, n_steps=1500, seed=0):
    """Seat and body of every road with n_masses seats, C3 and K3 spread by 30%, and the true p: (n, steps)."""
    rng = np.random.default_rng(seed)
    n = len(classes) * n_masses
    road = road_profiles(list(classes), n_steps, DT, SPEED, rng=seed)[np.repeat(np.arange(len(classes)), n_masses)]
    m3 = rng.integers(50, 201, size=n).astype(float)
    car = seat_car(CAR, n, CAR.c3 * rng.uniform(0.7, 1.3, n), CAR.k3 * rng.uniform(0.7, 1.3, n))
    seat, body = simulate(road, m3, DT, car, measurement="consistent")
    return seat, body, np.stack(car.parameters(m3), axis=1)


def cut(seat, body, rng, width=WINDOW, low=100):
    """One window of every row at a random start (not from rest: the transient term is needed)."""
    starts = rng.integers(low, seat.shape[1] - width + 1, size=len(seat))
    take = starts[:, None] + np.arange(width)
    return np.take_along_axis(seat, take, 1), np.take_along_axis(body, take, 1)


def continuous_windows(classes, n_rec, n_steps, seed):
    """Windows of exact continuous recordings (physics.exact), two per recording, with the true p."""
    rng = np.random.default_rng(seed)
    phases = road_phases(len(classes), N_WAVES, rng)
    m3 = rng.uniform(50.0, 200.0, size=n_rec)
    c3, k3 = CAR.c3 * rng.uniform(0.7, 1.3, n_rec), CAR.k3 * rng.uniform(0.7, 1.3, n_rec)
    seat, body = continuous_recordings(
        road_amplitudes(list(classes), N_WAVES),
        phases,
        wave_numbers(N_WAVES) * SPEED,
        np.arange(n_rec) % len(classes),
        m3,
        n_steps,
        DT,
        c3=c3,
        k3=k3,
    )
    p = np.stack([c3 / m3, k3 / m3], axis=1)
    windows = [cut(seat, body, rng, low=0) for _ in range(2)]
    return np.concatenate([w[0] for w in windows]), np.concatenate([w[1] for w in windows]), np.tile(p, (2, 1))


def test_clean_consistent_windows_of_the_simulator_give_p_to_rounding():
    seat, body, p = consistent_recordings()
    seat, body = cut(seat, body, np.random.default_rng(1))
    start = fit_windows(seat, body, DT, "consistent", FIR).p
    for p0, ratio in ((None, 1.0), (start, 1.0), (start, 0.0), (start, 5.0)):
        fit = fit_eiv(seat, body, DT, noise_ratio=ratio, p0=p0)
        assert fit.converged.all()
        assert np.abs(fit.p / p - 1).max() <= 1e-9  # measured 1e-13; the criterion asks 1e-4
        assert (fit.se < 1e-9).all() and (fit.sigma2 < 1e-20).all()


def test_clean_windows_of_an_independent_recursion_give_p_to_rounding():
    """lfilter of the transfer function from a random start state: the window begins mid-motion."""
    rng = np.random.default_rng(2)
    for dt in (0.002, 0.005, 0.01):
        p = np.stack([rng.uniform(2.0, 40.0, 6), rng.uniform(100.0, 1500.0, 6)], axis=1)
        seat, body = np.empty((6, 400)), np.empty((6, 400))
        for i in range(6):
            body[i] = lfilter([1.0], [1.0, -0.7], rng.standard_normal(400))
            seat[i] = lfilter(*transfer(p[i], dt), body[i], zi=rng.standard_normal(2))[0]
        fit = fit_eiv(seat, body, dt)
        assert fit.converged.all()
        assert np.abs(fit.p / p - 1).max() <= 1e-9


def criterion_residuals(theta, seat, body, dt, ratio, model):
    """The criterion's residuals on the full DFT grid, real and imaginary parts stacked, with the transient's real
    coefficients solved by lstsq: written from the module docstring's formulas, pointwise in z."""
    n = len(seat)
    p1, p2 = np.exp(theta)
    x = np.exp(-2j * np.pi * np.arange(n) / n)  # z^-1
    if model == "discrete":
        a = 1 + (p1 * dt + p2 * dt * dt - 2) * x + (1 - p1 * dt) * x * x
        b = p1 * dt + (p2 * dt * dt - p1 * dt) * x
        n_transient = 2
    else:
        # dt s = 2 num / den with w = nw / dw, nw = 1 - z^-1, dw = 1 + z^-1, both times dw^5 (finite at Nyquist)
        nw, dw = 1 - x, 1 + x
        num = 2 * nw * (945 * dw**4 - 735 * nw**2 * dw**2 + 64 * nw**4)
        den = dw * (945 * dw**4 - 1050 * nw**2 * dw**2 + 225 * nw**4)
        a = num**2 + p1 * dt * num * den + p2 * dt * dt * den**2
        b = p1 * dt * num * den + p2 * dt * dt * den**2
        n_transient = 10
    root = np.sqrt(np.abs(a) ** 2 + ratio * np.abs(b) ** 2)
    r = (a * np.fft.fft(seat) - b * np.fft.fft(body)) / root
    basis = x[:, None] ** np.arange(n_transient) / root[:, None]
    rows = np.concatenate([basis.real, basis.imag])
    rhs = np.concatenate([r.real, r.imag])
    coef = np.linalg.lstsq(rows, rhs, rcond=None)[0]
    return rhs - rows @ coef


def test_the_fit_is_least_squares_minimum_of_the_criterion():
    rng = np.random.default_rng(3)
    seat, body, p = consistent_recordings()
    seat, body = cut(seat[4:10], body[4:10], rng)  # class D
    cases = [(seat, body, p[4:10], "discrete", 1.0), (seat[:3], body[:3], p[4:7], "discrete", 0.3)]
    cseat, cbody, cp = continuous_windows("D", 2, 1200, 4)
    cases.append((cseat[:3], cbody[:3], cp[:3], "continuous", 0.5))
    for s, u, p_true, model, ratio in cases:
        s = s + 0.02 * rng.standard_normal(s.shape)
        u = u + 0.02 * np.sqrt(ratio) * rng.standard_normal(u.shape)
        fit = fit_eiv(s, u, DT, noise_ratio=ratio, model=model, p0=p_true)
        assert fit.converged.all()
        for i in range(len(s)):
            ref = least_squares(
                criterion_residuals,
                np.log(p_true[i]),
                args=(s[i], u[i], DT, ratio, model),
                xtol=1e-15,
                ftol=1e-15,
                gtol=1e-15,
            )
            assert fit.p[i] == pytest.approx(np.exp(ref.x), rel=1e-6)
            assert fit.cost[i] == pytest.approx(np.sum(ref.fun**2), rel=1e-8)


def test_noise_ratio_zero_is_time_domain_output_error_with_free_initial_conditions():
    rng = np.random.default_rng(5)
    seat, body, p = consistent_recordings()
    seat, body = cut(seat[::3], body[::3], rng)
    seat = seat + 0.02 * rng.standard_normal(seat.shape)
    body = body + 0.02 * rng.standard_normal(body.shape)
    fit = fit_eiv(seat, body, DT, noise_ratio=0.0, p0=p[::3])
    assert fit.converged.all()

    def output_error(x, s, u):
        return s - lfilter(*transfer(np.exp(x[:2]), DT), u, zi=x[2:])[0]

    for i in range(len(seat)):
        x0 = np.concatenate([np.log(p[3 * i]), np.zeros(2)])
        ref = least_squares(output_error, x0, args=(seat[i], body[i]), xtol=1e-15, ftol=1e-15, gtol=1e-15)
        assert fit.p[i] == pytest.approx(np.exp(ref.x[:2]), rel=1e-6)
        assert fit.cost[i] == pytest.approx(WINDOW * np.sum(ref.fun**2), rel=1e-8)  # Parseval


def test_eiv_is_unbiased_where_band_passed_least_squares_is_not():
    """Long windows (4000 steps) on class D roads, noise 0.1 on both channels, 200 windows: the mean relative error
    of the EIV p within 2 standard errors of the Monte Carlo mean, that of least squares below -3 (on p2; p1 is
    low too). Measured here: EIV +0.04% and -0.08% (0.1 and 0.8 SE), least squares -1.5% and -1.5% (3.0 and 5.3
    SE); over four other seeds EIV within 1.7 SE (its own bias, of the order of its variance, is ~0.2% on p1) and
    least squares 2.2-3.6 SE low on p1, 4.8-5.6 SE on p2."""
    rng = np.random.default_rng(6)
    n, steps = 200, 4000
    m3 = rng.integers(50, 201, size=n).astype(float)
    seat, body = simulate(road_profiles(["D"] * n, steps + 500, DT, SPEED, rng=7), m3, DT, measurement="consistent")
    seat = seat[:, 500:] + 0.1 * rng.standard_normal((n, steps))
    body = body[:, 500:] + 0.1 * rng.standard_normal((n, steps))
    p = np.stack(CAR.parameters(m3), axis=1)
    ls = fit_windows(seat, body, DT, "consistent", FIR)
    fit = fit_eiv(seat, body, DT, p0=ls.p)
    assert fit.converged.all()

    def bias(est):
        err = est / p - 1
        return err.mean(axis=0), err.std(axis=0, ddof=1) / np.sqrt(n)

    eiv_bias, eiv_se = bias(fit.p)
    ls_bias, ls_se = bias(ls.p)
    assert (np.abs(eiv_bias) < 2 * eiv_se).all()
    assert ls_bias[1] < -3 * ls_se[1] and ls_bias[0] < 0
    assert (np.abs(eiv_bias) < np.abs(ls_bias)).all()


@pytest.mark.parametrize("model", ["discrete", "continuous"])
def test_the_monte_carlo_spread_is_the_cramer_rao_bound(model):
    """1000 noise realisations on one clean window: the standard error of a sample std is 2.2%, so 10% is 4.5 of
    them (measured 1-2%); the fit's own se and noise std agree within 0.2% (asserted 3%)."""
    rng = np.random.default_rng(8)
    if model == "discrete":
        seat, body, p = consistent_recordings()
        seat, body, p, ratio = seat[4, 700 : 700 + WINDOW], body[4, 700 : 700 + WINDOW], p[4], 1.0
    else:
        seat, body, p = continuous_windows("D", 1, 1200, 9)
        seat, body, p, ratio = seat[0], body[0], p[0], 0.5
    sigma, reps = 0.005, 1000
    bound = crb_relative_std(seat, body, p, DT, ratio, model)[0] * sigma
    noisy_seat = seat + sigma * rng.standard_normal((reps, WINDOW))
    noisy_body = body + sigma * np.sqrt(ratio) * rng.standard_normal((reps, WINDOW))
    fit = fit_eiv(noisy_seat, noisy_body, DT, noise_ratio=ratio, model=model, p0=p)
    assert fit.converged.all()
    spread = np.log(fit.p / p).std(axis=0, ddof=1)
    np.testing.assert_allclose(spread, bound, rtol=0.1)
    np.testing.assert_allclose(np.median(fit.se, axis=0), bound, rtol=0.03)
    np.testing.assert_allclose(np.sqrt(np.median(fit.sigma2)), sigma, rtol=0.03)


def time_domain_crb(body, p, zi, dt, ratio):
    """The Cramer-Rao bound of log p from the time-domain likelihood (sigma_s = 1): the seat is lfilter's output from
    the true input u0 with initial state zi, the body is u0; (zi, u0) are nuisance parameters (u0 is known when
    the ratio is 0). Derivatives by central differences in log p; the model is linear in zi and u0."""
    n = len(body)

    def seat(theta, state, u):
        return lfilter(*transfer(np.exp(theta), dt), u, zi=state)[0]

    theta, h = np.log(p), 1e-6
    d_theta = np.stack(
        [(seat(theta + h * e, zi, body) - seat(theta - h * e, zi, body)) / (2 * h) for e in np.eye(2)], axis=1
    )
    d_zi = np.stack([seat(theta, e, np.zeros(n)) for e in np.eye(2)], axis=1)
    if ratio == 0:
        jac, inv_cov = np.hstack([d_theta, d_zi]), np.eye(n)
    else:
        d_u = np.stack([seat(theta, np.zeros(2), e) for e in np.eye(n)], axis=1)
        jac = np.block([[d_theta, d_zi, d_u], [np.zeros((n, 4)), np.eye(n)]])
        inv_cov = np.diag(np.concatenate([np.ones(n), np.full(n, 1.0 / ratio)]))
    info = jac.T @ inv_cov @ jac
    schur = info[:2, :2] - info[:2, 2:] @ np.linalg.solve(info[2:, 2:], info[2:, :2])
    return np.sqrt(np.diag(np.linalg.inv(schur)))


def test_the_bound_is_the_time_domain_fisher_information_and_behaves():
    rng = np.random.default_rng(10)
    n = 41  # odd: no Nyquist bin
    p = np.array([[12.0, 700.0], [30.0, 300.0], [4.0, 1400.0]])
    body = rng.standard_normal((3, n))
    zi = rng.standard_normal((3, 2))
    seat = np.stack([lfilter(*transfer(p[i], DT), body[i], zi=zi[i])[0] for i in range(3)])
    for ratio in (1.0, 0.3, 0.0):
        got = crb_relative_std(seat, body, p, DT, ratio)
        for i in range(3):
            # measured 2e-8: the finite differences'
            np.testing.assert_allclose(got[i], time_domain_crb(body[i], p[i], zi[i], DT, ratio), rtol=1e-6)

    seat, body, p = consistent_recordings()
    seat, body = cut(seat, body, np.random.default_rng(11))
    both = crb_relative_std(seat, body, p, DT, 1.0)
    np.testing.assert_allclose(crb_relative_std(3 * seat, 3 * body, p, DT, 1.0), both / 3, rtol=1e-10)
    assert (crb_relative_std(seat, body, p, DT, 0.0) <= both).all()
    assert (both <= crb_relative_std(seat, body, p, DT, 4.0)).all()
    seat[2], body[2] = 0.0, 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dead = crb_relative_std(seat, body, p, DT, 1.0)
    assert np.isinf(dead[2]).all() and np.isfinite(np.delete(dead, 2, axis=0)).all()


def test_map_follows_the_prior_without_data_the_data_without_noise_and_is_calibrated():
    mean, cov = log_p_prior(*PRIOR)
    seat, body, p = consistent_recordings()
    seat, body = cut(seat, body, np.random.default_rng(12))

    ml = fit_eiv(seat, body, DT, p0=p)
    posterior = fit_eiv(seat, body, DT, p0=p, prior=(mean, cov))
    assert posterior.converged.all()
    np.testing.assert_allclose(posterior.p, ml.p, rtol=1e-9)  # clean: sigma^2 ~ 0 gives the prior no weight

    # Nearly uninformative: the signal at 1e-3 of its size under noise 0.01, and a prior of 4% (its information
    # ~600 per unit of log p squared, the window's ~10-20). With its data, ML runs 10-90 prior stds away (median
    # 36); measured MAP at most 0.53 of one from the prior's mean (median 0.11), with a posterior std 0.97-0.99 of
    # the prior's. (With the wide
    # prior of 42% the window's information is not negligible: the profile likelihood of EIV keeps a curvature
    # from the noise itself, which leaves MAP up to a few prior stds away.)
    rng = np.random.default_rng(13)
    tight = cov / 100
    tight_std = np.sqrt(np.diag(tight))
    faint = 1e-3 * seat[:8] + 0.01 * rng.standard_normal((8, WINDOW))
    faint_body = 1e-3 * body[:8] + 0.01 * rng.standard_normal((8, WINDOW))
    ml = fit_eiv(faint, faint_body, DT)
    posterior = fit_eiv(faint, faint_body, DT, prior=(mean, tight))
    assert posterior.converged.all()
    pull = np.abs(np.log(posterior.p) - mean) / tight_std
    assert (pull < 1.0).all() and np.median(pull) < 0.02 * np.median(np.abs(np.log(ml.p) - mean) / tight_std)
    assert ((0.9 * tight_std < posterior.se) & (posterior.se <= tight_std)).all()

    # p drawn from a narrower prior, one window each with noise that leaves p1 about as uncertain as the prior
    # does: the MAP's errors match its own se (measured rms z 1.01 and 1.04; a prior weight off by 2 gives 0.85 or
    # 1.32 on p1; the standard error of an rms over 800 draws is 2.5%) and halve ML's on p1
    cov = cov / 16
    n = 800
    theta = rng.multivariate_normal(mean, cov, size=n)
    seat, body = np.empty((n, WINDOW)), np.empty((n, WINDOW))
    for i in range(n):
        u = lfilter([1.0], [1.0, -0.9], rng.standard_normal(WINDOW + 300))
        seat[i], body[i] = lfilter(*transfer(np.exp(theta[i]), DT), u)[300:], u[300:]
    noise = 1.4  # measured: ~ the prior's std on p1 (the bound's median is 0.075 per unit noise)
    seat = seat + noise * rng.standard_normal(seat.shape)
    body = body + noise * rng.standard_normal(body.shape)
    ml = fit_eiv(seat, body, DT, p0=np.exp(mean))
    posterior = fit_eiv(seat, body, DT, p0=np.exp(mean), prior=(mean, cov))
    assert posterior.converged.all()
    for key in ("p", "se", "sigma2", "converged"):  # the ML fit it started from, kept: the ML fit of its own
        np.testing.assert_array_equal(getattr(posterior.ml, key), getattr(ml, key))
    err_map, err_ml = np.log(posterior.p) - theta, np.log(ml.p) - theta
    z = np.sqrt(np.mean((err_map / posterior.se) ** 2, axis=0))
    assert ((0.9 < z) & (z < 1.1)).all()
    rms_map, rms_ml = np.sqrt(np.mean(err_map**2, axis=0)), np.sqrt(np.mean(err_ml**2, axis=0))
    assert rms_map[0] < 0.7 * rms_ml[0] and rms_map[1] <= 1.05 * rms_ml[1]


def test_the_continuous_model_is_exact_on_exact_recordings_where_least_squares_and_the_discrete_model_are_not():
    """Measured: EIV worst 8e-10 here (1.3e-9 over 90 windows of all classes); band-passed least squares 1-4e-5 on
    average, worst 9e-5; the discrete model on these recordings 1.4-3.5% (the step's error, not the noise's)."""
    errors = {"eiv": [], "ls": [], "discrete": []}
    for k, classes in enumerate(("AC", "E")):
        seat, body, p = continuous_windows(classes, 6, 1400, 20 + k)
        ls = fit_windows(seat, body, DT, "continuous", FIR)
        fit = fit_eiv(seat, body, DT, model="continuous", p0=ls.p)
        assert fit.converged.all()
        errors["eiv"].append(np.abs(fit.p / p - 1))
        errors["ls"].append(np.abs(ls.p / p - 1))
        errors["discrete"].append(np.abs(fit_eiv(seat, body, DT, p0=ls.p).p / p - 1))
    eiv, ls, discrete = (np.concatenate(errors[key]) for key in ("eiv", "ls", "discrete"))
    assert eiv.max() <= 1e-8
    assert ls.max() <= 2e-4 and (eiv.mean(axis=0) < 1e-3 * ls.mean(axis=0)).all()
    assert (discrete.mean(axis=0) > 5e-3).all()


def test_undefined_windows_are_marked_and_float32_is_taken_in_float64():
    seat, body, p = consistent_recordings()
    seat, body = cut(seat[:5], body[:5], np.random.default_rng(14))
    seat = seat + 0.01 * np.random.default_rng(15).standard_normal(seat.shape)
    seat[1], body[1] = 0.0, 0.0
    seat[3, 17] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fit = fit_eiv(seat, body, DT)
        posterior = fit_eiv(seat, body, DT, prior=log_p_prior(*PRIOR))
    for f in (fit, posterior):
        assert np.isnan(f.p[[1, 3]]).all() and np.isinf(f.se[[1, 3]]).all() and not f.converged[[1, 3]].any()
        assert np.isfinite(f.p[[0, 2, 4]]).all() and f.converged[[0, 2, 4]].all()

    single = fit_eiv(seat[0].astype(np.float32), body[0].astype(np.float32), DT)
    again = fit_eiv(seat[:1].astype(np.float32).astype(np.float64), body[:1].astype(np.float32).astype(float), DT)
    np.testing.assert_array_equal(single.p, again.p)
    np.testing.assert_allclose(single.p, fit.p[:1], rtol=1e-3)  # float32 rounding of the samples only


def test_the_prior_is_the_draws_moments():
    """log p = log c3 + log U_c - log m3 (and likewise for k3): the moments of log U(1 - s, 1 + s) in closed form
    and those of log m3 over the integers."""
    m3_min, m3_max, c3, k3, s = PRIOR
    lo, hi = 1 - s, 1 + s

    def antiderivative(x, power):  # of log(x)^power
        return x * np.log(x) - x if power == 1 else x * (np.log(x) ** 2 - 2 * np.log(x) + 2)

    log_u = (antiderivative(hi, 1) - antiderivative(lo, 1)) / (2 * s)
    var_u = (antiderivative(hi, 2) - antiderivative(lo, 2)) / (2 * s) - log_u**2
    log_m = np.log(np.arange(m3_min, m3_max + 1))
    mean, cov = log_p_prior(*PRIOR)
    np.testing.assert_allclose(mean, [np.log(c3) + log_u - log_m.mean(), np.log(k3) + log_u - log_m.mean()], atol=2e-3)
    expected = np.full((2, 2), log_m.var()) + np.diag([var_u, var_u])
    np.testing.assert_allclose(cov, expected, rtol=0.02)
