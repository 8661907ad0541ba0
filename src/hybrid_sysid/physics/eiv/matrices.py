"""The small matrices of the fit: the (2, 2) and (3, 3) Hessians of each window, tested, solved and inverted
in closed form or batched, and the transient's Schur complement."""

from __future__ import annotations

import numpy as np


def schur(h, b, t):
    """h - b t^-1 b^T: (n, 2, 2) with the transient's (n, 2, m) coupling b and (n, m, m) normal matrix t."""
    return h - b @ np.linalg.solve(t, b.transpose(0, 2, 1))


def positive(h):
    """Whether each (2, 2) or (3, 3) matrix is positive definite, with a margin for rounding."""
    a, b, d = h[..., 0, 0], h[..., 0, 1], h[..., 1, 1]
    ok = (a > 0) & (d > 0) & (a * d - b * b > 1e-12 * a * d)
    if h.shape[-1] == 2:
        return ok
    with np.errstate(invalid="ignore", over="ignore"):
        return ok & (h[..., 2, 2] > 0) & (np.linalg.det(h) > 1e-12 * (a * d - b * b) * h[..., 2, 2])


def solve_positive(h, g):
    """h^-1 g for (n, P, P) and (n, P), P = 2 or 3; NaN where h is not positive definite."""
    if h.shape[-1] != 2:
        ok = positive(h)
        x = np.full(g.shape, np.nan)
        if ok.any():
            x[ok] = np.linalg.solve(h[ok], g[ok][..., None])[..., 0]
        return x
    a, b, d = h[:, 0, 0], h[:, 0, 1], h[:, 1, 1]
    x = np.stack([d * g[:, 0] - b * g[:, 1], a * g[:, 1] - b * g[:, 0]], axis=1) / (a * d - b * b)[:, None]
    x[~positive(h)] = np.nan
    return x


def inverse_diagonal(h):
    if h.shape[-1] != 2:
        return np.diagonal(np.linalg.inv(h), axis1=1, axis2=2)
    a, b, d = h[:, 0, 0], h[:, 0, 1], h[:, 1, 1]
    return np.stack([d, a], axis=1) / (a * d - b * b)[:, None]
