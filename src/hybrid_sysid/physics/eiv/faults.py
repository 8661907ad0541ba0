"""A recording fault fitted with p: each fix's problem for the damped Newton minimiser.

Fixes (``fix``, docs/faults.md): a recording fault is one more parameter eta of the same likelihood, fitted with p
by the same damped Newton in theta = (log p1, log p2, eta) with the exact 3 x 3 Hessian (``evaluate_fault``). The
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
  ``seat_displacement`` solves the seat equation for d from the seat channel, a stable first-order recursion that is
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

import numpy as np

from hybrid_sysid.physics.eiv.fault_criterion import evaluate_fault
from hybrid_sysid.physics.eiv.newton import minimise

SKEW_STEP = 1.0  # samples between the offsets of the skew's coarse search over [-skew_max, skew_max]
GAIN_BOX = (1.0 / 3.0, 3.0)  # g = g_seat / g_body
KAPPA_MAX = 1e6  # 1/m^2, |kappa| of the hardening fix: a spring twice as stiff at 1 mm (car=hardening_seat: 35000)
HARDENING_ROUNDS = 30
ANDERSON_MEMORY = 3
DISPLACEMENT_PASSES = 4


def fault_problem(fix, seat, body, theta_p, grid, lam, dt, model, lo, hi, max_iter, tol):
    """For one block of windows with a fix: solve(theta, prior, kappa) -> (theta, V, Gauss-Newton Hessian,
    converged) as ``minimise`` returns them, the start theta (n, 3), and the map from theta to EivFit.fault."""
    N = seat.shape[1]
    S, U = np.fft.rfft(seat, axis=-1), np.fft.rfft(body, axis=-1)
    theta = np.concatenate([theta_p, np.zeros((len(seat), 1))], axis=1)

    def evaluator(S, U, X, XA=None):
        def evaluate(th, sub):
            if sub is None:
                return evaluate_fault(th, S, U, X, fix, grid, lam, N, XA=XA)
            return evaluate_fault(
                th, S[sub], U[sub], None if X is None else X[sub], fix, grid, lam, N, XA=None if XA is None else XA[sub]
            )

        return evaluate

    if fix != "hardening":
        if fix == "skew":  # the coarse search: V along the offsets at the start's p
            offsets = np.linspace(lo[2], hi[2], 2 * int(np.ceil(hi[2] / SKEW_STEP)) + 1)
            cost = np.stack(
                [
                    evaluate_fault(
                        np.column_stack([theta_p, np.full(len(seat), o)]), S, U, None, fix, grid, lam, N, False
                    )[0]
                    for o in offsets
                ],
                axis=1,
            )
            theta[:, 2] = offsets[np.argmin(np.where(np.isfinite(cost), cost, np.inf), axis=1)]

        def solve(th, prior=None, kappa=None):
            return minimise(evaluator(S, U, None), th, lo, hi, max_iter, tol, prior, kappa)

        to_fault = (lambda th: np.exp(th[:, 2])) if fix == "gain" else (lambda th: th[:, 2] * dt)
        return solve, theta, to_fault

    p_start = np.exp(theta_p)
    d = seat_displacement(seat, body, p_start, np.zeros(len(seat)), dt, model)
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
            d = seat_displacement(seat[act], body[act], p, x[act, 2] * scale[act], dt, model)
            X = (scale[act, None] * a0) * np.fft.rfft(d**3, axis=-1)
            # the regressor's own noise, 3 c d^2 delta with delta = -(seat noise) / (p1 s + p2 + 3 c d^2), taken at
            # the mean stroke: without it in W the fit uses the cubic term to explain the seat's noise
            c_stroke = (x[act, 2] * scale[act] * np.mean(d**2, axis=1))[:, None]
            XA = -3.0 * (scale[act] * stroke[act])[:, None] * a0 / (p[:, :1] * s_grid + p[:, 1:] + 3.0 * c_stroke)
            kap = None if kappa is None else kappa[act]
            y, V[act], h[act], conv[act] = minimise(
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


def seat_displacement(seat, body, p, c, dt, model):
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
