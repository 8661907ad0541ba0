"""The criterion of a fix (physics.eiv.faults): V in theta = (log p1, log p2, eta) with its derivatives, and the
skew's advance of the body channel by a Kaiser-windowed sinc."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import special

from hybrid_sysid.physics.eiv.criterion import re_sum
from hybrid_sysid.physics.eiv.matrices import schur
from hybrid_sysid.physics.sensors import BETA_MAX, BETA_PER_TAP

SKEW_HALF_WIDTH = 8  # the skew fix's advance: a Kaiser-windowed sinc of 2 x 8 + 2 taps (physics.eiv.faults)


def abs2(x):
    return x.real**2 + x.imag**2


@lru_cache(maxsize=16)
def unit_powers(n_samples: int, low: int, high: int) -> np.ndarray:
    """z^p on the half spectrum for p = low..high: (high - low + 1, K)."""
    k = np.arange(n_samples // 2 + 1)
    powers = np.exp(2j * np.pi * np.outer(np.arange(low, high + 1), k) / n_samples)
    powers.flags.writeable = False
    return powers


def advance_kernel(u, half_width: int):
    """The advance's interpolation kernel at offsets u and its first two derivatives: the Kaiser-windowed sinc of
    physics.sensors, zero for |u| >= half_width + 1, where the sinc itself vanishes as a tap enters or leaves, so
    the advance is continuous in the delay. The derivatives by central differences: the kernel is analytic within
    its support, and their error (1e-10, 1e-8) is far below what the Newton steps need."""
    support = half_width + 1
    beta = min(BETA_PER_TAP * half_width, BETA_MAX)

    def k(v):
        t = np.sqrt(np.clip(1.0 - (v / support) ** 2, 0.0, None))
        return np.where(np.abs(v) < support, np.sinc(v) * special.i0(beta * t), 0.0) / special.i0(beta)

    e1, e2 = 1e-5, 1e-4
    k0 = k(u)
    return k0, (k(u + e1) - k(u - e1)) / (2.0 * e1), (k(u + e2) - 2.0 * k0 + k(u - e2)) / (e2 * e2)


def advance(delay, n_samples: int, half_width: int):
    """H_k = sum_p K(p - d) z_k^p over the taps |p - d| < half_width + 1, and its first two derivatives in d, on
    the half spectrum (n, K): the body channel advanced by d samples (the skew fix)."""
    whole = np.floor(delay)
    low, high = int(whole.min()) - half_width, int(whole.max()) + half_width + 1
    taps = advance_kernel(np.arange(low, high + 1) - delay[:, None], half_width)
    h = np.concatenate(taps) @ unit_powers(n_samples, low, high)
    n = len(delay)
    return h[:n], -h[n : 2 * n], h[2 * n :]


def body_factor(fix, eta, n_samples):
    """The body term's factor phi (A S - phi B U) with its first two derivatives in the fault's parameter, and
    psi = |phi|^2 (W = |A|^2 + lambda psi |B|^2) with its two: (n, K) or (n, 1) arrays, or scalars."""
    if fix == "gain":
        g = np.exp(eta)[:, None]
        return g, g, g, g * g, 2.0 * g * g, 4.0 * g * g
    if fix == "skew":
        h, h1, h2 = advance(eta, n_samples, SKEW_HALF_WIDTH)
        return h, h1, h2, abs2(h), 2.0 * (h.conj() * h1).real, 2.0 * (abs2(h1) + (h.conj() * h2).real)
    return 1.0, 0.0, 0.0, 1.0, 0.0, 0.0


def evaluate_fault(theta, S, U, X, fix, grid, lam, n_samples, derivatives=True, XA=None):
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
    c = np.linalg.solve(T, ((w * e) @ grid.basis.conj()).real[..., None])[..., 0]
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
    gn = schur(gn, np.stack([(wF[i] @ grid.basis).real for i in range(3)], axis=1), T)
    ex = schur(ex, np.stack([((w * G[i]) @ grid.basis.conj()).real for i in range(3)], axis=1), T)
    s = np.concatenate([p, np.ones((n, 1))], axis=1)  # d/dtheta_i = p_i d/dp_i for log p, eta as it is
    g = g * s
    ex = ex * s[:, :, None] * s[:, None, :]
    ex[:, 0, 0] += g[:, 0]
    ex[:, 1, 1] += g[:, 1]
    return V, g, gn * s[:, :, None] * s[:, None, :], ex
