"""fit_eiv, the errors-in-variables ML or MAP fit of (p1, p2) on windows, and its result EivFit.

The standard errors use the Gauss-Newton Hessian H at the fit (the Fisher information's estimate):
cov(theta) = N sigma^2 H^-1 with sigma^2 = V / (N (N - 2 - m)), the seat channel's noise variance per sample
estimated from the residual, since E V = N sigma_s^2 (N - 2 - m) at the minimum. They agree with the Monte Carlo
spread and the Cramer-Rao bound (``crb_relative_std``) within 1-2% at a good signal-to-noise ratio. On a barely
informative window they are too small: H is built from the noisy spectra, whose noise adds curvature of its own,
and the fit is no longer linear in the noise (class C at noise 0.1 on 4000 samples: rms se 0.12 on p1 where the
errors spread by 0.16).

MAP (``prior`` = (mean, cov) of theta): minimises V / (2 N sigma^2) + (theta - mean)^T cov^-1 (theta - mean) / 2
with sigma^2 from the ML fit, started at the ML solution; its se is that of the posterior's Laplace approximation,
(H / (N sigma^2) + cov^-1)^-1. Where the data are informative the errors of MAP over draws from the prior match
that se (tests/physics/test_eiv.py). Where they are not, the profile likelihood of EIV keeps a curvature the noise
itself gives it, so MAP is drawn towards the prior's mean but not onto it unless the prior is much stronger than
the window (the signal at 1e-3 of its size under noise 0.01, with the prior of ``log_p_prior`` for the data's
draws: 0.3-4 prior stds from its mean, ML 5-9; with that prior's std cut to a tenth, within 0.6 of one).

The fits start at the band-passed least squares: from the box's centre ML takes longer (benchmarks/README.md, "The
classical fits against the Cramér-Rao bound", times both).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from hybrid_sysid.core.checks import bad, check_int, check_number
from hybrid_sysid.physics.eiv.criterion import evaluate_criterion
from hybrid_sysid.physics.eiv.faults import fault_problem
from hybrid_sysid.physics.eiv.matrices import inverse_diagonal, positive
from hybrid_sysid.physics.eiv.model import CHUNK, error_spectra, frequency_grid, setup_windows, transfer_polynomials
from hybrid_sysid.physics.eiv.newton import MAX_ITER, TOL, minimise
from hybrid_sysid.physics.faults.registry import fix_code
from hybrid_sysid.physics.faults.skew import SkewFix, check_skew_max

P_LO = (0.5, 25.0)  # the default box of (p1, p2): wide around the seats' 2..40 1/s and 100..1500 1/s^2
P_HI = (200.0, 6000.0)


class EivFit(NamedTuple):
    """Per window, float64: ``p`` (n, 2) the fitted (p1, p2); ``se`` (n, 2) their standard errors relative to p
    (of log p); ``sigma2`` (n,) the seat channel's noise variance per sample, estimated from the ML residual;
    ``cost`` (n,) V at p (the criterion, physics.eiv); ``converged`` (n,) whether the step fell below the
    tolerance. A window whose fit is not defined (no excitation, non-finite samples, a singular information matrix)
    has NaN p, sigma2 and cost, infinite se and converged False. ``fault`` (n,) with a fix: the fitted fault, the
    gain ratio g_seat / g_body, the body sensor's delay tau in seconds or the spring's hardening kappa in 1/m^2
    (NaN where the fit is not defined); None without. ``ml``: with a prior, the ML fit the MAP one started from
    (an EivFit itself), so a caller that needs both fits solves the likelihood once; None without."""

    p: np.ndarray
    se: np.ndarray
    sigma2: np.ndarray
    cost: np.ndarray
    converged: np.ndarray
    fault: np.ndarray | None = None
    ml: "EivFit | None" = None


def _box(p_lo, p_hi):
    with np.errstate(invalid="ignore", divide="ignore"):
        lo, hi = np.log(np.asarray(p_lo, dtype=float)), np.log(np.asarray(p_hi, dtype=float))
    if not (lo.shape == hi.shape == (2,) and np.isfinite(lo).all() and np.isfinite(hi).all() and (lo < hi).all()):
        bad("p_lo", f"{p_lo} .. {p_hi}", "two finite values > 0 (p1, p2) each, p_lo < p_hi")
    return lo, hi


def skew_edges(skew_max: float, dt: float) -> tuple[int, int]:
    """The skew fix's lead and lag samples at a window's ends: the advance's reach and its sinc's half width."""
    return SkewFix().eiv_edges(skew_max, dt)


def fix_samples(fix: str, model: str, dt: float, skew_max: float) -> int:
    """The fewest samples a window needs for ``fix``: the transient's basis widened by the fix's edges, plus 4."""
    code = fix_code(fix)
    lead, lag = (0, 0) if code is None else code.eiv_edges(skew_max, dt)
    return lead + lag + transfer_polynomials(model, dt).shape[1] - 1 + 4


def skew_samples(model: str, dt: float, skew_max: float) -> int:
    """The fewest samples a window needs for the skew fix (``fix_samples``)."""
    return fix_samples("skew", model, dt, skew_max)


def fit_eiv(
    seat,
    body,
    dt: float,
    *,
    noise_ratio: float = 1.0,
    model: str = "discrete",
    p0=None,
    p_lo=P_LO,
    p_hi=P_HI,
    prior=None,
    max_iter: int = MAX_ITER,
    tol: float = TOL,
    fix: str = "none",
    skew_max: float = 0.02,
) -> EivFit:
    """The errors-in-variables ML (or MAP) fit of (p1, p2) on every window (n, N) of seat and body acceleration.

    noise_ratio: lambda = sigma_body^2 / sigma_seat^2 (0: output error). model: "discrete" (consistent recordings
    of the simulator) or "continuous" (samples of the continuous motion); see physics.eiv.model.
    p0: the start, (2,) or (n, 2), e.g. the band-passed least squares (seat_fit.fit_windows(...).p); a window whose
    start is NaN or outside the box starts at its centre in log p, as all do with None.
    p_lo, p_hi: the box (p1, p2) the fit stays in. prior: None (ML) or (mean (2,), cov (2, 2)) of log p, e.g. from
    ``log_p_prior``: the MAP fit, started from the ML one and with the ML fit's sigma^2.
    fix: "none", or the recording fault fitted with p as one more parameter (physics.eiv.faults): "gain"
    (the ratio of the sensors' gains), "skew" (the body sensor's time offset, |tau| <= ``skew_max`` seconds),
    "hardening" (a hardening seat spring) or a registered fault's own fix (physics.faults.fixes); the fit's se
    then includes that parameter's uncertainty, and EivFit.fault holds its estimate.
    Float32 windows are taken in float64; a single window (N,) as (1, N). Returns EivFit.
    """
    code = fix_code(fix)
    skew_max = check_skew_max(skew_max)
    seat, body, good, grid, q = setup_windows(seat, body, dt, noise_ratio, model)
    max_iter = check_int("max_iter", max_iter, 1)
    tol = check_number("tol", tol, 0.0, low_open=True)
    lo, hi = _box(p_lo, p_hi)
    n, N = seat.shape
    lam = float(noise_ratio)
    lead, lag = (0, 0) if code is None else code.eiv_edges(skew_max, dt)
    if lead or lag:  # the skew's advance reaches across the window's ends: the transient widens (physics.eiv.faults)
        grid = frequency_grid(model, float(dt), N, lead, lag)
        if N < grid.basis.shape[1] + 4:
            bad("seat", f"windows of {N} samples", f"at least {grid.basis.shape[1] + 4} samples for the {fix} fix")
    dim = 2 if fix == "none" else 3
    dof = N - dim - grid.basis.shape[1]
    if p0 is None:
        theta0 = np.tile(0.5 * (lo + hi), (n, 1))
    else:
        with np.errstate(invalid="ignore", divide="ignore"):
            theta0 = np.log(np.broadcast_to(np.asarray(p0, dtype=float), (n, 2))).copy()
        outside = ~(np.isfinite(theta0) & (theta0 >= lo) & (theta0 <= hi)).all(axis=1)
        theta0[outside] = 0.5 * (lo + hi)
    if prior is not None:
        mean = np.asarray(prior[0], dtype=float)
        cov = np.asarray(prior[1], dtype=float)
        if mean.shape != (2,) or cov.shape != (2, 2) or not (np.isfinite(mean).all() and positive(cov)):
            bad("prior", "(mean, cov)", "a mean (2,) and a positive definite covariance (2, 2) of log p")
        prec = np.linalg.inv(cov)
        if dim == 3:  # no prior on the fault's parameter
            mean, prec = np.append(mean, 0.0), np.pad(prec, ((0, 1), (0, 1)))
    if dim == 3:
        bound = code.eiv_bound(skew_max, dt)  # the hardening's: per window, in its own problem
        lo, hi = np.append(lo, bound[0]), np.append(hi, bound[1])
    out = _Results(n, fix != "none")
    ml = None if prior is None else _Results(n, fix != "none")
    block = max(1, CHUNK // (N // 2 + 1))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for start in range(0, n, block):
            rows = np.arange(start, min(start + block, n))
            rows = rows[good[rows]]
            if not rows.size:
                continue
            if fix == "none":
                E = error_spectra(seat[rows], body[rows], grid)

                def solve(th, prior_=None, kappa_=None, E=E):
                    def evaluate(th, sub):
                        return evaluate_criterion(th, E if sub is None else E[:, sub], grid, q)

                    return minimise(evaluate, th, lo, hi, max_iter, tol, prior_, kappa_)

                theta, to_fault = theta0[rows], None
            else:
                solve, theta, to_fault = fault_problem(
                    code, seat[rows], body[rows], theta0[rows], grid, lam, float(dt), model, lo, hi, max_iter, tol
                )
            theta, V, h, conv = solve(theta)
            kappa = V / dof  # N sigma^2: V's scale in the likelihood
            if prior is not None:
                ml.store(rows, theta, V, h, conv, kappa, N, to_fault)
                # two starts, the ML fit and the prior's mean, the lower posterior kept: where the data leave p
                # loose the ML fit may sit at the box's edge, in another basin than the one the prior favours
                first = solve(theta, (mean, prec), kappa)
                centre = theta.copy()
                centre[:, :2] = np.clip(mean[:2], lo[:2], hi[:2])
                second = solve(centre, (mean, prec), kappa)
                better = _posterior(second, mean, prec, kappa) < _posterior(first, mean, prec, kappa)
                theta, V, h, conv = (
                    np.where(better.reshape((-1,) + (1,) * (a.ndim - 1)), b, a) for a, b in zip(first, second)
                )
                h = h + kappa[:, None, None] * prec
            out.store(rows, theta, V, h, conv, kappa, N, to_fault)
    return out.fit(None if ml is None else ml.fit())


class _Results:
    """The arrays of an EivFit being filled block by block; a window no block fills stays not defined."""

    def __init__(self, n: int, fault: bool):
        self.p, self.se = np.full((n, 2), np.nan), np.full((n, 2), np.inf)
        self.sigma2, self.cost = np.full(n, np.nan), np.full(n, np.nan)
        self.converged = np.zeros(n, bool)
        self.fault = np.full(n, np.nan) if fault else None

    def store(self, rows, theta, V, h, conv, kappa, N, to_fault):
        """Keep the solution of ``rows`` where it is defined: a positive Hessian, finite theta and V."""
        ok = positive(h) & np.isfinite(theta).all(axis=1) & np.isfinite(V) & (kappa >= 0)
        if self.fault is not None:
            self.fault[rows[ok]] = to_fault(theta)[ok]
        rows, theta, V, h, conv, kappa = rows[ok], theta[ok], V[ok], h[ok], conv[ok], kappa[ok]
        self.p[rows] = np.exp(theta[:, :2])
        self.se[rows] = np.sqrt(kappa[:, None] * inverse_diagonal(h)[:, :2])
        self.sigma2[rows] = kappa / N
        self.cost[rows] = V
        self.converged[rows] = conv

    def fit(self, ml: EivFit | None = None) -> EivFit:
        return EivFit(self.p, self.se, self.sigma2, self.cost, self.converged, self.fault, ml)


def _posterior(solved, mean, prec, kappa):
    """The MAP criterion V + kappa (theta - mean)' prec (theta - mean) of ``solve``'s result, per window; inf where
    the fit failed."""
    theta, V = solved[0], solved[1]
    d = theta - mean
    out = V + kappa * np.einsum("ni,ij,nj->n", d, prec, d)
    return np.where(np.isfinite(out), out, np.inf)
