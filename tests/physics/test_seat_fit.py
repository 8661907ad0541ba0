"""physics.seat_fit: the seat equation's least squares with its statistics, against numpy's lstsq and the textbook
standard error, and the window fit against a fit of the same windows integrated from t0."""

import numpy as np
import pytest

from hybrid_sysid.physics import relative_states, road_profiles, simulate
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.physics.seat_fit import fit_seat, fit_windows


def regressors(rng, n, t):
    a = rng.standard_normal((n, t)).cumsum(axis=1)
    return a, 0.3 * a + 0.03 * rng.standard_normal((n, t)).cumsum(axis=1)


def test_the_fit_and_its_statistics_are_lstsqs_and_the_textbook_ones():
    rng = np.random.default_rng(0)
    a, b = regressors(rng, 6, 300)
    y = -8.0 * a - 1200.0 * b + 0.1 * rng.standard_normal(a.shape)
    keep = np.ones_like(y)
    keep[:, 100:180] = 0  # a row may leave samples out: only the kept ones take part
    fit = fit_seat(y, a, b, keep)
    for i in range(len(y)):
        x = np.stack([-a[i], -b[i]], axis=1)[keep[i] > 0]
        coef, rss, _, _ = np.linalg.lstsq(x, y[i][keep[i] > 0], rcond=None)
        cov = rss[0] / (len(x) - 2) * np.linalg.inv(x.T @ x)
        assert fit.p[i] == pytest.approx(coef, rel=1e-9)
        assert fit.se[i] == pytest.approx(np.sqrt(np.diag(cov)) / np.abs(coef), rel=1e-6)
        assert fit.unexplained[i] == pytest.approx(rss[0] / (y[i][keep[i] > 0] ** 2).sum(), rel=1e-6)
        cosine = x[:, 0] @ x[:, 1] / np.linalg.norm(x[:, 0]) / np.linalg.norm(x[:, 1])  # uncentred: no intercept
        assert fit.correlation[i] == pytest.approx(cosine, rel=1e-9)


def test_an_exact_fit_has_a_standard_error_of_rounding_and_an_undefined_one_is_marked():
    rng = np.random.default_rng(1)
    a, b = regressors(rng, 3, 300)
    fit = fit_seat(-8.0 * a - 1200.0 * b, a, b)
    assert fit.p == pytest.approx(np.tile([8.0, 1200.0], (3, 1)), rel=1e-10)  # the normal equations' rounding
    assert (fit.se < 1e-10).all()
    dead = fit_seat(np.zeros((2, 50)), np.zeros((2, 50)), np.zeros((2, 50)))
    assert np.isnan(dead.p).all() and np.isinf(dead.se).all()


def test_windows_integrated_on_their_own_fit_as_from_t0():
    """The band-pass removes the constant and ramp that the motion before a window leaves in its regressors."""
    dt, n, w, starts = 0.005, 900, 400, (0, 250, 500)
    m3 = np.array([60.0, 150.0])
    seat, body = simulate(road_profiles(["C", "E"], n, dt, 15.0, rng=3), m3, dt, measurement="consistent")
    seat, body = seat + 0.01 * np.random.default_rng(4).standard_normal((2, 2, n))
    fir = bandpass_taps(4.0, 20.0, 151, dt)
    rv, rd = relative_states(seat, body, dt, "consistent")
    for s in starts:
        own = fit_windows(seat[:, s : s + w], body[:, s : s + w], dt, "consistent", fir)
        filt = [np.stack([np.convolve(x[i, s : s + w], fir, "valid") for i in range(2)]) for x in (seat, rv, rd)]
        from_t0 = fit_seat(*filt)
        assert own.p == pytest.approx(from_t0.p, rel=1e-6)
