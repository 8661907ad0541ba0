"""The Cramer-Rao bound of the errors-in-variables fit: the plain model's, with or without a fault."""

from __future__ import annotations

import numpy as np

from hybrid_sysid.physics.eiv.criterion import re_sum
from hybrid_sysid.physics.eiv.matrices import inverse_diagonal, positive, schur
from hybrid_sysid.physics.eiv.model import CHUNK, error_spectra, noise_weight, setup_windows


def crb_relative_std(seat_clean, body_clean, p_true, dt: float, noise_ratio: float = 1.0, model: str = "discrete"):
    """The Cramer-Rao bound of std(p_i) / p_i per unit seat noise std (sigma_s = 1; the bound is linear in it),
    (n, 2), for white noise on both channels with sigma_b^2 = noise_ratio sigma_s^2 (0: on the seat alone).

    seat_clean, body_clean: the noise-free windows (n, N); p_true (2,) or (n, 2). The true input and the
    transient's coefficients are nuisance parameters: the Fisher information of log p is the Gauss-Newton Hessian
    of V / N at the clean data and the true p, with the transient projected out (its Schur complement); the input's
    elimination is what the division by W = |A|^2 + lambda |B|^2 does. A window without excitation gives inf.
    """
    seat, body, good, grid, q = setup_windows(seat_clean, body_clean, dt, noise_ratio, model)
    n, N = seat.shape
    p_all = np.broadcast_to(np.asarray(p_true, dtype=float), (n, 2))
    out = np.full((n, 2), np.inf)
    block = max(1, CHUNK // (N // 2 + 1))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for start in range(0, n, block):
            rows = np.arange(start, min(start + block, n))
            rows = rows[good[rows] & (p_all[rows] > 0).all(axis=1) & np.isfinite(p_all[rows]).all(axis=1)]
            if not rows.size:
                continue
            E = error_spectra(seat[rows], body[rows], grid)
            p = p_all[rows]
            w = grid.weight / noise_weight(p, q)
            T = (w @ grid.cos)[:, grid.toeplitz]
            # on clean data the residual vanishes at the true p: the Jacobian is p_i E_i / sqrt(W)
            F = [p[:, i : i + 1] * E[i + 1] for i in range(2)]
            wF = [w * f.conj() for f in F]
            h = np.empty((len(rows), 2, 2))
            for i in range(2):
                for j in range(i, 2):
                    h[:, i, j] = h[:, j, i] = re_sum(wF[i], F[j])
            h = schur(h, np.stack([(wF[i] @ grid.basis).real for i in range(2)], axis=1), T)
            ok = positive(h)
            out[rows[ok]] = np.sqrt(N * inverse_diagonal(h[ok]))
    return out
