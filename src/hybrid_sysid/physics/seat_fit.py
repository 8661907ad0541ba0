"""The seat equation fitted by least squares, with the statistics a fit can give about itself (plain numpy).

z''_k = -p1 rel_vel_k - p2 rel_disp_k is linear in p, so every row (a window, a recording, the samples of a
recording outside a window) gives p by regressing the seat acceleration on (-rel_vel, -rel_disp). ``fit_seat``
returns that p with its relative standard error, the share of the seat signal the fit leaves unexplained and the
correlation of the two regressors: what an estimator needs to judge how far to trust the fit (model/anchored.py)
and what a label-free target needs to weigh it (model/cross_segment.py).

The standard error is the textbook one, sqrt(s^2 (A^T A)^-1_ii) with s^2 = RSS / (n - 2). On band-passed
signals the residual is coloured, so it is too small by a factor that depends on the band, not on the window:
it ranks fits, it is not a calibrated interval.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from hybrid_sysid.physics.filters import fir_valid
from hybrid_sysid.physics.integrate import relative_states


class SeatFit(NamedTuple):
    """Per row, float64: ``p`` (n, 2) the fitted (p1, p2); ``se`` (n, 2) their standard errors relative to |p|;
    ``unexplained`` (n,) RSS / sum(seat^2), in [0, 1]; ``correlation`` (n,) of rel_vel and rel_disp over the row.
    A row whose fit is not defined (fewer than 3 samples, a vanishing or dependent regressor) has NaN in p and
    infinite se."""

    p: np.ndarray
    se: np.ndarray
    unexplained: np.ndarray
    correlation: np.ndarray


def fit_seat(seat, rel_vel, rel_disp, weights=None) -> SeatFit:
    """Least squares of seat = -p1 rel_vel - p2 rel_disp per row of (n, T) arrays; ``weights`` (n, T) of 0 and
    1 (or None: all 1) selects the samples of each row that take part.

    Each regressor is scaled to unit norm before the 2 x 2 normal equations are solved, so their condition is
    that of the regressors' correlation, not of their scales (rel_disp is ~sqrt(p2) ~ 30 times smaller).
    """
    y, a, b = (np.asarray(v, dtype=np.float64) for v in (seat, rel_vel, rel_disp))
    w = np.ones_like(y) if weights is None else np.asarray(weights, dtype=np.float64)
    n = w.sum(axis=-1)
    saa, sbb, sab = (w * a * a).sum(-1), (w * b * b).sum(-1), (w * a * b).sum(-1)
    say, sby, syy = (w * a * y).sum(-1), (w * b * y).sum(-1), (w * y * y).sum(-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        na, nb = np.sqrt(saa), np.sqrt(sbb)
        rho = sab / (na * nb)
        det = 1.0 - rho * rho  # of the scaled normal matrix [[1, rho], [rho, 1]]
        ca, cb = say / na, sby / nb  # scaled right-hand side
        qa, qb = (ca - rho * cb) / det, (cb - rho * ca) / det  # scaled coefficients of +rel_vel, +rel_disp
        # from the residual itself: y'y - q'c would cancel to rounding noise on a near-exact fit
        resid = y - (qa / na)[..., None] * a - (qb / nb)[..., None] * b
        rss = (w * resid * resid).sum(-1)
        s2 = rss / (n - 2)
        p = np.stack([-qa / na, -qb / nb], axis=-1)
        var = np.stack([s2 / det / saa, s2 / det / sbb], axis=-1)  # s^2 (A^T A)^-1 on the diagonal
        se = np.sqrt(var) / np.abs(p)
        unexplained = np.where(syy > 0, rss / syy, 1.0)
    bad = ~((n > 2) & (na > 0) & (nb > 0) & (det > 1e-12) & np.isfinite(p).all(axis=-1))
    p[bad] = np.nan
    se[bad[:, None] | ~np.isfinite(se)] = np.inf
    return SeatFit(p, se, np.clip(unexplained, 0.0, 1.0), np.where(bad, 0.0, rho))


def fit_windows(seat, body, dt: float, measurement: str, fir: np.ndarray) -> SeatFit:
    """The band-passed fit of windows (n, W) of recorded seat and body accelerations, each window on its own.

    The regressors are integrated from the window's start: what came before adds a constant to rel_vel and a
    constant and a ramp to rel_disp, which a symmetric band-pass of zero sum removes (zero gain at DC and for a
    ramp), so the filtered signals are those of an integration from t0. The FIR's 'valid' part is fitted.
    """
    seat = np.asarray(seat, dtype=np.float64)
    rel_vel, rel_disp = relative_states(seat, body, dt, measurement)
    return fit_seat(*(fir_valid(x, fir) for x in (seat, rel_vel, rel_disp)))
