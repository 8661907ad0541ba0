"""The fit of the seat over a recording's samples outside a window by errors-in-variables: the "eiv" target of
``objective=cross_segment`` (data.outside computes the batches' targets, "ls" among them).

The maximum likelihood (physics.eiv) of the two outside segments [0, start) and [start + W, n) together, started
from the "ls" fit. The segments, joined, make one sequence of n - W samples for every start, so the fit is
vectorised over rows as fit_eiv is over windows. physics.eiv's model, A S - B U = I + noise in the DFT of one
sequence, holds for the joined one with a second transient: where the second segment begins, A and B reach back into
the first segment's end instead of the window, which changes the first m equations of the second segment only. So I
has m coefficients at the circle's start (the wrap from the end to the start) and m more at the junction
(``fit_joined``). The noise of the joined samples is still white and the DFT's circular convolution still exact, so
the likelihood is physics.eiv's, with 2 m transient coefficients instead of m; only raw samples outside the window
enter it, and the "ls" start too reads none.

Why one joint fit and not fit_eiv on pieces of a fixed length, combined by inverse-variance weights: measured on
data=default (seat_spread 0.3, 400 rows, noise 0.03), pieces of 100 to 350 samples missed p1 by 19-29% on average
(inverse-variance weights: 28-167%, the short fits' se being wrong where their p is), against the least squares'
15% and the joint fit's 13%.
"""

from __future__ import annotations

import numpy as np

from hybrid_sysid.physics.eiv import (
    P_HI,
    P_LO,
    TOL,
    error_spectra,
    frequency_grid,
    minimise,
    noise_weight,
    positive,
    weight_coefficients,
)

BLOCK = 64  # rows of one likelihood fit: its ~40 arrays of (rows, n_steps - window) stay in the cache
# Newton iterations of the outside fit. From the least-squares start every row of data=default at noise 0.03
# converges within 20; at noise 0.1 the 0.2% that need more end where 50 would, or keep the least squares. The
# last iterations run on a few rows each, at the cost of a full one: at noise 0.1, 20 halve the fit's work.
OUTSIDE_ITER = 20


class _Joined:
    """The criterion of physics.eiv on joined sequences (n, M) with a junction at ``junction`` (n,) (0: none):
    V(p) = sum_k |A_k S_k - B_k U_k - I_k|^2 / (|A_k|^2 + lambda |B_k|^2) over the full grid, I with m coefficients
    at z^0 and m at z^-J, projected out for each p."""

    def __init__(self, seat, body, junction, dt: float, model: str, noise_ratio: float):
        n, M = seat.shape
        grid = frequency_grid(model, dt, M)  # physics.eiv's, whose transient block is the first one here
        m = self.m = grid.basis.shape[1]
        k = np.arange(M // 2 + 1)
        self.weight, self.basis, self.cos, self.toeplitz = grid.weight, grid.basis, grid.cos, grid.toeplitz
        self.q = weight_coefficients(grid, noise_ratio)
        self.E = error_spectra(seat, body, grid)  # A S - B U = E0 + p1 E1 + p2 E2
        E1, E2 = self.E[1], self.E[2]

        def dot(u, v):
            return (u.conj() * v).real

        self.P = np.stack([dot(E1, E1), dot(E1, E2), dot(E2, E2)])
        self.d2W = 2.0 * self.q[3:].T  # d2W / dp_i dp_j (K, 3): 00, 01, 11, constant in p
        # the junction's block is the first one times z^-J; rows without a junction get a zero block, and an
        # identity in the normal matrix keeps its coefficients at 0
        self.has_junction = junction > 0
        self.shift = np.exp(-2j * np.pi * np.outer(junction, k) / M) * self.has_junction[:, None]
        self.lags = np.exp(2j * np.pi * np.outer(k, np.arange(-(m - 1), m)) / M)  # (K, 2m - 1): e^{i theta l}
        j = np.arange(m)
        self.cross = j[None, :] - j[:, None] + m - 1  # T[a, m + b] = C(J + b - a)
        self.dof = M - 2 - m - m * self.has_junction

    def evaluate(self, theta, rows):
        """V, the half gradient, the Gauss-Newton and the exact Hessian in theta = log p (those of physics.eiv's
        ``evaluate_criterion``, in real arithmetic where the products allow it), for the rows ``rows`` (None: all,
        as physics.eiv.minimise asks first)."""
        if rows is None:
            rows = np.arange(len(theta))
        q, m = self.q, self.m
        p = np.exp(theta)
        p1, p2 = p[:, :1], p[:, 1:]
        W = noise_weight(p, q)
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
    m = frequency_grid(model, dt, M).basis.shape[1]
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
            theta, V, gn, converged = minimise(fit.evaluate, theta0[rows], lo, hi, OUTSIDE_ITER, TOL)
            kappa = V / fit.dof
            a, b, d = gn[:, 0, 0], gn[:, 0, 1], gn[:, 1, 1]
            var = kappa[:, None] * np.stack([d, a], axis=1) / (a * d - b * b)[:, None]
            inside = ((theta > lo + 1e-9) & (theta < hi - 1e-9)).all(axis=1)
            fine = converged & positive(gn) & (kappa >= 0) & inside
        rows = rows[fine]
        p[rows], se[rows], ok[rows] = np.exp(theta[fine]), np.sqrt(var[fine]), True
    return p, se, ok
