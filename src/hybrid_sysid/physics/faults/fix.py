"""What a fault's classical fix declares (docs/faults.md, "Adding a fault"): the fault as one more parameter eta,
fitted with p by the band-passed least squares (``least_squares``, estimator=ls_fix) and by the errors-in-variables
likelihood (the ``eiv_*`` hooks and ``body_factor``, estimator=eiv_fix). A fault's file defines its fix beside it
(``Fault.fix_code``); baselines.fixes and physics.eiv.faults call these hooks and name no fix. Plain numpy.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import numpy as np

from hybrid_sysid.physics.filters import fir_valid


class FaultProblem(NamedTuple):
    """One block of windows for a fix's own likelihood fit (``Fix.eiv_problem``), with the fitting machinery passed
    in, so a fault's file imports none of physics.eiv. ``evaluator(S, U, X, XA=None)``: the function
    ``evaluate(theta, rows)`` of V and its derivatives in theta = (log p1, log p2, eta) that ``minimise`` takes, X
    the term eta multiplies in the residual and XA its noise (or None); ``minimise(evaluate, theta, lo, hi,
    max_iter, tol, prior, kappa)``: the damped Newton (physics.eiv.newton)."""

    seat: np.ndarray  # (n, N) float64
    body: np.ndarray
    S: np.ndarray  # their half spectra (n, K)
    U: np.ndarray
    theta: np.ndarray  # (n, 3) the start: log p, and eta = 0
    grid: Any  # physics.eiv.model's frequency grid
    lam: float
    dt: float
    model: str
    lo: np.ndarray  # (3,) the box of theta
    hi: np.ndarray
    max_iter: int
    tol: float
    evaluator: Callable
    minimise: Callable


class Fix:
    """A classical fix. Subclasses set ``name`` (baseline.fix) and override ``least_squares``; the likelihood's
    hooks default to a fault that scales the body channel by phi(eta) (``body_factor``), eta starting at 0."""

    name: str = ""

    def least_squares(self, seat, body, rel_vel, rel_disp, dt: float, measurement: str, fir, skew_max: float):
        """p (n, 2) of windows (n, W) by the band-passed least squares with the fault's parameter (``rel_vel``,
        ``rel_disp``: the regressors integrated from t0 and cropped, as the data module serves them)."""
        raise NotImplementedError(f"fix {self.name!r}: no least-squares fit")

    def eiv_bound(self, skew_max: float, dt: float) -> tuple[float, float]:
        """The box of eta in the likelihood fit."""
        return -np.inf, np.inf

    def eiv_edges(self, skew_max: float, dt: float) -> tuple[int, int]:
        """Samples at a window's start and end the fix's residual reaches across (the transient widens by them)."""
        return 0, 0

    def eiv_starts(self, lo: np.ndarray, hi: np.ndarray):
        """Values of eta whose criterion at the start's p picks eta's start (a coarse search), or None: eta = 0."""
        return None

    def body_factor(self, eta: np.ndarray, n_samples: int):
        """phi (A S - phi B U) with its first two derivatives in eta, and psi = |phi|^2 (W = |A|^2 + lambda psi
        |B|^2) with its two: (n, K) or (n, 1) arrays, or scalars."""
        return 1.0, 0.0, 0.0, 1.0, 0.0, 0.0

    def eiv_fault(self, eta: np.ndarray, dt: float) -> np.ndarray:
        """EivFit.fault, the fitted fault in its unit, from eta."""
        return eta

    def eiv_problem(self, problem: FaultProblem):
        """A fit of its own instead of the body factor's: (solve, theta (n, 3), to_fault) as
        physics.eiv.faults.fault_problem returns them; None (the default) takes the body factor's."""
        return None


def lstsq_columns(columns: list[np.ndarray], y: np.ndarray, fir: np.ndarray | None) -> np.ndarray:
    """Per row, the coefficients (n, k) of y (n, T) on k columns (each (n, T)), after ``fir`` on all of them.

    Batched QR of the columns scaled to unit norm: the integrals of the seat and of the body are nearly collinear
    (the seat follows the body), so the normal equations would square an already large condition number. A row
    whose columns are dependent gives NaN."""
    if fir is not None:
        columns, y = [fir_valid(c, fir) for c in columns], fir_valid(y, fir)
    a = np.stack([np.asarray(c, dtype=np.float64) for c in columns], axis=-1)  # (n, T, k)
    scale = np.linalg.norm(a, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        q, r = np.linalg.qr(a / scale)
        diag = np.abs(np.diagonal(r, axis1=1, axis2=2))
        ok = (diag > 1e-10).all(axis=1) & np.isfinite(diag).all(axis=1)
        out = np.full((len(a), a.shape[2]), np.nan)
        if ok.any():
            rhs = np.einsum("ntk,nt->nk", q[ok], np.asarray(y, dtype=np.float64)[ok])
            out[ok] = np.linalg.solve(r[ok], rhs[..., None])[..., 0] / scale[ok, 0]
    return out
