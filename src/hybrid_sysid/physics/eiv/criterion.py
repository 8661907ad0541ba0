"""The criterion V of the plain model at theta = log p, with its half gradient and its Gauss-Newton and exact
Hessians, the transient projected out (physics.eiv's docstring has V; the fault's criterion: fault_criterion)."""

from __future__ import annotations

import numpy as np

from hybrid_sysid.physics.eiv.matrices import schur
from hybrid_sysid.physics.eiv.model import noise_weight, re_basis


def re_sum(a, b):
    return np.einsum("nk,nk->n", a, b).real


def evaluate_criterion(theta, E, grid, q, derivatives=True):
    """V at theta = log p for every window of E; with ``derivatives`` also the half gradient g, the Gauss-Newton
    Hessian and the exact Hessian (V(theta + d) ~ V + 2 g^T d + d^T H d), the transient projected out of both."""
    p = np.exp(theta)
    p1, p2 = p[:, :1], p[:, 1:]
    W = noise_weight(p, q)
    w = grid.weight / W
    e = E[0] + p1 * E[1] + p2 * E[2]
    T = (w @ grid.cos)[:, grid.toeplitz]
    c = np.linalg.solve(T, re_basis(w * e, grid, conj=True)[..., None])[..., 0]
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
    g = np.stack([re_sum(wc, F[i]) for i in range(2)], axis=1)
    gn, ex = np.empty((n, 2, 2)), np.empty((n, 2, 2))
    for i in range(2):
        for j in range(i, 2):
            gn[:, i, j] = gn[:, j, i] = re_sum(wF[i], F[j])
            ex[:, i, j] = ex[:, j, i] = (
                re_sum(wE[i], E[j + 1])
                - re_sum(wc * dW[j], E[i + 1])
                - re_sum(wc * dW[i], E[j + 1])
                + np.einsum("nk,nk->n", w * eps2, dW[i] * dW[j] - 0.5 * d2W[i][j] / W)
            )
    gn = schur(gn, re_basis(np.stack(wF, axis=1), grid), T)
    ex = schur(ex, re_basis(w[:, None] * np.stack(G, axis=1), grid, conj=True), T)
    scale = p[:, :, None] * p[:, None, :]  # d/dtheta_i = p_i d/dp_i
    g = g * p
    ex = ex * scale
    ex[:, 0, 0] += g[:, 0]
    ex[:, 1, 1] += g[:, 1]
    return V, g, gn * scale, ex
