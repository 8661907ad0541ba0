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

Fixes (``fix``, docs/faults.md): a recording fault is one more parameter eta of the same likelihood, fitted with p
by the same damped Newton in theta = (log p1, log p2, eta) with the exact 3 x 3 Hessian (``_evaluate_fault``). The
se of p are then the marginals of the 3 x 3 inverse, so they include eta's uncertainty; the Cramer-Rao bound
(``crb_relative_std``) stays the plain model's, the bound of a recording without the fault.

- "gain": each sensor's gain unknown, the seat recorded as g_s s, the body as g_b u. Then A S = g B U + I with
  g = g_s / g_b, eta = log g within GAIN_BOX. The noise is the recorded channels' (the simulator adds it after the
  gain), so W = |A|^2 + lambda g^2 |B|^2 with lambda = noise_ratio their variance ratio as recorded; noise that
  a sensor's gain scales too would make that ratio lambda_sensors / g^2, and W the plain |A|^2 + lambda |B|^2.
  Exact: clean windows give p and g to rounding.
- "skew": the body sensor late by tau, |tau| <= skew_max. The body is advanced by d = tau / dt samples,
  A S = H_d B U + I with H_d(z) = sum_p K(p - d) z^p, K the Kaiser-windowed sinc of physics.sensors over
  |p - d| < h + 1 (h = SKEW_HALF_WIDTH: 18 taps). Not e^(i omega tau): on a window's DFT that is the periodic sinc,
  whose error at the window's ends decays as 1 / n through the whole window (at the true tau, 40 clean windows:
  0.2% on p1 in the mean, 1.7% at worst). The windowed kernel's circular convolution differs from the true advance
  only in the first and last h + |d| + 1 samples, and the transient I widened to z^-j, -lead <= j < m + lag
  (lead = floor(D) + h + 1, lag = ceil(D) + h, D = skew_max / dt) absorbs that exactly: 2 h + 1 + 2 D more nuisance
  coefficients (25 at skew_max = 20 ms and dt = 5 ms), the information of about as many samples. What remains is
  the kernel's error in the band (docs/faults.md: 5e-6 of the signal at h = 8): p within 3e-7 on clean skewed
  windows, tau within 1e-8 s. The advanced body's noise is H_d's, W = |A|^2 + lambda |H_d|^2 |B|^2. The start:
  V along offsets one sample apart over [-D, D] at the starting p, then the joint Newton. A low-pass that differs
  between the sensors (the lowpass fault) is a delay only approximately, and the fit reads the one that best
  explains the whole band, where least squares' fix reads it in 4-20 Hz.
- "hardening": a seat spring K3 (d + kappa d^3). Its cubic force is not a transfer function, but it enters the
  stepped recording exactly as an input force would: A S - B U = a0 F + I with F_k = -c d_k^3, c = p2 kappa and
  a0 = (1 - z^-1)^2 (the continuous model's a0 likewise). That is an equation-error term with d from the data:
  ``_displacement`` solves the seat equation for d from the seat channel, a stable first-order recursion that is
  exact on clean recordings, where the double integral of both channels would carry their noise as a drift of
  millimetres over a window (the stroke is about 1 mm on class E roads). eta = kappa mean(d^2), the spring's
  stiffening at the window's rms stroke, |kappa| <= KAPPA_MAX. As d follows (p, c), the fit alternates: the cubic
  term at a round's start x, the fit T(x) from there; the true (p, c) is the fixed point on clean data, which
  Anderson's extrapolation over the last rounds reaches in 6-13 rounds. On clean consistent windows p to 1e-11.
  Under noise it is approximate: d carries the seat's noise delta, and the regressor's 3 c d^2 delta is correlated
  with the residual. Left out of W and kappa unbounded, the fit uses the cubic term to explain the seat's noise
  (noise 0.01, classes B to E: p2 off by 5% in the mean, kappa up to 1e5 times the truth on class B). Its linear
  part at the mean stroke enters W, A -> A - 3 c mean(d^2) a0 / (p1 s + p2 + 3 c mean(d^2)), and the box on kappa
  bounds what remains. The alternative of the linear model's fit started from least squares with the hardening
  fix would not do: its minimum is the linear model's, the stiffness at the window's amplitude, wherever it starts.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numpy.polynomial import polynomial as poly

from hybrid_sysid.core.checks import bad, check_choice, check_int, check_number, check_positive
from hybrid_sysid.core.options import FIXES
from hybrid_sysid.physics.sensors import BETA_MAX, BETA_PER_TAP

MODELS = ("discrete", "continuous")
P_LO = (0.5, 25.0)  # the default box of (p1, p2): wide around the seats' 2..40 1/s and 100..1500 1/s^2
P_HI = (200.0, 6000.0)
TOL = 1e-10
MAX_ITER = 50
CHUNK = 1 << 17  # windows x frequencies in one block: bounds the ~40 arrays of that size an iteration makes
SKEW_HALF_WIDTH = 8  # the skew fix's advance: a Kaiser-windowed sinc of 2 x 8 + 2 taps (module docstring)
SKEW_STEP = 1.0  # samples between the offsets of the skew's coarse search over [-skew_max, skew_max]
GAIN_BOX = (1.0 / 3.0, 3.0)  # g = g_seat / g_body
KAPPA_MAX = 1e6  # 1/m^2, |kappa| of the hardening fix: a spring twice as stiff at 1 mm (car=hardening_seat: 35000)
HARDENING_ROUNDS = 30
ANDERSON_MEMORY = 3
DISPLACEMENT_PASSES = 4

# artanh(w) / w ~ (1 - 735 t / 945 + 64 t^2 / 945) / (1 - 1050 t / 945 + 225 t^2 / 945), t = w^2: its [2/2] Pade
# approximant, the continuous model's map from z to s (module docstring)
_PADE_NUM = (1.0, -735.0 / 945.0, 64.0 / 945.0)
_PADE_DEN = (1.0, -1050.0 / 945.0, 225.0 / 945.0)


class EivFit(NamedTuple):
    """Per window, float64: ``p`` (n, 2) the fitted (p1, p2); ``se`` (n, 2) their standard errors relative to p
    (of log p); ``sigma2`` (n,) the seat channel's noise variance per sample, estimated from the ML residual;
    ``cost`` (n,) V at p (the criterion, module docstring); ``converged`` (n,) whether the step fell below the
    tolerance. A window whose fit is not defined (no excitation, non-finite samples, a singular information matrix)
    has NaN p, sigma2 and cost, infinite se and converged False. ``fault`` (n,) with a fix: the fitted fault, the
    gain ratio g_seat / g_body, the body sensor's delay tau in seconds or the spring's hardening kappa in 1/m^2
    (NaN where the fit is not defined); None without."""

    p: np.ndarray
    se: np.ndarray
    sigma2: np.ndarray
    cost: np.ndarray
    converged: np.ndarray
    fault: np.ndarray | None = None


class _Grid(NamedTuple):
    weight: np.ndarray  # (K,) the half spectrum's multiplicity in the full grid: 1 at DC and Nyquist, else 2
    polys: np.ndarray  # (5, K) complex: a0, a1, a2, b1, b2 on the grid
    basis: np.ndarray  # (K, M) complex: z^-j, -lead <= j < m + lag, the transient's polynomial
    cos: np.ndarray  # (K, M) cos(j theta_k), j < M: the transient's normal matrix is Toeplitz in sum w cos(j theta_k)
    toeplitz: np.ndarray  # (M, M) |i - j|


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
def _grid(model: str, dt: float, n_samples: int, lead: int = 0, lag: int = 0) -> _Grid:
    """The frequency grid of windows of n_samples, the transient's basis widened by ``lead`` powers of z and
    ``lag`` more of z^-1 (the skew fix's edges)."""
    coef = _coefficients(model, dt)
    m = coef.shape[1] - 1
    k = np.arange(n_samples // 2 + 1)
    x = np.exp(-2j * np.pi * k / n_samples)
    weight = np.full(len(k), 2.0)
    weight[0] = 1.0
    if n_samples % 2 == 0:
        weight[-1] = 1.0
    basis = x[:, None] ** np.arange(-lead, m + lag)
    j = np.arange(basis.shape[1])
    cos = basis.real.copy() if lead == 0 else (x[:, None] ** j).real
    polys = np.stack([poly.polyval(x, c) for c in coef])
    grid = _Grid(weight, polys, basis, cos, np.abs(j[:, None] - j[None, :]))
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
    """Whether each (2, 2) or (3, 3) matrix is positive definite, with a margin for rounding."""
    a, b, d = h[..., 0, 0], h[..., 0, 1], h[..., 1, 1]
    ok = (a > 0) & (d > 0) & (a * d - b * b > 1e-12 * a * d)
    if h.shape[-1] == 2:
        return ok
    with np.errstate(invalid="ignore", over="ignore"):
        return ok & (h[..., 2, 2] > 0) & (np.linalg.det(h) > 1e-12 * (a * d - b * b) * h[..., 2, 2])


def _solve(h, g):
    """h^-1 g for (n, P, P) and (n, P), P = 2 or 3; NaN where h is not positive definite."""
    if h.shape[-1] != 2:
        ok = _positive(h)
        x = np.full(g.shape, np.nan)
        if ok.any():
            x[ok] = np.linalg.solve(h[ok], g[ok][..., None])[..., 0]
        return x
    a, b, d = h[:, 0, 0], h[:, 0, 1], h[:, 1, 1]
    x = np.stack([d * g[:, 0] - b * g[:, 1], a * g[:, 1] - b * g[:, 0]], axis=1) / (a * d - b * b)[:, None]
    x[~_positive(h)] = np.nan
    return x


def _inverse_diagonal(h):
    if h.shape[-1] != 2:
        return np.diagonal(np.linalg.inv(h), axis1=1, axis2=2)
    a, b, d = h[:, 0, 0], h[:, 0, 1], h[:, 1, 1]
    return np.stack([d, a], axis=1) / (a * d - b * b)[:, None]


def _minimise(evaluate, theta, lo, hi, max_iter, tol, prior=None, kappa=None):
    """Minimise V + kappa (theta - mean)^T prec (theta - mean) per window (prior = (mean, prec) or None) from
    theta (n, P) inside [lo, hi]; evaluate(theta, rows) gives V, its half gradient, Gauss-Newton and exact
    Hessians at theta for those rows of the windows (None: all). Returns theta, V, the Gauss-Newton Hessian of V
    and the converged flags."""
    n, dim = theta.shape
    lo, hi = np.broadcast_to(lo, theta.shape), np.broadcast_to(hi, theta.shape)  # a box per window, or one for all
    mean, prec = prior if prior is not None else (np.zeros(dim), np.zeros((dim, dim)))
    kappa = np.zeros(n) if kappa is None else kappa

    def objective(V, th, kap):
        d = th - mean
        return V + kap * np.einsum("ni,ij,nj->n", d, prec, d)

    V, g, gn, ex = evaluate(theta, None)
    obj = objective(V, theta, kappa)
    damping = np.full(n, 1e-4)
    done = ~np.isfinite(obj)
    converged = np.zeros(n, bool)
    eye = np.eye(dim)
    for _ in range(max_iter):
        act = np.flatnonzero(~done)
        if not act.size:
            break
        th, kap = theta[act], kappa[act]
        newton = _positive(ex[act])[:, None, None]
        h = np.where(newton, ex[act], gn[act]) + kap[:, None, None] * prec
        grad = g[act] + kap[:, None] * ((th - mean) @ prec)
        # a coordinate on a bound whose gradient pushes outwards stays there: the step is the others' alone
        low, high = lo[act], hi[act]
        held = ((th <= low) & (grad > 0)) | ((th >= high) & (grad < 0))
        h = np.where(held[:, :, None] | held[:, None, :], eye, h)
        grad = np.where(held, 0.0, grad)
        newton_point = np.clip(th - _solve(h, grad), low, high)
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
        cand = np.clip(th - _solve(h + damping[act, None, None] * (h * eye), grad), lo[act], hi[act])
        Vc, gc, gnc, exc = evaluate(cand, act)
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


def _abs2(x):
    return x.real**2 + x.imag**2


@lru_cache(maxsize=16)
def _powers(n_samples: int, low: int, high: int) -> np.ndarray:
    """z^p on the half spectrum for p = low..high: (high - low + 1, K)."""
    k = np.arange(n_samples // 2 + 1)
    powers = np.exp(2j * np.pi * np.outer(np.arange(low, high + 1), k) / n_samples)
    powers.flags.writeable = False
    return powers


def _kernel(u, half_width: int):
    """The advance's interpolation kernel at offsets u and its first two derivatives: the Kaiser-windowed sinc of
    physics.sensors, zero for |u| >= half_width + 1, where the sinc itself vanishes as a tap enters or leaves, so
    the advance is continuous in the delay. The derivatives by central differences: the kernel is analytic within
    its support, and their error (1e-10, 1e-8) is far below what the Newton steps need."""
    from scipy import special  # here: importing the physics layer loads no scipy

    support = half_width + 1
    beta = min(BETA_PER_TAP * half_width, BETA_MAX)

    def k(v):
        t = np.sqrt(np.clip(1.0 - (v / support) ** 2, 0.0, None))
        return np.where(np.abs(v) < support, np.sinc(v) * special.i0(beta * t), 0.0) / special.i0(beta)

    e1, e2 = 1e-5, 1e-4
    k0 = k(u)
    return k0, (k(u + e1) - k(u - e1)) / (2.0 * e1), (k(u + e2) - 2.0 * k0 + k(u - e2)) / (e2 * e2)


def _advance(delay, n_samples: int, half_width: int):
    """H_k = sum_p K(p - d) z_k^p over the taps |p - d| < half_width + 1, and its first two derivatives in d, on
    the half spectrum (n, K): the body channel advanced by d samples (the skew fix)."""
    whole = np.floor(delay)
    low, high = int(whole.min()) - half_width, int(whole.max()) + half_width + 1
    taps = _kernel(np.arange(low, high + 1) - delay[:, None], half_width)
    h = np.concatenate(taps) @ _powers(n_samples, low, high)
    n = len(delay)
    return h[:n], -h[n : 2 * n], h[2 * n :]


def _factor(fix, eta, n_samples):
    """The body term's factor phi (A S - phi B U) with its first two derivatives in the fault's parameter, and
    psi = |phi|^2 (W = |A|^2 + lambda psi |B|^2) with its two: (n, K) or (n, 1) arrays, or scalars."""
    if fix == "gain":
        g = np.exp(eta)[:, None]
        return g, g, g, g * g, 2.0 * g * g, 4.0 * g * g
    if fix == "skew":
        h, h1, h2 = _advance(eta, n_samples, SKEW_HALF_WIDTH)
        return h, h1, h2, _abs2(h), 2.0 * (h.conj() * h1).real, 2.0 * (_abs2(h1) + (h.conj() * h2).real)
    return 1.0, 0.0, 0.0, 1.0, 0.0, 0.0


def _evaluate_fault(theta, S, U, X, fix, grid, lam, n_samples, derivatives=True, XA=None):
    """``_evaluate`` for theta = (log p1, log p2, eta), eta the fault's parameter: the residual
    A S - phi B U + eta X - I with W = |A|^2 + lambda psi |B|^2 (``_factor``; X: the hardening's cubic term or
    None). V, its half gradient and the Gauss-Newton and exact Hessians in theta, the transient projected out."""
    p = np.exp(theta[:, :2])
    eta = theta[:, 2]
    p1, p2 = p[:, :1], p[:, 1:]
    a0, a1, a2, b1, b2 = grid.polys
    A = a0 + p1 * a1 + p2 * a2
    B = p1 * b1 + p2 * b2
    phi, phi1, phi2, psi, psi1, psi2 = _factor(fix, eta, n_samples)
    BU = B * U
    e = A * S - phi * BU
    if X is not None:
        e = e + eta[:, None] * X
    QB = _abs2(B)
    Aw = A if XA is None else A + eta[:, None] * XA
    W = _abs2(Aw) + lam * psi * QB
    w = grid.weight / W
    T = (w @ grid.cos)[:, grid.toeplitz]
    c = np.linalg.solve(T, ((w * e) @ grid.basis.conj()).real[..., None])[..., 0]
    eps = e - c @ grid.basis.T
    eps2 = _abs2(eps)
    V = np.einsum("nk,nk->n", w, eps2)
    if not derivatives:
        return V, None, None, None
    # derivatives in x = (p1, p2, eta): e is affine in p at fixed eta, W quadratic
    U1, U2 = b1 * U, b2 * U
    de = [a1 * S - phi * U1, a2 * S - phi * U2, -phi1 * BU + (0.0 if X is None else X)]
    d2e = {(0, 2): -phi1 * U1, (1, 2): -phi1 * U2, (2, 2): -phi2 * BU}
    qb = [2.0 * (B.conj() * b1).real, 2.0 * (B.conj() * b2).real]
    dW = [
        (2.0 * (Aw.conj() * a1).real + lam * psi * qb[0]) / W,
        (2.0 * (Aw.conj() * a2).real + lam * psi * qb[1]) / W,
        (lam * psi1 * QB + (0.0 if XA is None else 2.0 * (Aw.conj() * XA).real)) / W,
    ]
    d2W = {
        (0, 0): 2.0 * (_abs2(a1) + lam * psi * _abs2(b1)),
        (0, 1): 2.0 * ((a1.conj() * a2).real + lam * psi * (b1.conj() * b2).real),
        (1, 1): 2.0 * (_abs2(a2) + lam * psi * _abs2(b2)),
        (0, 2): lam * psi1 * qb[0],
        (1, 2): lam * psi1 * qb[1],
        (2, 2): lam * psi2 * QB,
    }
    if XA is not None:
        d2W[(0, 2)] = d2W[(0, 2)] + 2.0 * (a1.conj() * XA).real
        d2W[(1, 2)] = d2W[(1, 2)] + 2.0 * (a2.conj() * XA).real
        d2W[(2, 2)] = d2W[(2, 2)] + 2.0 * _abs2(XA)
    F = [de[i] - 0.5 * eps * dW[i] for i in range(3)]
    G = [de[i] - eps * dW[i] for i in range(3)]
    wF = [w * f.conj() for f in F]
    wc = w * eps.conj()
    n = len(p)
    g = np.stack([_re_sum(wc, F[i]) for i in range(3)], axis=1)
    gn, ex = np.empty((n, 3, 3)), np.empty((n, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            gn[:, i, j] = gn[:, j, i] = _re_sum(wF[i], F[j])
            second = _re_sum(wc, d2e[(i, j)]) if (i, j) in d2e else 0.0
            ex[:, i, j] = ex[:, j, i] = (
                _re_sum(w * de[i].conj(), de[j])
                + second
                - _re_sum(wc * dW[j], de[i])
                - _re_sum(wc * dW[i], de[j])
                + np.einsum("nk,nk->n", w * eps2, dW[i] * dW[j] - 0.5 * d2W[(i, j)] / W)
            )
    gn = _schur(gn, np.stack([(wF[i] @ grid.basis).real for i in range(3)], axis=1), T)
    ex = _schur(ex, np.stack([((w * G[i]) @ grid.basis.conj()).real for i in range(3)], axis=1), T)
    s = np.concatenate([p, np.ones((n, 1))], axis=1)  # d/dtheta_i = p_i d/dp_i for log p, eta as it is
    g = g * s
    ex = ex * s[:, :, None] * s[:, None, :]
    ex[:, 0, 0] += g[:, 0]
    ex[:, 1, 1] += g[:, 1]
    return V, g, gn * s[:, :, None] * s[:, None, :], ex


def _displacement(seat, body, p, c, dt, model):
    """The seat's relative displacement d (n, N) by the seat equation with the cubic force c d^3: discrete,
    (p1 / dt + p2) d_k + c d_k^3 = p1 / dt d_{k-1} - s_k + p1 dt u_k (the consistent recording's step); continuous,
    the trapezoid rule on p1 d' + p2 d + c d^3 = -s. It filters the seat channel through a stable first-order
    low-pass of gain <= 1 / p2, so its noise stays small where the double integral of the noisy channels drifts.
    Its one free state, d_0, is the one whose second differences best match the kinematics,
    d_{k+1} - 2 d_k + d_{k-1} = dt^2 (s_k - u_k): the recursion forgets it within tens of samples."""
    p1, p2 = p[:, 0], p[:, 1]
    if model == "discrete":
        alpha, beta, implicit = p1 / dt + p2, p1 / dt, 1.0
        rhs = -seat + (p1 * dt)[:, None] * body
    else:
        alpha, beta, implicit = p1 / dt + p2 / 2.0, p1 / dt - p2 / 2.0, 0.5
        rhs = np.concatenate([-seat[:, :1], -0.5 * (seat[:, 1:] + seat[:, :-1])], axis=1)
    cubic, explicit = implicit * c, (1.0 - implicit) * c
    cubic3, explicit3 = 3.0 * cubic, 3.0 * explicit
    kinematic = dt * dt * (seat - body)[:, 1:-1]
    N = seat.shape[1]
    d, free = np.empty_like(seat), np.empty_like(seat)
    d[:, 0], free[:, 0] = 0.0, 1.0
    end = N  # the samples a pass recomputes: after the first, only those d_0 still reaches
    for attempt in range(DISPLACEMENT_PASSES):  # Gauss-Newton in d_0: the cube makes d's dependence on it nonlinear
        for k in range(1, end):
            last = d[:, k - 1]
            r = beta * last + rhs[:, k]
            if implicit < 1.0:
                r -= explicit * last * last * last
            x = r / alpha
            for _ in range(4):  # Newton from the linear spring's d: the cube is a correction
                x2 = x * x
                x -= (x * (alpha + cubic * x2) - r) / (alpha + cubic3 * x2)
            d[:, k] = x
            slope = beta - explicit3 * last * last if implicit < 1.0 else beta
            free[:, k] = free[:, k - 1] * slope / (alpha + cubic3 * x * x)
        shape = np.diff(free, 2, axis=1)
        step = -np.einsum("nk,nk->n", np.diff(d, 2, axis=1) - kinematic, shape) / np.einsum("nk,nk->n", shape, shape)
        # below 1e-6 of d the linear correction is exact to 1e-12
        if attempt == DISPLACEMENT_PASSES - 1 or not (np.abs(step) > 1e-6 * np.abs(d).max(axis=1)).any():
            return d + step[:, None] * free
        d[:, 0] += step
        reach = np.abs(free).max(axis=0) * np.abs(step).max() > 1e-17 * np.abs(d).max()
        end = min(N, int(np.flatnonzero(reach).max(initial=0)) + 2)


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
    fix: str = "none",
    skew_max: float = 0.02,
) -> EivFit:
    """The errors-in-variables ML (or MAP) fit of (p1, p2) on every window (n, N) of seat and body acceleration.

    noise_ratio: lambda = sigma_body^2 / sigma_seat^2 (0: output error). model: "discrete" (consistent recordings
    of the simulator) or "continuous" (samples of the continuous motion); see the module docstring.
    p0: the start, (2,) or (n, 2), e.g. the band-passed least squares (seat_fit.fit_windows(...).p); a window whose
    start is NaN or outside the box starts at its centre in log p, as all do with None.
    p_lo, p_hi: the box (p1, p2) the fit stays in. prior: None (ML) or (mean (2,), cov (2, 2)) of log p, e.g. from
    ``log_p_prior``: the MAP fit, started from the ML one and with the ML fit's sigma^2.
    fix: "none", or the recording fault fitted with p as one more parameter (module docstring, "Fixes"): "gain"
    (the ratio of the sensors' gains), "skew" (the body sensor's time offset, |tau| <= ``skew_max`` seconds) or
    "hardening" (a hardening seat spring); the fit's se then includes that parameter's uncertainty, and
    EivFit.fault holds its estimate.
    Float32 windows are taken in float64; a single window (N,) as (1, N). Returns EivFit.
    """
    check_choice("fix", fix, FIXES)
    skew_max = check_number("skew_max", skew_max, 0.0, unit="seconds")
    seat, body, good, grid, q = _setup(seat, body, dt, noise_ratio, model)
    max_iter = check_int("max_iter", max_iter, 1)
    tol = check_number("tol", tol, 0.0, low_open=True)
    lo, hi = _box(p_lo, p_hi)
    n, N = seat.shape
    lam = float(noise_ratio)
    if fix == "skew":  # the advance's circular edges: lead and lag samples at the window's ends (module docstring)
        reach = skew_max / dt
        lead = int(np.floor(reach)) + SKEW_HALF_WIDTH + 1
        lag = int(np.ceil(reach)) + SKEW_HALF_WIDTH
        grid = _grid(model, float(dt), N, lead, lag)
        if N < grid.basis.shape[1] + 4:
            bad("seat", f"windows of {N} samples", f"at least {grid.basis.shape[1] + 4} samples for the skew fix")
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
        if mean.shape != (2,) or cov.shape != (2, 2) or not (np.isfinite(mean).all() and _positive(cov)):
            bad("prior", "(mean, cov)", "a mean (2,) and a positive definite covariance (2, 2) of log p")
        prec = np.linalg.inv(cov)
        if dim == 3:  # no prior on the fault's parameter
            mean, prec = np.append(mean, 0.0), np.pad(prec, ((0, 1), (0, 1)))
    if dim == 3:
        bound = {
            "gain": np.log(GAIN_BOX),
            "skew": (-skew_max / dt, skew_max / dt),
            "hardening": (-np.inf, np.inf),  # per window: _fault_problem
        }[fix]
        lo, hi = np.append(lo, bound[0]), np.append(hi, bound[1])
    p = np.full((n, 2), np.nan)
    se = np.full((n, 2), np.inf)
    sigma2, cost = np.full(n, np.nan), np.full(n, np.nan)
    converged = np.zeros(n, bool)
    fault = None if fix == "none" else np.full(n, np.nan)
    block = max(1, CHUNK // (N // 2 + 1))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for start in range(0, n, block):
            rows = np.arange(start, min(start + block, n))
            rows = rows[good[rows]]
            if not rows.size:
                continue
            if fix == "none":
                E = _spectra(seat[rows], body[rows], grid)

                def solve(th, prior_=None, kappa_=None, E=E):
                    def evaluate(th, sub):
                        return _evaluate(th, E if sub is None else E[:, sub], grid, q)

                    return _minimise(evaluate, th, lo, hi, max_iter, tol, prior_, kappa_)

                theta = theta0[rows]
            else:
                solve, theta, to_fault = _fault_problem(
                    fix, seat[rows], body[rows], theta0[rows], grid, lam, float(dt), model, lo, hi, max_iter, tol
                )
            theta, V, h, conv = solve(theta)
            kappa = V / dof  # N sigma^2: V's scale in the likelihood
            if prior is not None:
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
            ok = _positive(h) & np.isfinite(theta).all(axis=1) & np.isfinite(V) & (kappa >= 0)
            if fault is not None:
                fault[rows[ok]] = to_fault(theta)[ok]
            rows, theta, V, h, conv, kappa = rows[ok], theta[ok], V[ok], h[ok], conv[ok], kappa[ok]
            p[rows] = np.exp(theta[:, :2])
            se[rows] = np.sqrt(kappa[:, None] * _inverse_diagonal(h)[:, :2])
            sigma2[rows] = kappa / N
            cost[rows] = V
            converged[rows] = conv
    return EivFit(p, se, sigma2, cost, converged, fault)


def _posterior(solved, mean, prec, kappa):
    """The MAP criterion V + kappa (theta - mean)' prec (theta - mean) of ``solve``'s result, per window; inf where
    the fit failed."""
    theta, V = solved[0], solved[1]
    d = theta - mean
    out = V + kappa * np.einsum("ni,ij,nj->n", d, prec, d)
    return np.where(np.isfinite(out), out, np.inf)


def _fault_problem(fix, seat, body, theta_p, grid, lam, dt, model, lo, hi, max_iter, tol):
    """For one block of windows with a fix: solve(theta, prior, kappa) -> (theta, V, Gauss-Newton Hessian,
    converged) as ``_minimise`` returns them, the start theta (n, 3), and the map from theta to EivFit.fault."""
    N = seat.shape[1]
    S, U = np.fft.rfft(seat, axis=-1), np.fft.rfft(body, axis=-1)
    theta = np.concatenate([theta_p, np.zeros((len(seat), 1))], axis=1)

    def evaluator(S, U, X, XA=None):
        def evaluate(th, sub):
            if sub is None:
                return _evaluate_fault(th, S, U, X, fix, grid, lam, N, XA=XA)
            return _evaluate_fault(
                th, S[sub], U[sub], None if X is None else X[sub], fix, grid, lam, N, XA=None if XA is None else XA[sub]
            )

        return evaluate

    if fix != "hardening":
        if fix == "skew":  # the coarse search: V along the offsets at the start's p
            offsets = np.linspace(lo[2], hi[2], 2 * int(np.ceil(hi[2] / SKEW_STEP)) + 1)
            cost = np.stack(
                [
                    _evaluate_fault(
                        np.column_stack([theta_p, np.full(len(seat), o)]), S, U, None, fix, grid, lam, N, False
                    )[0]
                    for o in offsets
                ],
                axis=1,
            )
            theta[:, 2] = offsets[np.argmin(np.where(np.isfinite(cost), cost, np.inf), axis=1)]

        def solve(th, prior=None, kappa=None):
            return _minimise(evaluator(S, U, None), th, lo, hi, max_iter, tol, prior, kappa)

        to_fault = (lambda th: np.exp(th[:, 2])) if fix == "gain" else (lambda th: th[:, 2] * dt)
        return solve, theta, to_fault

    p_start = np.exp(theta_p)
    d = _displacement(seat, body, p_start, np.zeros(len(seat)), dt, model)
    stroke = np.mean(d**2, axis=1)
    scale = p_start[:, 1] / stroke  # c = eta scale: eta ~ kappa mean(d^2), the stiffening at the rms stroke
    lo, hi = np.tile(lo, (len(seat), 1)), np.tile(hi, (len(seat), 1))
    lo[:, 2], hi[:, 2] = -KAPPA_MAX * stroke, KAPPA_MAX * stroke
    a0 = grid.polys[0]
    s_grid = 2j * np.pi * np.arange(S.shape[1]) / (N * dt)

    def solve(x, prior=None, kappa=None):
        # The cubic term is fitted at the displacement of the round's start x, T(x) the fit: the true (p, c) is a
        # fixed point on clean data. The plain iteration x <- T(x) contracted by only 0.45 per round on rough
        # roads (30 rounds); Anderson's extrapolation over the last rounds (a secant method) takes 6-13.
        x, n = x.copy(), len(x)
        out, V, h = np.full((n, 3), np.nan), np.full(n, np.nan), np.full((n, 3, 3), np.nan)
        conv, act = np.zeros(n, bool), np.arange(n)
        xs, fs = [], []
        for _ in range(HARDENING_ROUNDS):
            p = np.exp(x[act, :2])
            d = _displacement(seat[act], body[act], p, x[act, 2] * scale[act], dt, model)
            X = (scale[act, None] * a0) * np.fft.rfft(d**3, axis=-1)
            # the regressor's own noise, 3 c d^2 delta with delta = -(seat noise) / (p1 s + p2 + 3 c d^2), taken at
            # the mean stroke: without it in W the fit uses the cubic term to explain the seat's noise
            c_stroke = (x[act, 2] * scale[act] * np.mean(d**2, axis=1))[:, None]
            XA = -3.0 * (scale[act] * stroke[act])[:, None] * a0 / (p[:, :1] * s_grid + p[:, 1:] + 3.0 * c_stroke)
            kap = None if kappa is None else kappa[act]
            y, V[act], h[act], conv[act] = _minimise(
                evaluator(S[act], U[act], X, XA), x[act].copy(), lo[act], hi[act], max_iter, tol, prior, kap
            )
            out[act] = y
            f = np.full((n, 3), np.nan)
            f[act] = y - x[act]
            xs.append(x.copy())
            fs.append(f)
            settled = ~(np.max(np.abs(f[act]), axis=1) > tol)  # NaN too: nothing to iterate
            step = _anderson(xs, fs, act)
            x[act] = np.clip(np.where(np.isfinite(step).all(axis=1, keepdims=True), step, y), lo[act], hi[act])
            act = act[~settled]
            if not act.size:
                break
        conv[act] = False
        return out, V, h, conv

    return solve, theta, lambda th: th[:, 2] * scale / np.exp(th[:, 1])


def _anderson(xs, fs, rows, memory=ANDERSON_MEMORY):
    """The next x of the fixed-point iteration x <- x + f(x) for ``rows``, from the history of x and f (lists of
    (n, P)): Anderson's mixing of the last ``memory`` differences; NaN where they are degenerate."""
    x, f = xs[-1][rows], fs[-1][rows]
    m = min(memory, len(xs) - 1)
    if m == 0:
        return x + f
    dx = np.stack([xs[-j][rows] - xs[-j - 1][rows] for j in range(1, m + 1)], axis=-1)
    df = np.stack([fs[-j][rows] - fs[-j - 1][rows] for j in range(1, m + 1)], axis=-1)
    gram = np.einsum("npi,npj->nij", df, df)
    gram += 1e-12 * np.trace(gram, axis1=1, axis2=2)[:, None, None] * np.eye(m)
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = np.isfinite(gram).all(axis=(1, 2)) & (np.trace(gram, axis1=1, axis2=2) > 0)
        gamma = np.full((len(x), m), np.nan)
        if ok.any():
            gamma[ok] = np.linalg.solve(gram[ok], np.einsum("npi,np->ni", df[ok], f[ok])[..., None])[..., 0]
    return x + f - np.einsum("npi,ni->np", dx + df, gamma)


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
