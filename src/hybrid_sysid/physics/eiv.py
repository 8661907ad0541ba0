"""Errors-in-variables maximum likelihood of the seat's (p1, p2) from windows of both noisy channels (plain numpy).

The band-passed least squares (physics.seat_fit) regresses the seat acceleration on re-integrated regressors that
carry the body channel's noise, so its p is biased towards zero as the noise grows. Here the seat's transfer
function from body acceleration U to seat acceleration S is fitted in the frequency domain with noise on both
channels (Pintelon and Schoukens, "System Identification: A Frequency Domain Approach"; Soderstrom,
"Errors-in-variables methods in system identification", Automatica 43, 2007).

The model, per window of N samples, with S_k, U_k the DFT (unnormalised, k = 0..N-1) and z_k = exp(2 pi i k / N):

    A_k S_k - B_k U_k = I_k + noise,      I_k = i0 + i1 z_k^-1 + ... + i_{m-1} z_k^-(m-1), i real

where A(z), B(z) are polynomials in z^-1 whose coefficients are affine in p: A = a0 + p1 a1 + p2 a2 and
B = p1 b1 + p2 b2. I is not an approximation: A(q) s = B(q) u holds inside the window, and the circular convolution
the DFT takes differs from it only in its first m samples, where it reaches back across the window's edge; those
m values (real) are I's coefficients. White noise of std sigma_s on the seat and sigma_b on the body samples enters
as A N_s - B N_u, whose DFT is (exactly, the convolution being circular) independent over k <= N/2 with variance
N sigma_s^2 W_k, W_k = |A_k|^2 + lambda |B_k|^2, lambda = sigma_b^2 / sigma_s^2. The negative log-likelihood of
the window, maximised over the true input (a nuisance parameter at every frequency), is then, up to a constant,

    V(p) / (2 N sigma_s^2),    V(p) = sum_k |A_k S_k - B_k U_k - I_k|^2 / W_k    (sum over the full grid)

(Parseval: the full grid's sum of |DFT|^2 is N times the time domain's sum of squares). I is eliminated by
variable projection: for given p it is the weighted least squares in its m real coefficients. Computed on the half
spectrum with the weights 1 (DC, Nyquist) and 2 (the rest), which is the same sum. lambda = 0 is output error: V is
then N times the time-domain sum of squared output errors, minimised over the free initial conditions too.

Models (``model``):

- "discrete": the simulator's symplectic Euler step with the "consistent" recording, derived from
  quarter_car.step: with r_k = w_k - v_k and d_k = z_k - y_k, S_k = -p1 (r_k - dt U_k) - p2 d_k,
  r_{k+1} = r_k + dt (S_k - U_k), d_{k+1} = d_k + dt r_{k+1}, so that S[k] pairs with U[k] (no delay):
  A = 1 + (p1 dt + p2 dt^2 - 2) z^-1 + (1 - p1 dt) z^-2, B = p1 dt + (p2 dt^2 - p1 dt) z^-1, m = 2. Exact: a clean
  consistent window gives p to rounding.
- "continuous": recordings that sample the continuous motion (physics.exact) obey
  G(s) = (p1 s + p2) / (s^2 + p1 s + p2) at s = i omega, and no rational function of z reproduces that exactly.
  s is replaced by a rational approximation of ln(z) / dt = (2 / dt) artanh(w), w = (1 - z^-1) / (1 + z^-1),
  the [5/4] Pade approximant of artanh in w:

      s ~ (2 / dt) w (945 - 735 w^2 + 64 w^4) / (945 - 1050 w^2 + 225 w^4),

  and A, B are s^2 + p1 s + p2 and p1 s + p2 times the denominator squared: polynomials of degree 10 in z^-1, so
  m = 10 transient coefficients, and the noise model stays exact. On the unit circle the map is purely imaginary
  (no damping error) with a relative frequency error of 1e-11 at 10 Hz, 2e-8 at 20 Hz and 7e-5 at 45 Hz at
  dt = 5 ms (the road's highest frequency at 15 m/s is 45 Hz). Measured on clean exact recordings (5 road classes
  x 6 recordings, m3 in 50..200 kg, C3 and K3 spread by 30%, 90 windows of 500 samples at random starts,
  dt = 5 ms): relative error of p mean 1.2e-10 / 1.9e-11 (p1 / p2), worst 1.3e-9 / 2.6e-10; band-passed least
  squares (fit_windows, 4-20 Hz, 151 taps) on the same windows: mean 1.4e-5 / 2.3e-5, worst 5.4e-5 / 8.7e-5. The
  lower-order maps were measured too: Tustin (m = 2) 0.2% / 0.4%, the [3/2] approximant (m = 6) 3e-8 / 3e-8. Ten
  transient coefficients instead of four (the [1/2] approximant) cost 0.3% in the Cramer-Rao bound of these windows.
  The alternative of evaluating A and B at s_k = i omega_k leaves the leakage term a non-polynomial function of
  k (the DFT of a sampled window aliases its edge jumps), which a polynomial I models only approximately.

Fit: theta = log p, for all windows at once, inside the box [log p_lo, log p_hi]. Each iteration takes a damped
Newton step with the exact Hessian of the projected V (analytic), or the Gauss-Newton one where the exact Hessian is
not positive definite, with Marquardt damping per window, steps clipped to the box and a coordinate held on a bound
its gradient pushes against. The exact Hessian is there because V is a large-residual problem on weakly informative
windows: Gauss-Newton overestimated the curvature there (8 times on one such window) and crept towards the minimum,
leaving 20% of noisy windows (std 0.1, 500 samples, classes A to E) unconverged after 50 iterations; with the exact
Hessian 2% stay so, all of them windows whose fit runs to the box's edge. Converged: the full step is below ``tol``
in theta (relative in p); the last, unchecked step is taken too. On clean windows the fit reaches p to rounding
(1e-13).

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

Measured on one core (400 windows of 500 samples, noise 0.01 on both channels, started at the band-passed least
squares; best of 3 on a shared machine): ML 0.10 s discrete, 0.14 s continuous; MAP (ML then MAP) 0.20 and 0.23 s.
From the box centre ML takes 0.26 s; the band-passed least squares 0.02 s.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numpy.polynomial import polynomial as poly

from hybrid_sysid.core.checks import bad, check_choice, check_int, check_number, check_positive

MODELS = ("discrete", "continuous")
P_LO = (0.5, 25.0)  # the default box of (p1, p2): wide around the seats' 2..40 1/s and 100..1500 1/s^2
P_HI = (200.0, 6000.0)
TOL = 1e-10
MAX_ITER = 50
CHUNK = 1 << 17  # windows x frequencies in one block: bounds the ~40 arrays of that size an iteration makes

# artanh(w) / w ~ (1 - 735 t / 945 + 64 t^2 / 945) / (1 - 1050 t / 945 + 225 t^2 / 945), t = w^2: its [2/2] Pade
# approximant, the continuous model's map from z to s (module docstring)
_PADE_NUM = (1.0, -735.0 / 945.0, 64.0 / 945.0)
_PADE_DEN = (1.0, -1050.0 / 945.0, 225.0 / 945.0)


class EivFit(NamedTuple):
    """Per window, float64: ``p`` (n, 2) the fitted (p1, p2); ``se`` (n, 2) their standard errors relative to p
    (of log p); ``sigma2`` (n,) the seat channel's noise variance per sample, estimated from the ML residual;
    ``cost`` (n,) V at p (the criterion, module docstring); ``converged`` (n,) whether the step fell below the
    tolerance. A window whose fit is not defined (no excitation, non-finite samples, a singular information matrix)
    has NaN p, sigma2 and cost, infinite se and converged False."""

    p: np.ndarray
    se: np.ndarray
    sigma2: np.ndarray
    cost: np.ndarray
    converged: np.ndarray


class _Grid(NamedTuple):
    weight: np.ndarray  # (K,) the half spectrum's multiplicity in the full grid: 1 at DC and Nyquist, else 2
    polys: np.ndarray  # (5, K) complex: a0, a1, a2, b1, b2 on the grid
    basis: np.ndarray  # (K, m) complex: z^-j, j < m, the transient's polynomial
    cos: np.ndarray  # (K, m) its real part: the transient's normal matrix is Toeplitz in sum w cos(j theta_k)
    toeplitz: np.ndarray  # (m, m) |i - j|


def _coefficients(model: str, dt: float) -> np.ndarray:
    """a0, a1, a2, b1, b2 as polynomials in z^-1 (ascending powers), rows of one length m + 1."""
    if model == "discrete":
        return np.array(
            [
                [1.0, -2.0, 1.0],
                [0.0, dt, -dt],
                [0.0, dt * dt, 0.0],
                [dt, -dt, 0.0],
                [0.0, dt * dt, 0.0],
            ]
        )
    # dt s = 2 num / den with w = (1 - x) / (1 + x), x = z^-1, both brought to degree d over (1 + x)^d
    d = max(2 * len(_PADE_NUM) - 1, 2 * len(_PADE_DEN) - 2)
    nw, dw = np.array([1.0, -1.0]), np.array([1.0, 1.0])

    def homogeneous(coef, odd):
        terms = [
            c * poly.polymul(poly.polypow(nw, 2 * j + odd), poly.polypow(dw, d - 2 * j - odd))
            for j, c in enumerate(coef)
        ]
        return np.sum([np.pad(t, (0, d + 1 - len(t))) for t in terms], axis=0)

    num, den = 2.0 * homogeneous(_PADE_NUM, 1), homogeneous(_PADE_DEN, 0)
    # (s^2 + p1 s + p2) den^2 dt^2 and (p1 s + p2) den^2 dt^2: scaled like the discrete model's
    a1 = dt * poly.polymul(num, den)
    a2 = dt * dt * poly.polymul(den, den)
    return np.stack([poly.polymul(num, num), a1, a2, a1, a2])


@lru_cache(maxsize=16)
def _grid(model: str, dt: float, n_samples: int) -> _Grid:
    coef = _coefficients(model, dt)
    m = coef.shape[1] - 1
    k = np.arange(n_samples // 2 + 1)
    x = np.exp(-2j * np.pi * k / n_samples)
    weight = np.full(len(k), 2.0)
    weight[0] = 1.0
    if n_samples % 2 == 0:
        weight[-1] = 1.0
    basis = x[:, None] ** np.arange(m)
    j = np.arange(m)
    polys = np.stack([poly.polyval(x, c) for c in coef])
    grid = _Grid(weight, polys, basis, basis.real.copy(), np.abs(j[:, None] - j[None, :]))
    for array in grid:  # shared by every call through the cache
        array.flags.writeable = False
    return grid


def _quadratic(grid: _Grid, lam: float) -> np.ndarray:
    """W = |A|^2 + lam |B|^2 = q0 + 2 p1 q1 + 2 p2 q2 + p1^2 q3 + 2 p1 p2 q4 + p2^2 q5 on the grid: (6, K)."""
    a0, a1, a2, b1, b2 = grid.polys

    def dot(u, v):
        return (u.conj() * v).real

    return np.stack(
        [
            dot(a0, a0),
            dot(a0, a1),
            dot(a0, a2),
            dot(a1, a1) + lam * dot(b1, b1),
            dot(a1, a2) + lam * dot(b1, b2),
            dot(a2, a2) + lam * dot(b2, b2),
        ]
    )


def _weight(p, q):
    p1, p2 = p[:, :1], p[:, 1:]
    return q[0] + p1 * (2.0 * q[1] + p1 * q[3]) + p2 * (2.0 * q[2] + 2.0 * p1 * q[4] + p2 * q[5])


def _spectra(seat, body, grid):
    """E0, E1, E2 (3, n, K): A S - B U = E0 + p1 E1 + p2 E2 is affine in p."""
    s, u = np.fft.rfft(seat, axis=-1), np.fft.rfft(body, axis=-1)
    a0, a1, a2, b1, b2 = grid.polys
    return np.stack([a0 * s, a1 * s - b1 * u, a2 * s - b2 * u])


def _re_sum(a, b):
    return np.einsum("nk,nk->n", a, b).real


def _schur(h, b, t):
    """h - b t^-1 b^T: (n, 2, 2) with the transient's (n, 2, m) coupling b and (n, m, m) normal matrix t."""
    return h - b @ np.linalg.solve(t, b.transpose(0, 2, 1))


def _evaluate(theta, E, grid, q, derivatives=True):
    """V at theta = log p for every window of E; with ``derivatives`` also the half gradient g, the Gauss-Newton
    Hessian and the exact Hessian (V(theta + d) ~ V + 2 g^T d + d^T H d), the transient projected out of both."""
    p = np.exp(theta)
    p1, p2 = p[:, :1], p[:, 1:]
    W = _weight(p, q)
    w = grid.weight / W
    e = E[0] + p1 * E[1] + p2 * E[2]
    T = (w @ grid.cos)[:, grid.toeplitz]
    c = np.linalg.solve(T, ((w * e) @ grid.basis.conj()).real[..., None])[..., 0]
    eps = e - c @ grid.basis.T
    eps2 = eps.real**2 + eps.imag**2
    V = np.einsum("nk,nk->n", w, eps2)
    if not derivatives:
        return V, None, None, None
    # dW/dp_i / W and d2W/dp_i dp_j (constant in p)
    dW = (2.0 * (q[1] + p1 * q[3] + p2 * q[4]) / W, 2.0 * (q[2] + p1 * q[4] + p2 * q[5]) / W)
    d2W = ((2.0 * q[3], 2.0 * q[4]), (2.0 * q[4], 2.0 * q[5]))
    # The residual's Jacobian in p is F_i / sqrt(W) at fixed transient; the exact Hessian of V needs the
    # transient's coupling through G_i, F_i's derivative in the transient's coefficients
    F = [E[i + 1] - 0.5 * eps * dW[i] for i in range(2)]
    G = [E[i + 1] - eps * dW[i] for i in range(2)]
    wF = [w * f.conj() for f in F]
    wE = [w * E[i + 1].conj() for i in range(2)]
    wc = w * eps.conj()
    n = len(p)
    g = np.stack([_re_sum(wc, F[i]) for i in range(2)], axis=1)
    gn, ex = np.empty((n, 2, 2)), np.empty((n, 2, 2))
    for i in range(2):
        for j in range(i, 2):
            gn[:, i, j] = gn[:, j, i] = _re_sum(wF[i], F[j])
            ex[:, i, j] = ex[:, j, i] = (
                _re_sum(wE[i], E[j + 1])
                - _re_sum(wc * dW[j], E[i + 1])
                - _re_sum(wc * dW[i], E[j + 1])
                + np.einsum("nk,nk->n", w * eps2, dW[i] * dW[j] - 0.5 * d2W[i][j] / W)
            )
    gn = _schur(gn, np.stack([(wF[i] @ grid.basis).real for i in range(2)], axis=1), T)
    ex = _schur(ex, np.stack([((w * G[i]) @ grid.basis.conj()).real for i in range(2)], axis=1), T)
    scale = p[:, :, None] * p[:, None, :]  # d/dtheta_i = p_i d/dp_i
    g = g * p
    ex = ex * scale
    ex[:, 0, 0] += g[:, 0]
    ex[:, 1, 1] += g[:, 1]
    return V, g, gn * scale, ex


def _positive(h):
    """Whether each (2, 2) matrix is positive definite, with a margin for rounding."""
    a, b, d = h[..., 0, 0], h[..., 0, 1], h[..., 1, 1]
    return (a > 0) & (d > 0) & (a * d - b * b > 1e-12 * a * d)


def _solve2(h, g):
    """h^-1 g for (n, 2, 2) and (n, 2); NaN where h is not positive definite."""
    a, b, d = h[:, 0, 0], h[:, 0, 1], h[:, 1, 1]
    x = np.stack([d * g[:, 0] - b * g[:, 1], a * g[:, 1] - b * g[:, 0]], axis=1) / (a * d - b * b)[:, None]
    x[~_positive(h)] = np.nan
    return x


def _inverse_diagonal(h):
    a, b, d = h[:, 0, 0], h[:, 0, 1], h[:, 1, 1]
    return np.stack([d, a], axis=1) / (a * d - b * b)[:, None]


def _minimise(E, grid, q, theta, lo, hi, max_iter, tol, prior=None, kappa=None):
    """Minimise V + kappa (theta - mean)^T prec (theta - mean) per window (prior = (mean, prec) or None) from
    theta (n, 2) inside [lo, hi]. Returns theta, V, the Gauss-Newton Hessian of V and the converged flags."""
    n = len(theta)
    mean, prec = prior if prior is not None else (np.zeros(2), np.zeros((2, 2)))
    kappa = np.zeros(n) if kappa is None else kappa

    def objective(V, th, kap):
        d = th - mean
        return V + kap * np.einsum("ni,ij,nj->n", d, prec, d)

    V, g, gn, ex = _evaluate(theta, E, grid, q)
    obj = objective(V, theta, kappa)
    damping = np.full(n, 1e-4)
    done = ~np.isfinite(obj)
    converged = np.zeros(n, bool)
    eye = np.eye(2)
    for _ in range(max_iter):
        act = np.flatnonzero(~done)
        if not act.size:
            break
        th, kap = theta[act], kappa[act]
        newton = _positive(ex[act])[:, None, None]
        h = np.where(newton, ex[act], gn[act]) + kap[:, None, None] * prec
        grad = g[act] + kap[:, None] * ((th - mean) @ prec)
        # a coordinate on a bound whose gradient pushes outwards stays there: the step is the other's alone
        held = ((th <= lo) & (grad > 0)) | ((th >= hi) & (grad < 0))
        h = np.where(held[:, :, None] | held[:, None, :], eye, h)
        grad = np.where(held, 0.0, grad)
        newton_point = np.clip(th - _solve2(h, grad), lo, hi)
        full = np.max(np.abs(newton_point - th), axis=1)
        stop = full <= tol
        # the last step is taken unchecked: it is below the tolerance, and on clean data it brings p from
        # within 1e-10 to rounding
        theta[act[stop]] = newton_point[stop]
        converged[act[stop]] = True
        done[act[stop | ~np.isfinite(full)]] = True
        go = np.isfinite(full) & ~stop
        act, th, h, grad = act[go], th[go], h[go], grad[go]
        if not act.size:
            break
        cand = np.clip(th - _solve2(h + damping[act, None, None] * (h * eye), grad), lo, hi)
        Vc, gc, gnc, exc = _evaluate(cand, E[:, act], grid, q)
        objc = objective(Vc, cand, kappa[act])
        # a tie within rounding is taken: near the minimum V's change drops below its last digits long before
        # the step reaches the tolerance, and refusing it would only grow the damping
        better = np.isfinite(objc) & (objc <= obj[act] * (1.0 + 1e-14))
        idx, worse = act[better], act[~better]
        theta[idx], V[idx], g[idx], gn[idx], ex[idx], obj[idx] = (
            cand[better],
            Vc[better],
            gc[better],
            gnc[better],
            exc[better],
            objc[better],
        )
        damping[idx] = np.maximum(damping[idx] * 0.1, 1e-12)
        damping[worse] *= 10.0
        small = np.max(np.abs(cand[better] - th[better]), axis=1) <= tol
        converged[idx[small]] = True
        done[idx[small]] = True
        done[worse[damping[worse] > 1e12]] = True  # no step decreases the objective: stuck, not converged
    return theta, V, gn, converged


def _windows(seat, body):
    seat = np.asarray(seat, dtype=np.float64)
    body = np.asarray(body, dtype=np.float64)
    if seat.ndim == 1 and body.ndim == 1:
        seat, body = seat[None], body[None]
    if seat.ndim != 2 or seat.shape != body.shape:
        bad("body", f"shape {body.shape}", f"the seat's shape {seat.shape}, windows (n, N)")
    good = np.isfinite(seat).all(axis=1) & np.isfinite(body).all(axis=1)
    seat = np.where(good[:, None], seat, 0.0)
    body = np.where(good[:, None], body, 0.0)
    good &= (seat != 0).any(axis=1) | (body != 0).any(axis=1)
    return seat, body, good


def _setup(seat, body, dt, noise_ratio, model):
    check_choice("model", model, MODELS)
    dt = check_positive("dt", dt, "seconds")
    lam = check_number("noise_ratio", noise_ratio, 0.0)
    seat, body, good = _windows(seat, body)
    grid = _grid(model, dt, seat.shape[1])
    m = grid.basis.shape[1]
    if seat.shape[1] < m + 3:
        bad("seat", f"windows of {seat.shape[1]} samples", f"at least {m + 3} samples for the {model} model")
    return seat, body, good, grid, _quadratic(grid, lam)


def _box(p_lo, p_hi):
    with np.errstate(invalid="ignore", divide="ignore"):
        lo, hi = np.log(np.asarray(p_lo, dtype=float)), np.log(np.asarray(p_hi, dtype=float))
    if not (lo.shape == hi.shape == (2,) and np.isfinite(lo).all() and np.isfinite(hi).all() and (lo < hi).all()):
        bad("p_lo", f"{p_lo} .. {p_hi}", "two finite values > 0 (p1, p2) each, p_lo < p_hi")
    return lo, hi


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
) -> EivFit:
    """The errors-in-variables ML (or MAP) fit of (p1, p2) on every window (n, N) of seat and body acceleration.

    noise_ratio: lambda = sigma_body^2 / sigma_seat^2 (0: output error). model: "discrete" (consistent recordings
    of the simulator) or "continuous" (samples of the continuous motion); see the module docstring.
    p0: the start, (2,) or (n, 2), e.g. the band-passed least squares (seat_fit.fit_windows(...).p); a window whose
    start is NaN or outside the box starts at its centre in log p, as all do with None.
    p_lo, p_hi: the box (p1, p2) the fit stays in. prior: None (ML) or (mean (2,), cov (2, 2)) of log p, e.g. from
    ``log_p_prior``: the MAP fit, started from the ML one and with the ML fit's sigma^2.
    Float32 windows are taken in float64; a single window (N,) as (1, N). Returns EivFit.
    """
    seat, body, good, grid, q = _setup(seat, body, dt, noise_ratio, model)
    max_iter = check_int("max_iter", max_iter, 1)
    tol = check_number("tol", tol, 0.0, low_open=True)
    lo, hi = _box(p_lo, p_hi)
    n, N = seat.shape
    dof = N - 2 - grid.basis.shape[1]
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
        if mean.shape != (2,) or cov.shape != (2, 2) or not (np.isfinite(mean).all() and _positive(cov)):
            bad("prior", "(mean, cov)", "a mean (2,) and a positive definite covariance (2, 2) of log p")
        prec = np.linalg.inv(cov)
    p = np.full((n, 2), np.nan)
    se = np.full((n, 2), np.inf)
    sigma2, cost = np.full(n, np.nan), np.full(n, np.nan)
    converged = np.zeros(n, bool)
    block = max(1, CHUNK // (N // 2 + 1))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for start in range(0, n, block):
            rows = np.arange(start, min(start + block, n))
            rows = rows[good[rows]]
            if not rows.size:
                continue
            E = _spectra(seat[rows], body[rows], grid)
            theta, V, h, conv = _minimise(E, grid, q, theta0[rows], lo, hi, max_iter, tol)
            kappa = V / dof  # N sigma^2: V's scale in the likelihood
            if prior is not None:
                theta, V, h, conv = _minimise(E, grid, q, theta, lo, hi, max_iter, tol, (mean, prec), kappa)
                h = h + kappa[:, None, None] * prec
            ok = _positive(h) & np.isfinite(theta).all(axis=1) & np.isfinite(V) & (kappa >= 0)
            rows, theta, V, h, conv, kappa = rows[ok], theta[ok], V[ok], h[ok], conv[ok], kappa[ok]
            p[rows] = np.exp(theta)
            se[rows] = np.sqrt(kappa[:, None] * _inverse_diagonal(h))
            sigma2[rows] = kappa / N
            cost[rows] = V
            converged[rows] = conv
    return EivFit(p, se, sigma2, cost, converged)


def crb_relative_std(seat_clean, body_clean, p_true, dt: float, noise_ratio: float = 1.0, model: str = "discrete"):
    """The Cramer-Rao bound of std(p_i) / p_i per unit seat noise std (sigma_s = 1; the bound is linear in it),
    (n, 2), for white noise on both channels with sigma_b^2 = noise_ratio sigma_s^2 (0: on the seat alone).

    seat_clean, body_clean: the noise-free windows (n, N); p_true (2,) or (n, 2). The true input and the
    transient's coefficients are nuisance parameters: the Fisher information of log p is the Gauss-Newton Hessian
    of V / N at the clean data and the true p, with the transient projected out (its Schur complement); the input's
    elimination is what the division by W = |A|^2 + lambda |B|^2 does. A window without excitation gives inf.
    """
    seat, body, good, grid, q = _setup(seat_clean, body_clean, dt, noise_ratio, model)
    n, N = seat.shape
    p_all = np.broadcast_to(np.asarray(p_true, dtype=float), (n, 2))
    out = np.full((n, 2), np.inf)
    block = max(1, CHUNK // (N // 2 + 1))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for start in range(0, n, block):
            rows = np.arange(start, min(start + block, n))
            rows = rows[good[rows] & (p_all[rows] > 0).all(axis=1) & np.isfinite(p_all[rows]).all(axis=1)]
            if not rows.size:
                continue
            E = _spectra(seat[rows], body[rows], grid)
            p = p_all[rows]
            w = grid.weight / _weight(p, q)
            T = (w @ grid.cos)[:, grid.toeplitz]
            # on clean data the residual vanishes at the true p: the Jacobian is p_i E_i / sqrt(W)
            F = [p[:, i : i + 1] * E[i + 1] for i in range(2)]
            wF = [w * f.conj() for f in F]
            h = np.empty((len(rows), 2, 2))
            for i in range(2):
                for j in range(i, 2):
                    h[:, i, j] = h[:, j, i] = _re_sum(wF[i], F[j])
            h = _schur(h, np.stack([(wF[i] @ grid.basis).real for i in range(2)], axis=1), T)
            ok = _positive(h)
            out[rows[ok]] = np.sqrt(N * _inverse_diagonal(h[ok]))
    return out


def log_p_prior(m3_min, m3_max, c3, k3, seat_spread, n: int = 200000, seed=0):
    """(mean (2,), cov (2, 2)) of log p = log(c3 / m3, k3 / m3) by Monte Carlo over the data's draws: m3 an
    integer uniform in [m3_min, m3_max], C3 = c3 U(1 - s, 1 + s) and K3 = k3 U(1 - s, 1 + s), s = seat_spread."""
    m3_min = check_int("m3_min", m3_min, 1)
    m3_max = check_int("m3_max", m3_max, m3_min)
    c3, k3 = check_positive("c3", c3), check_positive("k3", k3)
    spread = check_number("seat_spread", seat_spread, 0.0, 1.0, high_open=True)
    n = check_int("n", n, 2)
    rng = np.random.default_rng(seed)
    m3 = rng.integers(m3_min, m3_max + 1, size=n).astype(float)
    log_p = np.stack(
        [
            np.log(c3 * rng.uniform(1.0 - spread, 1.0 + spread, size=n) / m3),
            np.log(k3 * rng.uniform(1.0 - spread, 1.0 + spread, size=n) / m3),
        ],
        axis=1,
    )
    return log_p.mean(axis=0), np.cov(log_p, rowvar=False)
