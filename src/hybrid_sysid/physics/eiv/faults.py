"""A recording fault fitted with p: each fix's problem for the damped Newton minimiser. The code of each fix
lies in its fault's file (physics.faults, ``Fix``); the maths of the package's three is here.

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
from hybrid_sysid.physics.faults.fix import FaultProblem, Fix
from hybrid_sysid.physics.faults.gain import GAIN_BOX
from hybrid_sysid.physics.faults.hardening import (
    ANDERSON_MEMORY,
    DISPLACEMENT_PASSES,
    HARDENING_ROUNDS,
    KAPPA_MAX,
    seat_displacement,
)
from hybrid_sysid.physics.faults.skew import SKEW_STEP

__all__ = [
    "ANDERSON_MEMORY",
    "DISPLACEMENT_PASSES",
    "GAIN_BOX",
    "HARDENING_ROUNDS",
    "KAPPA_MAX",
    "SKEW_STEP",
    "fault_problem",
    "seat_displacement",
]


def fault_problem(fix: Fix, seat, body, theta_p, grid, lam, dt, model, lo, hi, max_iter, tol):
    """For one block of windows with a fix: solve(theta, prior, kappa) -> (theta, V, Gauss-Newton Hessian,
    converged) as ``minimise`` returns them, the start theta (n, 3), and the map from theta to EivFit.fault.
    The fix's own problem (``Fix.eiv_problem``), else the body factor's with eta started by ``Fix.eiv_starts``."""
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

    own = fix.eiv_problem(
        FaultProblem(seat, body, S, U, theta, grid, lam, dt, model, lo, hi, max_iter, tol, evaluator, minimise)
    )
    if own is not None:
        return own
    offsets = fix.eiv_starts(lo, hi)
    if offsets is not None:  # the coarse search: V along eta's candidates at the start's p
        starts = [np.column_stack([theta_p, np.full(len(seat), o)]) for o in offsets]
        cost = np.stack([evaluate_fault(th, S, U, None, fix, grid, lam, N, False)[0] for th in starts], axis=1)
        theta[:, 2] = offsets[np.argmin(np.where(np.isfinite(cost), cost, np.inf), axis=1)]

    def solve(th, prior=None, kappa=None):
        return minimise(evaluator(S, U, None), th, lo, hi, max_iter, tol, prior, kappa)

    return solve, theta, lambda th: fix.eiv_fault(th[:, 2], dt)
