"""The Bayes estimate of (p1, p2) for the mean relative deviation: the errors-in-variables likelihood times the
simulator's exact prior of log p, on a grid per window (baseline=eiv_bayes). Plain numpy.

Why not the MAP fit: the table's metric is E |p_hat / p - 1|, and the estimate that minimises its posterior
expectation is, per parameter, the median of the posterior marginal weighted by 1 / p (E |p_hat - p| / p is a
weighted absolute deviation), not the posterior's mode. The MAP fit's Gaussian prior (log_p_prior) has unbounded
support, so on barely informative windows (noise 0.1) it lets p run far from any seat the simulator draws; the
exact prior is zero there.

The prior: the simulator draws m3 uniformly from the integers [m3_min, m3_max], C3 = c3 U and K3 = k3 U' with U, U'
uniform in [1 - s, 1 + s] (data/dataset.py). log U has the density e^y / (2 s) on [log(1 - s), log(1 + s)], so
given m3 the density of theta = log p = (log C3 - log m3, log K3 - log m3) is the product of two such densities at
y = theta - log(c3, k3) + log m3, and the prior is their mean over the masses: exact, with a bounded support.

The posterior: exp(-V(theta) / (2 kappa)) times that prior, kappa = V_ML / dof the ML fit's estimate of
N sigma_seat^2 (fit_eiv: the likelihood is exp(-V / (2 N sigma^2))). It is evaluated on a G x G grid in theta
around the MAP fit, +-``width`` of its standard errors wide per parameter (at most ``cap`` in log p), cut to the
prior's support: the posterior's mass lies there, and on a clean window the grid shrinks with se, so the estimate
stays exact. Where the MAP fit lies farther outside the support than that (its Gaussian prior lets p run off on
barely informative windows), the grid spans the support: those windows carried most of MAP's error at noise 0.1.
"""

from __future__ import annotations

import numpy as np

from hybrid_sysid.core.checks import check_int, check_number, check_positive
from hybrid_sysid.physics.eiv.model import error_spectra, setup_windows

# grid points per parameter: on 3 x 400 windows, 21 cost 0.1 points of p1's error at noise 0.03 and 41 gain none
POINTS = 31
WIDTH = 5.0  # the grid's half width in the MAP fit's standard errors
CAP = 1.2  # and at most this in log p (a factor 3.3): the prior's support is narrower still
GRID_CHUNK = 1 << 22  # windows x grid points x frequencies in one block: ~10 float64 arrays of that size


def check_draws(m3_min, m3_max, c3, k3, seat_spread) -> tuple[np.ndarray, float, float, float]:
    """The masses (M,), log c3, log k3 and s of the simulator's draws, checked. A spread of 0 makes the prior a set
    of points (p1 / p2 = c3 / k3 for every mass), which has no density: it is refused."""
    m3_min = check_int("m3_min", m3_min, 1)
    m3_max = check_int("m3_max", m3_max, m3_min)
    c3, k3 = check_positive("c3", c3), check_positive("k3", k3)
    s = check_number("seat_spread", seat_spread, 0.0, 1.0, low_open=True, high_open=True)
    return np.arange(m3_min, m3_max + 1, dtype=float), float(np.log(c3)), float(np.log(k3)), s


def _spread_density(y, s: float):
    """The density of log U, U uniform in [1 - s, 1 + s], at y: e^y / (2 s) on its support, 0 elsewhere."""
    inside = (y >= np.log1p(-s)) & (y <= np.log1p(s))
    with np.errstate(over="ignore"):
        return np.where(inside, np.exp(np.minimum(y, 1.0)) / (2.0 * s), 0.0)


def log_prior_density(theta, m3_min, m3_max, c3, k3, seat_spread) -> np.ndarray:
    """log of the simulator's density of theta = log p at theta (..., 2); -inf outside its support."""
    masses, log_c3, log_k3, s = check_draws(m3_min, m3_max, c3, k3, seat_spread)
    theta = np.asarray(theta, dtype=float)
    log_m = np.log(masses)
    f1 = _spread_density(theta[..., 0, None] - log_c3 + log_m, s)
    f2 = _spread_density(theta[..., 1, None] - log_k3 + log_m, s)
    with np.errstate(divide="ignore"):
        return np.log((f1 * f2).mean(axis=-1))


def weighted_median(values, weights) -> np.ndarray:
    """Along the last axis: the smallest value whose cumulative weight reaches half the total, the minimiser of
    sum_i w_i |x - v_i|. NaN where the weights sum to zero (or are not finite)."""
    values, weights = np.broadcast_arrays(np.asarray(values, dtype=float), np.asarray(weights, dtype=float))
    order = np.argsort(values, axis=-1)
    v = np.take_along_axis(values, order, axis=-1)
    cw = np.cumsum(np.take_along_axis(weights, order, axis=-1), axis=-1)
    total = cw[..., -1:]
    with np.errstate(invalid="ignore", divide="ignore"):
        reached = cw >= 0.5 * total
    k = np.minimum(np.argmax(reached, axis=-1), v.shape[-1] - 1)[..., None]
    out = np.take_along_axis(v, k, axis=-1)[..., 0]
    return np.where((total[..., 0] > 0) & np.isfinite(total[..., 0]), out, np.nan)


def posterior_grid(
    centre, se, points: int = POINTS, width: float = WIDTH, cap: float = CAP, support=None
) -> np.ndarray:
    """(n, G, 2): per window and parameter the G values of theta the grid takes (its G x G points are their
    product), +-min(width se, cap) around ``centre`` (n, 2) in log p; a non-finite se takes the cap. ``support``:
    (low (2,), high (2,)) of theta outside which the prior is zero: the grid keeps to it, and where the MAP fit lies
    farther outside than the grid reaches (noise 0.1: p off by a factor 10 and more), it spans the support."""
    half = np.minimum(width * np.nan_to_num(np.asarray(se, dtype=float), nan=np.inf, posinf=np.inf), cap)
    low, high = centre - half, centre + half
    if support is not None:
        low, high = np.maximum(low, support[0]), np.minimum(high, support[1])
        missed = low > high
        low, high = np.where(missed, support[0], low), np.where(missed, support[1], high)
    return low[:, None, :] + np.linspace(0.0, 1.0, points)[None, :, None] * (high - low)[:, None, :]


def criterion_on_grid(axes, E, grid, q) -> np.ndarray:
    """(n, G, G): V at every point of each window's grid (``axes`` (n, G, 2) in log p, E (3, n, K) its error
    spectra), as criterion.evaluate_criterion computes it point by point. V is quadratic in the transient's
    coefficients, so V = S - r^T T^-1 r with S = sum w |e|^2, r = Re(basis^H w e), T = Re(basis^H w basis); e is
    affine in p and W quadratic: S, r and T are products of w with spectra fixed per window, matrix products
    over the frequencies for all G^2 points at once (an order of magnitude faster than point by point)."""
    n, G = axes.shape[:2]
    p = np.exp(axes)
    p1 = np.broadcast_to(p[:, :, None, 0], (n, G, G)).reshape(n, -1)
    p2 = np.broadcast_to(p[:, None, :, 1], (n, G, G)).reshape(n, -1)
    one = np.ones_like(p1)
    # W = q0 + 2 p1 q1 + 2 p2 q2 + p1^2 q3 + 2 p1 p2 q4 + p2^2 q5 (model.noise_weight)
    mono = np.stack([one, 2 * p1, 2 * p2, p1 * p1, 2 * p1 * p2, p2 * p2], axis=-1)
    # one product, not n broadcast ones: OpenBLAS threads each small one, ~20x slower on a busy machine
    w = grid.weight / (mono.reshape(-1, 6) @ q).reshape(n, G * G, -1)  # (n, G^2, K)
    pi = np.stack([one, p1, p2], axis=-1)  # e = sum_a pi_a E_a
    pairs = [(a, b) for a in range(3) for b in range(a, 3)]
    P = np.stack([(E[a] * E[b].conj()).real * (1 if a == b else 2) for a, b in pairs], axis=-1)  # (n, K, 6)
    m = grid.basis.shape[1]
    R = (E[:, :, :, None] * grid.basis.conj()[None, None]).real.transpose(1, 2, 0, 3).reshape(n, -1, 3 * m)
    cos = np.broadcast_to(grid.cos, (n, *grid.cos.shape))
    sums = w @ np.concatenate([P, R, cos], axis=-1)  # one product over the frequencies: (n, G^2, 6 + 4 m)
    S = np.einsum("ngc,ngc->ng", sums[..., :6], np.stack([pi[..., a] * pi[..., b] for a, b in pairs], axis=-1))
    r = np.einsum("ngam,nga->ngm", sums[..., 6 : 6 + 3 * m].reshape(n, -1, 3, m), pi)
    T = sums[..., 6 + 3 * m :][..., grid.toeplitz]  # (n, G^2, m, m)
    c = np.linalg.solve(T, r[..., None])[..., 0]
    return (S - np.einsum("ngm,ngm->ng", r, c)).reshape(n, G, G)


def bayes_fit(
    seat,
    body,
    dt: float,
    fit,
    draws: dict,
    *,
    noise_ratio: float = 1.0,
    model: str = "discrete",
    points: int = POINTS,
    width: float = WIDTH,
    cap: float = CAP,
) -> np.ndarray:
    """(n, 2) float64: the Bayes estimate of p for the mean relative deviation on windows (n, N) of seat and body.

    fit: the MAP EivFit of these windows (fit_eiv with a prior and fix "none"), whose ``ml`` is the ML fit: the
    grid's centre and width come from the MAP fit, the likelihood's scale kappa from the ML fit's cost. draws: the
    simulator's draws (m3_min, m3_max, c3, k3, seat_spread). A window whose MAP fit is not defined stays NaN; one
    whose posterior has no mass on its grid (a likelihood exact to rounding, kappa = 0, or a grid in a corner of
    the support's bounding box that the support itself misses) keeps the MAP fit."""
    masses, log_c3, log_k3, s = check_draws(*(draws[k] for k in ("m3_min", "m3_max", "c3", "k3", "seat_spread")))
    points = check_int("points", points, 2)
    width, cap = check_positive("width", width), check_positive("cap", cap)
    if fit.ml is None:
        raise ValueError("bayes_fit needs the MAP fit with its ML fit (fit_eiv with a prior)")
    seat, body, good, grid, q = setup_windows(seat, body, dt, noise_ratio, model)
    n, N = seat.shape
    dof = N - 2 - grid.basis.shape[1]
    with np.errstate(invalid="ignore", divide="ignore"):
        centre = np.log(fit.p)
    kappa = fit.ml.cost / dof
    out = np.full((n, 2), np.nan)
    defined = good & np.isfinite(centre).all(axis=1)
    out[defined] = fit.p[defined]
    usable = np.flatnonzero(defined & np.isfinite(kappa) & (kappa > 0))
    if not usable.size:
        return out
    # the prior's support: log(c (1 -+ s) / m) over the masses' range, per parameter
    log_c = np.array([log_c3, log_k3])
    support = (log_c + np.log1p(-s) - np.log(masses[-1]), log_c + np.log1p(s) - np.log(masses[0]))
    axes = posterior_grid(centre[usable], fit.se[usable], points, width, cap, support)  # (u, G, 2)
    # the prior separates per mass: mean_m f1(theta1 + log m) f2(theta2 + log m), an (u, G, M) x (u, G, M) product
    log_m = np.log(masses)
    f1 = _spread_density(axes[:, :, 0, None] - log_c3 + log_m, s)
    f2 = _spread_density(axes[:, :, 1, None] - log_k3 + log_m, s)
    prior = np.einsum("uim,ujm->uij", f1, f2) / len(masses)
    log_lik = np.empty((usable.size, points, points))
    block = max(1, GRID_CHUNK // (points * points * (N // 2 + 1)))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for start in range(0, usable.size, block):
            rows = slice(start, min(start + block, usable.size))
            E = error_spectra(seat[usable[rows]], body[usable[rows]], grid)
            log_lik[rows] = criterion_on_grid(axes[rows], E, grid, q)
        log_lik *= -0.5 / kappa[usable, None, None]
        log_post = np.where(np.isfinite(log_lik) & (prior > 0), log_lik + np.log(prior), -np.inf)
        top = log_post.max(axis=(1, 2), keepdims=True)
        weight = np.where(np.isfinite(top), np.exp(log_post - top), 0.0)
        # E |x / p - 1| over the posterior is sum w (|x - p| / p): the marginal's median with weights w / p
        p = np.exp(axes)
        est = np.stack(
            [
                weighted_median(p[:, :, 0], weight.sum(axis=2) / p[:, :, 0]),
                weighted_median(p[:, :, 1], weight.sum(axis=1) / p[:, :, 1]),
            ],
            axis=1,
        )
    found = np.isfinite(est).all(axis=1)
    out[usable[found]] = est[found]
    return out
