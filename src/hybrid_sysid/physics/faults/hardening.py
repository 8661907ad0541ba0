"""A model mismatch: a hardening seat spring, F = K3 (d + kappa d^3), d the seat-minus-body displacement.

Not a sensor fault: a constant of the car (``car.seat_hardening``, a QuarterCar field), which the simulation's step
carries (physics.quarter_car.step, physics.compiled), so nothing is drawn and nothing acts on the recorded signals.
p2 = K3 / m3 stays the label, the small-amplitude stiffness (docs/faults.md, "Hardening seat spring").

Its fix, "hardening" (``HardeningFix``): least squares takes the cube of the relative displacement as a third
regressor, a_s = -p1 V - p2 X - p2 kappa X^3; the likelihood fits the cubic force as an equation-error term with the
displacement from the seat channel, alternating with it (``hardening_problem``; physics.eiv.faults explains why).
"""

from __future__ import annotations

import numpy as np

from hybrid_sysid.core.checks import bad
from hybrid_sysid.core.options import STEPPED
from hybrid_sysid.physics.faults.base import Fault, Setting, value_of
from hybrid_sysid.physics.faults.fix import FaultProblem, Fix, lstsq_columns

# kappa above this: at d = 1 cm the cubic force is 1000 times the linear one, and a class E road's motion then
# overflows the semi-implicit step into NaN (the step's stability is that of the linearised car)
HARDENING_MAX = 1e7
HARDENING_UNIT = "1/m^2; 35000 in car=hardening_seat"
KAPPA_MAX = 1e6  # 1/m^2, |kappa| of the likelihood's fix: a spring twice as stiff at 1 mm (car=hardening_seat: 35000)
HARDENING_ROUNDS = 30
ANDERSON_MEMORY = 3
DISPLACEMENT_PASSES = 4


def detrend(x: np.ndarray) -> np.ndarray:
    """x minus its least-squares line per row: what integration from t0 and drift leave in a window."""
    t = np.linspace(-1.0, 1.0, x.shape[-1])
    x = np.asarray(x, dtype=np.float64)
    return x - x.mean(axis=-1, keepdims=True) - np.outer((x * t).sum(-1) / (t * t).sum(), t)


def fit_hardening(seat, rel_vel, rel_disp, fir: np.ndarray) -> np.ndarray:
    """p (n, 2) with the cube of the (detrended) relative displacement as a third regressor."""
    return lstsq_columns([-rel_vel, -rel_disp, -(detrend(rel_disp) ** 3)], seat, fir)[:, :2]


class HardeningFix(Fix):
    name = "hardening"

    def least_squares(self, seat, body, rel_vel, rel_disp, dt, measurement, fir, skew_max):
        return fit_hardening(seat, rel_vel, rel_disp, fir)

    def eiv_problem(self, problem: FaultProblem):
        return hardening_problem(problem)


class Hardening(Fault):
    name = "hardening"
    settings = (
        Setting(
            "seat_hardening",
            0.0,
            "a hardening seat spring, F = K3 (d + kappa d^3)",
            unit="1/m^2",
            drawn="nothing: a car constant",
            preset="`car=hardening_seat`: 35000",
            high=HARDENING_MAX,
            allowed=HARDENING_UNIT,
            section="car",
        ),
    )
    fix = "hardening"  # the cube of the displacement a third regressor
    fix_code = HardeningFix()
    fix_rank = 10
    compiled = True  # the step itself, numpy's and the kernel's

    def validate(self, config, dt, window=None, measurement=None):
        super().validate(config, dt, window, measurement)
        kappa = value_of(config, self.settings[0])
        if kappa and measurement is not None and measurement not in STEPPED:
            bad(
                "car.seat_hardening",
                kappa,
                "0 with data.measurement = continuous: its exact solution is of the linear car (physics.exact)",
            )


def hardening_problem(problem: FaultProblem):
    """The likelihood's fix for one block of windows: solve(theta, prior, kappa) -> (theta, V, Gauss-Newton Hessian,
    converged), the start theta (n, 3) and the map from theta to EivFit.fault, kappa in 1/m^2."""
    seat, body, S, U, theta, grid, _, dt, model, lo, hi, max_iter, tol, evaluator, minimise = problem
    N = seat.shape[1]
    p_start = np.exp(theta[:, :2])
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
            step = anderson(xs, fs, act)
            x[act] = np.clip(np.where(np.isfinite(step).all(axis=1, keepdims=True), step, y), lo[act], hi[act])
            act = act[~settled]
            if not act.size:
                break
        conv[act] = False
        return out, V, h, conv

    return solve, theta, lambda th: th[:, 2] * scale / np.exp(th[:, 1])


def anderson(xs, fs, rows, memory=ANDERSON_MEMORY):
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
    kinematic = dt * dt * (seat - body)[:, 1:-1]
    N = seat.shape[1]
    d, free = np.empty_like(seat, dtype=np.float64), np.empty_like(seat, dtype=np.float64)
    d[:, 0], free[:, 0] = 0.0, 1.0
    end = N  # the samples a pass recomputes: after the first, only those d_0 still reaches
    # compiled: numpy's pass over the samples (compiled_hardening.numpy_pass, equal bit for bit) took 40% of the fit
    from hybrid_sysid.physics.compiled_hardening import run_pass

    for attempt in range(DISPLACEMENT_PASSES):  # Gauss-Newton in d_0: the cube makes d's dependence on it nonlinear
        run_pass(d, free, rhs, alpha, beta, cubic, explicit, implicit, end)
        shape = np.diff(free, 2, axis=1)
        step = -np.einsum("nk,nk->n", np.diff(d, 2, axis=1) - kinematic, shape) / np.einsum("nk,nk->n", shape, shape)
        # below 1e-6 of d the linear correction is exact to 1e-12
        if attempt == DISPLACEMENT_PASSES - 1 or not (np.abs(step) > 1e-6 * np.abs(d).max(axis=1)).any():
            return d + step[:, None] * free
        d[:, 0] += step
        reach = np.abs(free).max(axis=0) * np.abs(step).max() > 1e-17 * np.abs(d).max()
        end = min(N, int(np.flatnonzero(reach).max(initial=0)) + 2)
