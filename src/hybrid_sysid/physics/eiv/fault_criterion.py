"""The criterion of a fix (physics.eiv.faults): V in theta = (log p1, log p2, eta) with its derivatives, the fault
entering through its fix's body factor (``Fix.body_factor``; the skew's advance lies in physics.faults.skew)."""

from __future__ import annotations

import numpy as np

from hybrid_sysid.physics.eiv.criterion import re_sum
from hybrid_sysid.physics.eiv.matrices import schur
from hybrid_sysid.physics.eiv.model import re_basis
from hybrid_sysid.physics.faults.fix import Fix
from hybrid_sysid.physics.faults.skew import SKEW_HALF_WIDTH, abs2, advance, advance_kernel, unit_powers

__all__ = [
    "SKEW_HALF_WIDTH",
    "abs2",
    "advance",
    "advance_kernel",
    "body_factor",
    "evaluate_fault",
    "evaluate_fault_numpy",
    "unit_powers",
]


def body_factor(fix: Fix, eta, n_samples):
    """The body term's factor phi (A S - phi B U) with its first two derivatives in the fault's parameter, and
    psi = |phi|^2 (W = |A|^2 + lambda psi |B|^2) with its two: the fix's (``Fix.body_factor``)."""
    return fix.body_factor(eta, n_samples)


def evaluate_fault(theta, S, U, X, fix, grid, lam, n_samples, derivatives=True, XA=None):
    """``evaluate_fault_numpy``'s V and derivatives from the compiled kernel (physics.eiv.compiled_criterion: with
    the gain fix, 0.13 ms a call on 4 windows against numpy's 0.55, 1.5 ms on 64 against 6.7)."""
    from hybrid_sysid.physics.eiv.compiled_criterion import evaluate  # numba at the first fault fit, not at start

    factors = body_factor(fix, theta[:, 2], n_samples)
    return evaluate(theta, S, U, X, factors, grid, lam, derivatives, XA)


def evaluate_fault_numpy(theta, S, U, X, fix, grid, lam, n_samples, derivatives=True, XA=None):
    """``evaluate_criterion`` for theta = (log p1, log p2, eta), eta the fault's parameter: the residual
    A S - phi B U + eta X - I with W = |A|^2 + lambda psi |B|^2 (``body_factor``; X: the hardening's cubic term or
    None). V, its half gradient and the Gauss-Newton and exact Hessians in theta, the transient projected out."""
    p = np.exp(theta[:, :2])
    eta = theta[:, 2]
    p1, p2 = p[:, :1], p[:, 1:]
    a0, a1, a2, b1, b2 = grid.polys
    A = a0 + p1 * a1 + p2 * a2
    B = p1 * b1 + p2 * b2
    phi, phi1, phi2, psi, psi1, psi2 = body_factor(fix, eta, n_samples)
    BU = B * U
    e = A * S - phi * BU
    if X is not None:
        e = e + eta[:, None] * X
    QB = abs2(B)
    Aw = A if XA is None else A + eta[:, None] * XA
    W = abs2(Aw) + lam * psi * QB
    w = grid.weight / W
    T = (w @ grid.cos)[:, grid.toeplitz]
    c = np.linalg.solve(T, re_basis(w * e, grid, conj=True)[..., None])[..., 0]
    eps = e - c @ grid.basis.T
    eps2 = abs2(eps)
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
        (0, 0): 2.0 * (abs2(a1) + lam * psi * abs2(b1)),
        (0, 1): 2.0 * ((a1.conj() * a2).real + lam * psi * (b1.conj() * b2).real),
        (1, 1): 2.0 * (abs2(a2) + lam * psi * abs2(b2)),
        (0, 2): lam * psi1 * qb[0],
        (1, 2): lam * psi1 * qb[1],
        (2, 2): lam * psi2 * QB,
    }
    if XA is not None:
        d2W[(0, 2)] = d2W[(0, 2)] + 2.0 * (a1.conj() * XA).real
        d2W[(1, 2)] = d2W[(1, 2)] + 2.0 * (a2.conj() * XA).real
        d2W[(2, 2)] = d2W[(2, 2)] + 2.0 * abs2(XA)
    F = [de[i] - 0.5 * eps * dW[i] for i in range(3)]
    G = [de[i] - eps * dW[i] for i in range(3)]
    wF = [w * f.conj() for f in F]
    wc = w * eps.conj()
    n = len(p)
    g = np.stack([re_sum(wc, F[i]) for i in range(3)], axis=1)
    gn, ex = np.empty((n, 3, 3)), np.empty((n, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            gn[:, i, j] = gn[:, j, i] = re_sum(wF[i], F[j])
            second = re_sum(wc, d2e[(i, j)]) if (i, j) in d2e else 0.0
            ex[:, i, j] = ex[:, j, i] = (
                re_sum(w * de[i].conj(), de[j])
                + second
                - re_sum(wc * dW[j], de[i])
                - re_sum(wc * dW[i], de[j])
                + np.einsum("nk,nk->n", w * eps2, dW[i] * dW[j] - 0.5 * d2W[(i, j)] / W)
            )
    gn = schur(gn, re_basis(np.stack(wF, axis=1), grid), T)
    ex = schur(ex, re_basis(w[:, None] * np.stack(G, axis=1), grid, conj=True), T)
    s = np.concatenate([p, np.ones((n, 1))], axis=1)  # d/dtheta_i = p_i d/dp_i for log p, eta as it is
    g = g * s
    ex = ex * s[:, :, None] * s[:, None, :]
    ex[:, 0, 0] += g[:, 0]
    ex[:, 1, 1] += g[:, 1]
    return V, g, gn * s[:, :, None] * s[:, None, :], ex
