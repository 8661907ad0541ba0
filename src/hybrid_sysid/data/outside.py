"""The fit of the seat over the rest of a window's recording: the target of ``objective=cross_segment``
(hybrid_sysid.model.cross_segment), computed with the batches.

Per batch row: the whole clean recording plus fresh Gaussian noise of the row's std, on both channels. Two fits of
the samples outside the window [start, start + W), as the objective's ``outside_fir`` asks (``OutsideTaps``):

"ls": the band-passed least squares. The recording is re-integrated from t0 by its measurement, band-passed
('valid') and fitted (physics.seat_fit) on the filtered samples whose whole FIR support lies outside the window.
Those samples read no sample of the window. The noise the window's own samples add to the regressors after it
integrates to a constant in rel_vel and a constant and a ramp in rel_disp, which a symmetric band-pass of zero sum
removes. So the fit's noise is independent of the window's, as in a recording whose sensor noise is white.

"eiv": the errors-in-variables maximum likelihood (physics.eiv) of the two outside segments [0, start) and
[start + W, n) together, started from the "ls" fit. The segments, joined, make one sequence of n - W samples for
every start, so the fit is vectorised over rows as fit_eiv is over windows. physics.eiv's model, A S - B U = I + noise
in the DFT of one sequence, holds for the joined one with a second transient: where the second segment begins, A and
B reach back into the first segment's end instead of the window, which changes the first m equations of the second
segment only. So I has m coefficients at the circle's start (the wrap from the end to the start) and m more at the
junction (``fit_joined``). The noise of the joined samples is still white and the DFT's circular convolution still
exact, so the likelihood is physics.eiv's, with 2 m transient coefficients instead of m; only raw samples outside the
window enter it, and the "ls" start too reads none.

Why one joint fit and not fit_eiv on pieces of a fixed length, combined by inverse-variance weights: measured on
data=default (seat_spread 0.3, 400 rows, noise 0.03), pieces of 100 to 350 samples missed p1 by 19-29% on average
(inverse-variance weights: 28-167%, the short fits' se being wrong where their p is), against the least squares'
15% and the joint fit's 13%.
"""

from __future__ import annotations

import numpy as np
import torch
from numpy.polynomial import polynomial as poly

from hybrid_sysid.core.checks import check_choice
from hybrid_sysid.physics import relative_states
from hybrid_sysid.physics.eiv import P_HI, P_LO, TOL
from hybrid_sysid.physics.seat_fit import fit_seat

CHUNK = 256  # rows filtered at once: bounds the float64 work arrays of a large evaluation batch (~30 MB)
BLOCK = 64  # rows of one likelihood fit: its ~40 arrays of (rows, n_steps - window) stay in the cache
# Newton iterations of the outside fit. From the least-squares start every row of data=default at noise 0.03
# converges within 20; at noise 0.1 the 0.2% that need more end where 50 would, or keep the least squares. The
# last iterations run on a few rows each, at the cost of a full one: at noise 0.1, 20 halve the fit's work.
OUTSIDE_ITER = 20
TARGETS = ("eiv", "ls")
# The likelihood fit corrects least squares' attenuation towards zero. A correction beyond this factor means the
# noise holds more of the regressors' power than the motion does. There (smooth roads at noise 0.1) the likelihood
# has maxima far from the truth with a small se: p1 off by 1-5 times at noise 0.1 (8-9% of the rows), by 0.4-1.2
# times at 0.03 (2-3%). Such a row keeps the least-squares target. Measured on data=default (seat_spread 0.3,
# 3 x 400 rows), the objective's loss at the true p at noise 0.1: limit 2, 0.17-0.20; 3, 0.18-0.21; none, 0.29-0.51;
# least squares, 0.18. At 0.03 every limit gave 0.05, none 0.05-0.12, least squares 0.07.
MAX_CORRECTION = 2.0
# physics.eiv's continuous model: dt s = 2 w num(w^2) / den(w^2), w = (1 - z^-1) / (1 + z^-1), the [5/4] Pade
# approximant of 2 artanh(w) (its module docstring)
PADE_NUM = (1.0, -735.0 / 945.0, 64.0 / 945.0)
PADE_DEN = (1.0, -1050.0 / 945.0, 225.0 / 945.0)


class OutsideTaps(np.ndarray):
    """The band-pass taps of the outside fit, tagged with the fit the objective wants (``target``, one of
    TARGETS). The objective hands the data module its ``outside_fir`` alone (training.build), so the choice
    travels with the taps; plain taps mean "ls"."""

    target = "ls"

    def __array_finalize__(self, obj):
        self.target = getattr(obj, "target", "ls")

    # an ndarray pickles its data alone; the tag must reach a data module built in another process too
    def __reduce__(self):
        rebuild, args, state = super().__reduce__()
        return rebuild, args, (state, self.target)

    def __setstate__(self, state):
        super().__setstate__(state[0])
        self.target = state[1]


def outside_taps(fir, target: str) -> OutsideTaps:
    """``fir`` as float64 taps that carry ``target``."""
    check_choice("target", target, TARGETS)
    taps = np.array(fir, dtype=np.float64).view(OutsideTaps)
    taps.target = target
    return taps


def eiv_model(measurement: str) -> str:
    """physics.eiv's model of a recording of this measurement, as baselines.errors_in_variables picks it."""
    return "continuous" if measurement == "continuous" else "discrete"


def transfer_polynomials(model: str, dt: float) -> np.ndarray:
    """a0, a1, a2, b1, b2 (5, m + 1), ascending powers of z^-1: A = a0 + p1 a1 + p2 a2, B = p1 b1 + p2 b2, the
    polynomials of physics.eiv's model. physics.eiv keeps its own private, and no private name crosses modules
    (tests/test_layers.py); tests/data/test_outside_eiv.py holds these to fit_eiv's fits."""
    if model == "discrete":
        return np.array([[1.0, -2.0, 1.0], [0.0, dt, -dt], [0.0, dt * dt, 0.0], [dt, -dt, 0.0], [0.0, dt * dt, 0.0]])
    d = max(2 * len(PADE_NUM) - 1, 2 * len(PADE_DEN) - 2)
    nw, dw = np.array([1.0, -1.0]), np.array([1.0, 1.0])

    def homogeneous(coef, odd):  # sum_j c_j w^(2j + odd), times (1 + z^-1)^d
        terms = [
            c * poly.polymul(poly.polypow(nw, 2 * j + odd), poly.polypow(dw, d - 2 * j - odd))
            for j, c in enumerate(coef)
        ]
        return np.sum([np.pad(t, (0, d + 1 - len(t))) for t in terms], axis=0)

    num, den = 2.0 * homogeneous(PADE_NUM, 1), homogeneous(PADE_DEN, 0)
    a1 = dt * poly.polymul(num, den)
    a2 = dt * dt * poly.polymul(den, den)
    return np.stack([poly.polymul(num, num), a1, a2, a1, a2])


def _positive(h):
    a, b, d = h[..., 0, 0], h[..., 0, 1], h[..., 1, 1]
    return (a > 0) & (d > 0) & (a * d - b * b > 1e-12 * a * d)


def _solve2(h, g):
    """h^-1 g for (n, 2, 2) and (n, 2); NaN where h is not positive definite."""
    a, b, d = h[:, 0, 0], h[:, 0, 1], h[:, 1, 1]
    x = np.stack([d * g[:, 0] - b * g[:, 1], a * g[:, 1] - b * g[:, 0]], axis=1) / (a * d - b * b)[:, None]
    x[~_positive(h)] = np.nan
    return x


class _Joined:
    """The criterion of physics.eiv on joined sequences (n, M) with a junction at ``junction`` (n,) (0: none):
    V(p) = sum_k |A_k S_k - B_k U_k - I_k|^2 / (|A_k|^2 + lambda |B_k|^2) over the full grid, I with m coefficients
    at z^0 and m at z^-J, projected out for each p."""

    def __init__(self, seat, body, junction, dt: float, model: str, noise_ratio: float):
        n, M = seat.shape
        coef = transfer_polynomials(model, dt)
        m = self.m = coef.shape[1] - 1
        k = np.arange(M // 2 + 1)
        x = np.exp(-2j * np.pi * k / M)
        self.weight = np.full(len(k), 2.0)  # the half spectrum's multiplicity in the full grid
        self.weight[0] = 1.0
        if M % 2 == 0:
            self.weight[-1] = 1.0
        a0, a1, a2, b1, b2 = (poly.polyval(x, c) for c in coef)

        def dot(u, v):
            return (u.conj() * v).real

        # W = |A|^2 + lambda |B|^2 = q0 + 2 p1 q1 + 2 p2 q2 + p1^2 q3 + 2 p1 p2 q4 + p2^2 q5
        lam = noise_ratio
        self.q = np.stack(
            [
                dot(a0, a0),
                dot(a0, a1),
                dot(a0, a2),
                dot(a1, a1) + lam * dot(b1, b1),
                dot(a1, a2) + lam * dot(b1, b2),
                dot(a2, a2) + lam * dot(b2, b2),
            ]
        )
        s, u = np.fft.rfft(seat, axis=-1), np.fft.rfft(body, axis=-1)
        self.E = np.stack([a0 * s, a1 * s - b1 * u, a2 * s - b2 * u])  # A S - B U = E0 + p1 E1 + p2 E2
        E1, E2 = self.E[1], self.E[2]
        self.P = np.stack([dot(E1, E1), dot(E1, E2), dot(E2, E2)])
        self.d2W = 2.0 * self.q[3:].T  # d2W / dp_i dp_j (K, 3): 00, 01, 11, constant in p
        self.basis = x[:, None] ** np.arange(m)  # (K, m): z^-j
        self.cos = self.basis.real.copy()  # sum w cos(j theta_k): the Toeplitz normal matrix of one block
        # the junction's block is the first one times z^-J; rows without a junction get a zero block, and an
        # identity in the normal matrix keeps its coefficients at 0
        self.has_junction = junction > 0
        self.shift = np.exp(-2j * np.pi * np.outer(junction, k) / M) * self.has_junction[:, None]
        self.lags = np.exp(2j * np.pi * np.outer(k, np.arange(-(m - 1), m)) / M)  # (K, 2m - 1): e^{i theta l}
        j = np.arange(m)
        self.toeplitz = np.abs(j[:, None] - j[None, :])
        self.cross = j[None, :] - j[:, None] + m - 1  # T[a, m + b] = C(J + b - a)
        self.dof = M - 2 - m - m * self.has_junction

    def evaluate(self, theta, rows):
        """V, the half gradient, the Gauss-Newton and the exact Hessian in theta = log p (those of physics.eiv's
        ``_evaluate``, in real arithmetic where the products allow it), for the rows ``rows``."""
        q, m = self.q, self.m
        p = np.exp(theta)
        p1, p2 = p[:, :1], p[:, 1:]
        W = q[0] + p1 * (2.0 * q[1] + p1 * q[3]) + p2 * (2.0 * q[2] + 2.0 * p1 * q[4] + p2 * q[5])
        w = self.weight / W
        E1, E2 = self.E[1, rows], self.E[2, rows]
        e = self.E[0, rows] + p1 * E1 + p2 * E2
        shift = self.shift[rows]
        back = shift.conj()
        n = len(rows)
        # C(l) = sum_k w_k cos(l theta_k): the normal matrix of the transient is C(lag difference)
        local = w @ self.cos
        cross = ((w * back) @ self.lags).real
        T = np.empty((n, 2 * m, 2 * m))
        T[:, :m, :m] = T[:, m:, m:] = local[:, self.toeplitz]
        T[:, :m, m:] = cross[:, self.cross]
        T[:, m:, :m] = T[:, :m, m:].transpose(0, 2, 1)
        T[~self.has_junction[rows], m:, m:] = np.eye(m)
        T_inv = np.linalg.inv(T)

        conj_basis = self.basis.conj()

        def coupling(v):  # Re sum_k v_k conj(basis_ka), v (c, n, K): (c, n, 2m), the junction's block second
            return np.concatenate([(v @ conj_basis).real, ((v * back) @ conj_basis).real], axis=-1)

        def dot(a, b):
            return np.einsum("nk,nk->n", a, b)

        c = np.einsum("nab,nb->na", T_inv, coupling((w * e)[None])[0])
        eps = e - c[:, :m] @ self.basis.T - shift * (c[:, m:] @ self.basis.T)
        eps2 = eps.real**2 + eps.imag**2
        V = dot(w, eps2)
        # with F_i = E_i - eps dW_i / 2 (the residual's Jacobian at a fixed transient) and G_i = E_i - eps dW_i,
        # a_i = Re(conj(eps) E_i) and P_ij = Re(conj(E_i) E_j) make every sum of physics.eiv's real
        dW = (2.0 * (q[1] + p1 * q[3] + p2 * q[4]) / W, 2.0 * (q[2] + p1 * q[4] + p2 * q[5]) / W)
        D = (w * dW[0], w * dW[1])
        a = (eps.real * E1.real + eps.imag * E1.imag, eps.real * E2.real + eps.imag * E2.imag)
        g = np.stack([dot(w, a[i]) - 0.5 * dot(D[i], eps2) for i in range(2)], axis=1)
        P = self.P[:, rows]
        curvature = (w * eps2 / W) @ self.d2W  # sum w eps2 d2W_ij / W, (n, 3): 00, 01, 11
        gn, ex = np.empty((n, 2, 2)), np.empty((n, 2, 2))
        for i, j, ij in ((0, 0, 0), (0, 1, 1), (1, 1, 2)):
            mixed = dot(D[j], a[i]) + dot(D[i], a[j])
            both = dot(D[i] * eps2, dW[j])
            wp = dot(w, P[ij])
            gn[:, i, j] = gn[:, j, i] = wp - 0.5 * mixed + 0.25 * both
            ex[:, i, j] = ex[:, j, i] = wp - mixed + both - 0.5 * curvature[:, ij]
        # the transient's coupling projected out: the Schur complement
        cE = coupling(w * np.stack([E1, E2]))
        cD = coupling(np.stack(D) * eps)
        for h, half in ((gn, 0.5), (ex, 1.0)):
            b = np.stack([cE[i] - half * cD[i] for i in range(2)], axis=1)
            h -= b @ T_inv @ b.transpose(0, 2, 1)
        scale = p[:, :, None] * p[:, None, :]
        g = g * p
        ex = ex * scale
        ex[:, 0, 0] += g[:, 0]
        ex[:, 1, 1] += g[:, 1]
        return V, g, gn * scale, ex


def fit_joined(seat, body, starts, window: int, dt: float, model: str = "discrete", noise_ratio: float = 1.0, p0=None):
    """The errors-in-variables fit over the samples of each row of (n, N) outside [start, start + window):
    (p, se, ok), p and its relative standard error (n, 2) as physics.eiv.fit_eiv gives them, and ``ok`` (n,)
    where the fit converged inside the box. A row whose window starts at 0 or ends at N has one segment, and no
    junction: its fit is fit_eiv's of that segment. ``p0``: the start (n, 2); NaN or None: the box's centre.

    Why ``ok`` excludes the box's edge and the unconverged: on noisy rows of a smooth road the likelihood can fall
    towards the box's corner, where W grows faster than the residual, with a small se there (data=default, noise
    0.03: 3-7 rows in 400, p1 off by up to 23 times; noise 0.1: 16-19% of the rows, up to 70 times). Those rows
    hold no maximum of the likelihood inside the box.
    """
    seat, body = np.asarray(seat, dtype=np.float64), np.asarray(body, dtype=np.float64)
    n, N = seat.shape
    M = N - window
    starts = np.asarray(starts, dtype=np.int64)
    j = np.arange(M)[None, :]
    index = j + window * (j >= starts[:, None])
    seat, body = np.take_along_axis(seat, index, 1), np.take_along_axis(body, index, 1)
    m = transfer_polynomials(model, dt).shape[1] - 1
    # the second segment's first m equations reach back across the junction; a first segment shorter than m
    # puts some of them in the first block's, and the junction's block at m keeps the two apart
    junction = np.where((starts > 0) & (starts < M), np.clip(starts, m, M - m), 0)
    lo, hi = np.log(P_LO), np.log(P_HI)
    theta0 = np.tile(0.5 * (lo + hi), (n, 1))
    if p0 is not None:
        with np.errstate(invalid="ignore", divide="ignore"):
            start = np.log(np.asarray(p0, dtype=np.float64))
        inside = (np.isfinite(start) & (start >= lo) & (start <= hi)).all(axis=1)
        theta0[inside] = start[inside]
    p, se, ok = np.full((n, 2), np.nan), np.full((n, 2), np.inf), np.zeros(n, bool)
    good = np.isfinite(seat).all(axis=1) & np.isfinite(body).all(axis=1)
    good &= (seat != 0).any(axis=1) | (body != 0).any(axis=1)
    for first in range(0, n, BLOCK):
        rows = np.arange(first, min(first + BLOCK, n))
        rows = rows[good[rows]]
        if not rows.size:
            continue
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            fit = _Joined(seat[rows], body[rows], junction[rows], dt, model, noise_ratio)
            theta, V, gn, converged = _minimise(fit, theta0[rows], lo, hi)
            kappa = V / fit.dof
            a, b, d = gn[:, 0, 0], gn[:, 0, 1], gn[:, 1, 1]
            var = kappa[:, None] * np.stack([d, a], axis=1) / (a * d - b * b)[:, None]
            inside = ((theta > lo + 1e-9) & (theta < hi - 1e-9)).all(axis=1)
            fine = converged & _positive(gn) & (kappa >= 0) & inside
        rows = rows[fine]
        p[rows], se[rows], ok[rows] = np.exp(theta[fine]), np.sqrt(var[fine]), True
    return p, se, ok


def _minimise(fit: _Joined, theta, lo, hi, max_iter: int = OUTSIDE_ITER, tol: float = TOL):
    """physics.eiv's damped Newton iteration (exact Hessian where positive definite, else Gauss-Newton) on every row
    of ``fit`` from theta (n, 2): theta, V, the Gauss-Newton Hessian and the converged flags."""
    rows = np.arange(len(theta))
    theta = theta.copy()
    V, g, gn, ex = fit.evaluate(theta, rows)
    n = len(rows)
    damping = np.full(n, 1e-4)
    done = ~np.isfinite(V)
    converged = np.zeros(n, bool)
    eye = np.eye(2)
    for _ in range(max_iter):
        act = np.flatnonzero(~done)
        if not act.size:
            break
        th, grad = theta[act], g[act]
        h = np.where(_positive(ex[act])[:, None, None], ex[act], gn[act])
        held = ((th <= lo) & (grad > 0)) | ((th >= hi) & (grad < 0))  # on a bound, pushed outwards: stays
        h = np.where(held[:, :, None] | held[:, None, :], eye, h)
        grad = np.where(held, 0.0, grad)
        full = np.clip(th - _solve2(h, grad), lo, hi)
        step = np.max(np.abs(full - th), axis=1)
        stop = step <= tol  # taken unchecked, as physics.eiv does: it brings a clean fit to rounding
        theta[act[stop]] = full[stop]
        converged[act[stop]] = True
        done[act[stop | ~np.isfinite(step)]] = True
        go = np.isfinite(step) & ~stop
        act, th, h, grad = act[go], th[go], h[go], grad[go]
        if not act.size:
            break
        cand = np.clip(th - _solve2(h + damping[act, None, None] * (h * eye), grad), lo, hi)
        Vc, gc, gnc, exc = fit.evaluate(cand, act)
        better = np.isfinite(Vc) & (Vc <= V[act] * (1.0 + 1e-14))
        idx, worse = act[better], act[~better]
        theta[idx], V[idx], g[idx], gn[idx], ex[idx] = cand[better], Vc[better], gc[better], gnc[better], exc[better]
        damping[idx] = np.maximum(damping[idx] * 0.1, 1e-12)
        damping[worse] *= 10.0
        small = np.max(np.abs(cand[better] - th[better]), axis=1) <= tol
        converged[idx[small]] = True
        done[idx[small]] = True
        done[worse[damping[worse] > 1e12]] = True  # no step lowers V: stuck, not converged
    return theta, V, gn, converged


class OutsideFit:
    """The outside fit of the windows of one dataset: ``fit(rows, starts, std, normals)`` -> {"p_out", "se_out"}.

    ``fir``: the objective's band-pass taps (``outside_fir``), whose ``target`` (``OutsideTaps``; plain taps:
    "ls") picks the fit. The clean recordings are the dataset's float32 channels, read as they are stored (no copy
    until a batch takes its rows).
    """

    def __init__(self, seat_acc: np.ndarray, body_acc: np.ndarray, dt: float, measurement: str, window: int, fir):
        self.seat, self.body = seat_acc, body_acc
        self.dt, self.measurement, self.window = dt, measurement, window
        self.target = getattr(fir, "target", "ls")
        check_choice("target", self.target, TARGETS)
        self.fir = np.asarray(fir, dtype=np.float64)
        self.n_steps = seat_acc.shape[1]
        # torch's FFT in float64 takes about a third of numpy's time here (physics.filters.fir_valid's), the
        # larger part of this fit's cost; a transform as long as the recording suffices, as the circular
        # wrap-around reaches only the taps - 1 edge samples that 'valid' drops
        self.nfft = 1 << int(np.ceil(np.log2(self.n_steps)))
        self.fir_fft = torch.fft.rfft(torch.from_numpy(self.fir), self.nfft)

    def mask(self, starts) -> np.ndarray:
        """(B, n_steps - taps + 1) of 1.0 where the filtered sample's FIR support (inputs j .. j + taps - 1) lies
        wholly before or after the window at each start, 0.0 elsewhere."""
        taps = len(self.fir)
        j = np.arange(self.n_steps - taps + 1)
        s = np.asarray(starts, dtype=np.int64)[:, None]
        return ((j + taps - 1 < s) | (j >= s + self.window)).astype(np.float64)

    def fit(self, rows, starts, std=0.0, normals: np.ndarray | None = None) -> dict[str, torch.Tensor]:
        """The batch's "p_out" and "se_out" (B, 2) float64: the fitted p and its relative standard error (NaN
        and inf where the fit is not defined). ``normals`` (B, 2, n_steps) standard normals on the seat and body
        channels, scaled by ``std`` (a number, or one per row); None: the clean recordings. The "eiv" target keeps
        the "ls" fit of a row where its own is not defined, not converged (``fit_joined``) or more than
        MAX_CORRECTION times away from it."""
        rows, starts = np.asarray(rows, dtype=np.int64), np.asarray(starts, dtype=np.int64)
        stds = np.broadcast_to(np.asarray(std, dtype=np.float64), rows.shape)
        p, se = np.empty((len(rows), 2)), np.empty((len(rows), 2))
        for i in range(0, len(rows), CHUNK):
            sl = slice(i, i + CHUNK)
            seat = self.seat[rows[sl]].astype(np.float64)
            body = self.body[rows[sl]].astype(np.float64)
            if normals is not None:
                seat += stds[sl, None] * normals[sl, 0]
                body += stds[sl, None] * normals[sl, 1]
            rel_vel, rel_disp = relative_states(seat, body, self.dt, self.measurement)
            spectra = torch.fft.rfft(torch.from_numpy(np.stack([seat, rel_vel, rel_disp])), self.nfft)
            filtered = torch.fft.irfft(spectra * self.fir_fft, self.nfft)[..., len(self.fir) - 1 : self.n_steps].numpy()
            out = fit_seat(*filtered, weights=self.mask(starts[sl]))
            p[sl], se[sl] = out.p, out.se
            if self.target == "eiv":
                model = eiv_model(self.measurement)
                p_eiv, se_eiv, ok = fit_joined(seat, body, starts[sl], self.window, self.dt, model, p0=out.p)
                with np.errstate(invalid="ignore", divide="ignore"):
                    ok &= (np.abs(np.log(p_eiv / out.p)) <= np.log(MAX_CORRECTION)).all(axis=1)
                p[sl] = np.where(ok[:, None], p_eiv, p[sl])
                se[sl] = np.where(ok[:, None], se_eiv, se[sl])
        return {"p_out": torch.from_numpy(p), "se_out": torch.from_numpy(se)}
