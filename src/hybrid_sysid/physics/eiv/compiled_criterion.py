"""The fault fix's criterion compiled with numba (physics.eiv.fault_criterion, ``evaluate_fault``).

A fit's damped Newton iterations evaluate the criterion on fewer and fewer windows as they converge, and numpy's
hundred-odd array operations a call cost about a millisecond whatever the number of windows: on a training batch
of experiment=anchored under a fault, the calls on 16 windows or fewer took 40-60% of the criterion's time. The
kernel takes one window at a time, in one pass over the frequencies for the transient's projection and one for V
and its derivatives. It equals ``fault_criterion.evaluate_fault_numpy`` to rounding, not bit for bit, as its sums
run in another order (tests/physics/test_compiled_criterion.py). Imported at the first fault fit, not by
``hybrid_sysid.physics``; cached on disk, as the kernel reads nothing from another file.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, error_model="numpy")
def _cholesky_solve(t, b, out):
    """out = T^-1 b for each column of b (M, R), T the Toeplitz matrix of its first row t (M,): positive
    definite, as the weights are; NaN propagates where they are not finite."""
    m = t.shape[0]
    low = np.zeros((m, m))
    for i in range(m):
        for j in range(i + 1):
            s = t[i - j]
            for q in range(j):
                s -= low[i, q] * low[j, q]
            low[i, j] = np.sqrt(s) if i == j else s / low[j, j]
    for r in range(b.shape[1]):
        for i in range(m):
            s = b[i, r]
            for q in range(i):
                s -= low[i, q] * out[q, r]
            out[i, r] = s / low[i, i]
        for i in range(m - 1, -1, -1):
            s = out[i, r]
            for q in range(i + 1, m):
                s -= low[q, i] * out[q, r]
            out[i, r] = s / low[i, i]


@numba.njit(cache=True, error_model="numpy")
def _kernel(p, eta, S, U, X, XA, factors, psis, polys, weight, cos, br, bi, lam, derivatives, V, g, gn, ex):
    """cos, br, bi: the grid's cos, basis.real and basis.imag transposed, (M, K): the loops over the transient's
    basis run along the frequencies, contiguous. X, XA (n, K) and the body factor's (3, n, K) may have length 1
    along either axis, broadcast as numpy would: a constant factor is not spread over every window and frequency."""
    n, K = S.shape
    fi, fk = int(factors.shape[1] > 1), int(factors.shape[2] > 1)
    xi, xk = int(X.shape[0] > 1), int(X.shape[1] > 1)
    ai, ak = int(XA.shape[0] > 1), int(XA.shape[1] > 1)
    M = br.shape[0]
    a0, a1, a2, b1, b2 = polys[0], polys[1], polys[2], polys[3], polys[4]
    e = np.empty(K, np.complex128)
    epsr, epsi = np.empty(K), np.empty(K)
    w, W = np.empty(K), np.empty(K)
    A, B = np.empty(K, np.complex128), np.empty(K, np.complex128)
    wf, wg = np.empty((3, K), np.complex128), np.empty((3, K), np.complex128)
    t = np.empty(M)
    rhs, c = np.empty((M, 1)), np.empty((M, 1))
    bg, be, sol = np.empty((M, 3)), np.empty((M, 3)), np.empty((M, 3))
    de, F = np.empty(3, np.complex128), np.empty(3, np.complex128)
    d2e = np.zeros((3, 3), np.complex128)
    dW, d2W = np.empty(3), np.empty((3, 3))
    g_, gn_, ex_ = np.empty(3), np.empty((3, 3)), np.empty((3, 3))
    for i in range(n):
        p1, p2, et = p[i, 0], p[i, 1], eta[i]
        for k in range(K):
            A[k] = a0[k] + p1 * a1[k] + p2 * a2[k]
            B[k] = p1 * b1[k] + p2 * b2[k]
            e[k] = A[k] * S[i, k] - factors[0, i * fi, k * fk] * (B[k] * U[i, k]) + et * X[i * xi, k * xk]
            aw = A[k] + et * XA[i * ai, k * ak]
            W[k] = aw.real**2 + aw.imag**2 + lam * psis[0, i * fi, k * fk] * (B[k].real ** 2 + B[k].imag ** 2)
            w[k] = weight[k] / W[k]
        # the transient's normal matrix (Toeplitz: its first row) and right side
        for j in range(M):
            tj, rj = 0.0, 0.0
            for k in range(K):
                tj += w[k] * cos[j, k]
                rj += w[k] * (e[k].real * br[j, k] + e[k].imag * bi[j, k])
            t[j], rhs[j, 0] = tj, rj
        _cholesky_solve(t, rhs, c)
        for k in range(K):
            epsr[k], epsi[k] = e[k].real, e[k].imag
        for j in range(M):
            cj = c[j, 0]
            for k in range(K):
                epsr[k] -= cj * br[j, k]
                epsi[k] -= cj * bi[j, k]
        v = 0.0
        g_[:] = 0.0
        gn_[:] = 0.0
        ex_[:] = 0.0
        for k in range(K):
            eps = complex(epsr[k], epsi[k])
            eps2 = epsr[k] ** 2 + epsi[k] ** 2
            v += w[k] * eps2
            if not derivatives:
                continue
            u, s_ = U[i, k], S[i, k]
            phi, phi1, phi2 = factors[0, i * fi, k * fk], factors[1, i * fi, k * fk], factors[2, i * fi, k * fk]
            psi, psi1, psi2 = psis[0, i * fi, k * fk], psis[1, i * fi, k * fk], psis[2, i * fi, k * fk]
            bu = B[k] * u
            u1, u2 = b1[k] * u, b2[k] * u
            de[0] = a1[k] * s_ - phi * u1
            de[1] = a2[k] * s_ - phi * u2
            de[2] = -phi1 * bu + X[i * xi, k * xk]
            d2e[0, 2] = -phi1 * u1
            d2e[1, 2] = -phi1 * u2
            d2e[2, 2] = -phi2 * bu
            qb = B[k].real ** 2 + B[k].imag ** 2
            qb0 = 2.0 * (B[k].conjugate() * b1[k]).real
            qb1 = 2.0 * (B[k].conjugate() * b2[k]).real
            xa = XA[i * ai, k * ak]
            aw = A[k] + et * xa
            dW[0] = (2.0 * (aw.conjugate() * a1[k]).real + lam * psi * qb0) / W[k]
            dW[1] = (2.0 * (aw.conjugate() * a2[k]).real + lam * psi * qb1) / W[k]
            dW[2] = (lam * psi1 * qb + 2.0 * (aw.conjugate() * xa).real) / W[k]
            d2W[0, 0] = 2.0 * (a1[k].real ** 2 + a1[k].imag ** 2 + lam * psi * (b1[k].real ** 2 + b1[k].imag ** 2))
            d2W[0, 1] = 2.0 * ((a1[k].conjugate() * a2[k]).real + lam * psi * (b1[k].conjugate() * b2[k]).real)
            d2W[1, 1] = 2.0 * (a2[k].real ** 2 + a2[k].imag ** 2 + lam * psi * (b2[k].real ** 2 + b2[k].imag ** 2))
            d2W[0, 2] = lam * psi1 * qb0 + 2.0 * (a1[k].conjugate() * xa).real
            d2W[1, 2] = lam * psi1 * qb1 + 2.0 * (a2[k].conjugate() * xa).real
            d2W[2, 2] = lam * psi2 * qb + 2.0 * (xa.real**2 + xa.imag**2)
            wk = w[k]
            wc = wk * eps.conjugate()
            for a in range(3):
                F[a] = de[a] - 0.5 * eps * dW[a]
                g_[a] += (wc * F[a]).real
                wf[a, k] = wk * F[a].conjugate()
                wg[a, k] = wk * (de[a] - eps * dW[a])
            for a in range(3):
                for b in range(a, 3):
                    gn_[a, b] += (wf[a, k] * F[b]).real
                    ex_[a, b] += (
                        (wk * de[a].conjugate() * de[b]).real
                        + (wc * d2e[a, b]).real
                        - (wc * dW[b] * de[a]).real
                        - (wc * dW[a] * de[b]).real
                        + wk * eps2 * (dW[a] * dW[b] - 0.5 * d2W[a, b] / W[k])
                    )
        V[i] = v
        if not derivatives:
            continue
        # the transient projected out of both Hessians: h - b^T T^-1 b, b the coupling of theta and the transient
        for j in range(M):
            for a in range(3):
                sg, se = 0.0, 0.0
                for k in range(K):
                    sg += wf[a, k].real * br[j, k] - wf[a, k].imag * bi[j, k]
                    se += wg[a, k].real * br[j, k] + wg[a, k].imag * bi[j, k]
                bg[j, a], be[j, a] = sg, se
        for coupling, h in ((bg, gn_), (be, ex_)):
            _cholesky_solve(t, coupling, sol)
            for a in range(3):
                for b in range(a, 3):
                    s = 0.0
                    for j in range(M):
                        s += coupling[j, a] * sol[j, b]
                    h[a, b] -= s
        scale = (p1, p2, 1.0)  # d/dtheta_i = p_i d/dp_i for log p, eta as it is
        for a in range(3):
            g[i, a] = g_[a] * scale[a]
        for a in range(3):
            for b in range(3):
                lo, hi = min(a, b), max(a, b)
                gn[i, a, b] = gn_[lo, hi] * scale[a] * scale[b]
                ex[i, a, b] = ex_[lo, hi] * scale[a] * scale[b]
        ex[i, 0, 0] += g[i, 0]
        ex[i, 1, 1] += g[i, 1]


def evaluate(theta, S, U, X, body_factor, grid, lam, derivatives=True, XA=None):
    """``evaluate_fault_numpy``'s (V, g, Gauss-Newton Hessian, exact Hessian) from the compiled kernel, with the
    fix's ``body_factor`` (phi, phi', phi'', psi, psi', psi'') already evaluated at theta's eta."""
    n, K = S.shape

    def compact(values, dtype):  # (3, 1 or n, 1 or K): what the three broadcast to, no larger
        values = [np.asarray(v, dtype=dtype).reshape((1,) * (2 - np.ndim(v)) + np.shape(v)) for v in values]
        return np.ascontiguousarray(np.stack(np.broadcast_arrays(*values)))

    zero = np.zeros((1, 1), np.complex128)
    theta = np.asarray(theta, dtype=np.float64)
    V = np.empty(n)
    g, gn, ex = np.empty((n, 3)), np.empty((n, 3, 3)), np.empty((n, 3, 3))
    _kernel(
        np.exp(theta[:, :2]),
        np.ascontiguousarray(theta[:, 2]),
        np.ascontiguousarray(S, dtype=np.complex128),
        np.ascontiguousarray(U, dtype=np.complex128),
        zero if X is None else np.ascontiguousarray(X, dtype=np.complex128),
        zero if XA is None else np.ascontiguousarray(XA, dtype=np.complex128),
        compact(body_factor[:3], np.complex128),
        compact(body_factor[3:], np.float64),
        np.ascontiguousarray(grid.polys, dtype=np.complex128),
        np.ascontiguousarray(grid.weight, dtype=np.float64),
        np.ascontiguousarray(grid.cos.T, dtype=np.float64),
        np.ascontiguousarray(grid.basis_re.T),
        np.ascontiguousarray(grid.basis_im.T),
        float(lam),
        bool(derivatives),
        V,
        g,
        gn,
        ex,
    )
    if not derivatives:
        return V, None, None, None
    return V, g, gn, ex
