"""physics.eiv.posterior: the Bayes estimate of p for the mean relative deviation, against references built here.

References: a brute-force minimiser of the posterior expected relative error; the simulator's draws of m3, C3 and
K3 made here with numpy (a histogram, and the density's integral); an independent recursion (scipy's lfilter of
the discrete transfer function of physics.eiv's docstring); the MAP fit of the same noisy windows.
"""

import numpy as np
import pytest
from scipy.signal import lfilter

from hybrid_sysid.core.checks import ConfigError
from hybrid_sysid.data.dataset import generate_dataset
from hybrid_sysid.data.spec import DatasetSpec
from hybrid_sysid.physics import QuarterCar
from hybrid_sysid.physics.eiv import fit_eiv, log_p_prior
from hybrid_sysid.physics.eiv.criterion import evaluate_criterion
from hybrid_sysid.physics.eiv.model import error_spectra, setup_windows
from hybrid_sysid.physics.eiv.posterior import (
    bayes_fit,
    criterion_on_grid,
    log_prior_density,
    posterior_grid,
    weighted_median,
)
from hybrid_sysid.physics.filters import bandpass_taps
from hybrid_sysid.physics.seat_fit import fit_windows

DT = 0.005
CAR = QuarterCar()
DRAWS = {"m3_min": 50, "m3_max": 200, "c3": CAR.c3, "k3": CAR.k3, "seat_spread": 0.3}


def draw_log_p(rng, n, m3_min=50, m3_max=200, s=0.3):
    """The simulator's draws (data/dataset.py) of log p, written here: m3 integer uniform, C3 and K3 spread."""
    m3 = rng.integers(m3_min, m3_max + 1, size=n).astype(float)
    c3 = CAR.c3 * rng.uniform(1 - s, 1 + s, size=n)
    k3 = CAR.k3 * rng.uniform(1 - s, 1 + s, size=n)
    return np.log(np.stack([c3 / m3, k3 / m3], axis=1))


def test_the_weighted_median_minimises_the_expected_relative_error_by_brute_force():
    rng = np.random.default_rng(3)
    x = np.sort(np.exp(rng.normal(2.0, 0.4, size=60)))  # a skewed 1-D posterior's support points
    w = rng.gamma(2.0, size=60)  # and their posterior weights
    candidates = np.linspace(x[0], x[-1], 20001)
    loss = (w * np.abs(candidates[:, None] / x - 1)).sum(axis=1)  # E |m / p - 1| up to the weights' total
    m = weighted_median(x, w / x)
    assert (w * np.abs(m / x - 1)).sum() <= loss.min() * (1 + 1e-12)
    assert m == x[np.argmin((w * np.abs(x[:, None] / x - 1)).sum(axis=1))]  # the minimiser among the points
    assert np.isnan(weighted_median(x, np.zeros_like(x)))


def test_the_prior_density_integrates_to_one_and_matches_the_simulators_draws():
    m3_min, m3_max = 50, 200
    draws = dict(DRAWS)
    lo = np.log([CAR.c3 * 0.7 / m3_max, CAR.k3 * 0.7 / m3_max]) - 0.05
    hi = np.log([CAR.c3 * 1.3 / m3_min, CAR.k3 * 1.3 / m3_min]) + 0.05
    bins = 24
    edges = [np.linspace(lo[i], hi[i], bins + 1) for i in range(2)]
    # each bin's mass by the midpoint rule on a sub-grid (10 x 10 points per bin)
    sub = 10
    mids = [e[0] + (np.arange(bins * sub) + 0.5) * (e[-1] - e[0]) / (bins * sub) for e in edges]
    area = np.prod([(e[-1] - e[0]) / (bins * sub) for e in edges])
    density = np.exp(log_prior_density(np.stack(np.meshgrid(*mids, indexing="ij"), axis=-1), **draws))
    mass = density.reshape(bins, sub, bins, sub).sum(axis=(1, 3)) * area
    assert mass.sum() == pytest.approx(1.0, abs=1e-4)  # measured 4e-7: the midpoint rule at the support's edges
    n = 1_000_000
    hist = np.histogram2d(*draw_log_p(np.random.default_rng(11), n).T, bins=edges)[0] / n
    # binomial sd <= 1.2e-4 per bin: measured max 2.9e-4 over the 576 bins; a spread of 0.27 instead gives 2e-3
    assert np.abs(hist - mass).max() < 7e-4
    assert np.isneginf(log_prior_density(np.array([lo[0], hi[1]]) - 0.01, **draws))  # outside: no density
    with pytest.raises(ConfigError, match="seat_spread"):
        log_prior_density(np.zeros(2), **{**draws, "seat_spread": 0.0})


def lfilter_windows(p, n_steps, window, rng):
    """Clean consistent windows of the discrete model (physics.eiv's docstring), simulated by lfilter from rest on
    a broadband body input; the last ``window`` samples, so the window starts in motion."""
    seat, body = [], []
    for p1, p2 in p:
        u = lfilter([1.0], [1.0, -0.9], rng.standard_normal(n_steps))
        b = [p1 * DT, p2 * DT**2 - p1 * DT]
        a = [1.0, p1 * DT + p2 * DT**2 - 2, 1 - p1 * DT]
        seat.append(lfilter(b, a, u)[-window:])
        body.append(u[-window:])
    return np.array(seat), np.array(body)


def test_exact_on_clean_windows_of_an_independent_simulation():
    rng = np.random.default_rng(5)
    p = np.exp(draw_log_p(rng, 24))
    seat, body = lfilter_windows(p, 900, 500, rng)
    start = fit_windows(seat, body, DT, "consistent", bandpass_taps(4.0, 20.0, 151, DT)).p
    fit = fit_eiv(seat, body, DT, p0=start, prior=log_p_prior(*DRAWS.values()))
    est = bayes_fit(seat, body, DT, fit, DRAWS)
    assert np.abs(est / p - 1).max() <= 1e-4


def test_noisy_windows_below_the_map_fit_on_both_parameters():
    """Noise 0.03 on 1200 windows of the simulator's recordings (seat_spread 0.3). Measured ratios Bayes / MAP of
    the mean relative deviation over data seeds 0-7: p1 0.933-0.991, p2 0.951-0.998, below 1 on both for every
    seed; seed 0, held here to below MAP, 0.933 / 0.951 (5-7% room: the data are seeded, only rounding moves them)."""
    spec = DatasetSpec(n_roads=20, n_masses=60, n_steps=500, seat_spread=0.3, seed=0)
    ds = generate_dataset(spec)
    rng = np.random.default_rng(0)
    true = ds.params[:, :2].astype(float)
    seat, body = (x.astype(float) + 0.03 * rng.standard_normal(x.shape) for x in (ds.seat_acc, ds.body_acc))
    start = fit_windows(seat, body, DT, "consistent", bandpass_taps(4.0, 20.0, 151, DT)).p
    fit = fit_eiv(seat, body, DT, p0=start, prior=log_p_prior(*DRAWS.values()))
    est = bayes_fit(seat, body, DT, fit, DRAWS)
    assert np.isfinite(est).all()
    bayes, map_ = np.abs(est / true - 1).mean(axis=0), np.abs(fit.p / true - 1).mean(axis=0)
    assert (bayes < map_).all(), (bayes, map_)


def test_windows_without_a_map_fit_stay_undefined():
    rng = np.random.default_rng(2)
    p = np.exp(draw_log_p(rng, 3))
    seat, body = lfilter_windows(p, 700, 400, rng)
    seat[1] = body[1] = 0.0  # no excitation: no fit
    fit = fit_eiv(seat, body, DT, prior=log_p_prior(*DRAWS.values()))
    est = bayes_fit(seat, body, DT, fit, DRAWS)
    assert np.isnan(est[1]).all() and np.isfinite(est[[0, 2]]).all()


@pytest.mark.parametrize("model", ["discrete", "continuous"])
def test_the_criterion_on_the_grid_equals_the_criterion_point_by_point(model):
    rng = np.random.default_rng(4)
    seat, body, _, grid, q = setup_windows(rng.standard_normal((3, 300)), rng.standard_normal((3, 300)), DT, 1.0, model)
    E = error_spectra(seat, body, grid)
    axes = posterior_grid(np.log([[10.0, 500.0]]) + rng.normal(0, 0.2, (3, 2)), np.full((3, 2), 0.1), points=5)
    V = criterion_on_grid(axes, E, grid, q)
    for i in range(5):
        for j in range(5):
            theta = np.stack([axes[:, i, 0], axes[:, j, 1]], axis=1)
            assert V[:, i, j] == pytest.approx(evaluate_criterion(theta, E, grid, q, derivatives=False)[0], rel=1e-10)
