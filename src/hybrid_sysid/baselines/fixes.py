"""The classical fix of each recording fault (docs/faults.md): one more parameter in the band-passed least-squares
fit of the seat equation, so the fault is estimated with p instead of biasing it. Plain numpy, per window.

- "gain": each sensor's gain unknown. With g = g_seat / g_body, the recorded seat a_s obeys
  a_s = -p1 V_s - p2 X_s + g p1 V_b + g p2 X_b, where (V_s, X_s) and (V_b, X_b) integrate the recorded seat and
  body on their own: linear in four coefficients, of which the first two are p.
- "skew": the body sensor's time offset unknown. The body channel is moved back by each candidate offset on a grid
  (a fractional delay, physics.sensors) and the offset whose fit leaves the least residual is kept.
- "hardening": a hardening seat spring, a_s = -p1 V - p2 X - p2 kappa X^3: linear in three coefficients with the
  cube of the relative displacement as the third regressor; p2 is the small-amplitude stiffness.
"""

from __future__ import annotations

import numpy as np

from hybrid_sysid.physics import relative_states
from hybrid_sysid.physics.filters import fir_valid
from hybrid_sysid.physics.seat_fit import fit_seat
from hybrid_sysid.physics.sensors import delay_taps, fractional_delay  # the fault's own interpolator


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


def fit_gain(seat, body, dt: float, measurement: str, fir: np.ndarray) -> np.ndarray:
    """p (n, 2) with each sensor's gain unknown: four regressors, the seat's and the body's integrals apart."""
    zero = np.zeros_like(np.asarray(seat, dtype=np.float64))
    vs, xs = relative_states(seat, zero, dt, measurement)
    vb, xb = relative_states(zero, body, dt, measurement)  # minus the body's: relative_states is linear
    return lstsq_columns([-vs, -xs, -vb, -xb], seat, fir)[:, :2]


def detrend(x: np.ndarray) -> np.ndarray:
    """x minus its least-squares line per row: what integration from t0 and drift leave in a window."""
    t = np.linspace(-1.0, 1.0, x.shape[-1])
    x = np.asarray(x, dtype=np.float64)
    return x - x.mean(axis=-1, keepdims=True) - np.outer((x * t).sum(-1) / (t * t).sum(), t)


def fit_hardening(seat, rel_vel, rel_disp, fir: np.ndarray) -> np.ndarray:
    """p (n, 2) with the cube of the (detrended) relative displacement as a third regressor."""
    return lstsq_columns([-rel_vel, -rel_disp, -(detrend(rel_disp) ** 3)], seat, fir)[:, :2]


def fit_skew(seat, body, dt: float, measurement: str, fir: np.ndarray, skew_max: float, grid: int = 21) -> np.ndarray:
    """p (n, 2) with the body sensor's time offset unknown, searched per window over ``grid`` offsets in
    [-skew_max, skew_max] seconds, then refined by the parabola through the best offset and its neighbours.

    The body window is moved back by each offset (physics.sensors.fractional_delay) and re-integrated from the
    window's start; the delay's inexact edge samples only shift the integrals by a constant and a ramp at the
    start, which the band-pass removes, and lie in the part 'valid' drops at the end."""
    seat, body = np.asarray(seat, dtype=np.float64), np.asarray(body, dtype=np.float64)
    n = len(seat)
    offsets = np.linspace(-skew_max, skew_max, grid) if skew_max > 0 else np.zeros(1)
    seat_f = fir_valid(seat, fir)  # the fitted signal does not move: filtered once, not once per offset

    def fit_at(moved: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rel_vel, rel_disp = relative_states(seat, moved, dt, measurement)
        fit = fit_seat(seat_f, fir_valid(rel_vel, fir), fir_valid(rel_disp, fir))
        return fit.p, np.where(np.isfinite(fit.unexplained), fit.unexplained, np.inf)

    rss = np.stack([fit_at(moved)[1] for moved in delayed_copies(body, -offsets / dt)], axis=1)  # (n, grid)
    best = np.argmin(rss, axis=1)
    delay = offsets[best]
    inner = (best > 0) & (best < len(offsets) - 1)
    if inner.any():  # the vertex of the parabola through the best three, within one grid step
        i = best[inner]
        r = np.arange(n)[inner]
        lo, mid, hi = rss[r, i - 1], rss[r, i], rss[r, i + 1]
        curve = lo - 2 * mid + hi
        shift = np.where(curve > 0, 0.5 * (lo - hi) / np.where(curve > 0, curve, 1.0), 0.0)
        delay[inner] += np.clip(shift, -1, 1) * (offsets[1] - offsets[0])
    return fit_at(fractional_delay(body, -delay / dt))[0]


def delayed_copies(x: np.ndarray, delays: np.ndarray, half_width: int = 32):
    """``fractional_delay(x, d)`` for each d of ``delays`` (samples; one delay for every row), as a generator.

    Every row shares the delay, so the taps are one filter: x's spectrum is taken once and each copy is one
    product and one inverse FFT, where fractional_delay sums 2 half_width + 1 shifted arrays per call. With the
    seat filtered once, it makes the skew search faster (benchmarks/README.md, "Summary")."""
    whole, taps = delay_taps(delays, half_width)
    pad = half_width + int(np.abs(whole).max(initial=0))
    padded = np.pad(x, ((0, 0), (pad, pad)), mode="edge")
    n_fft = 1 << int(np.ceil(np.log2(padded.shape[1] + 2 * half_width)))  # a linear, not circular, convolution
    spectrum = np.fft.rfft(padded, n_fft, axis=1)
    length = x.shape[1]
    for w, h in zip(whole, taps):
        # fractional_delay's out[k] = sum_j h[j] padded[pad - w - half_width + k + 2 half_width - j]
        full = np.fft.irfft(spectrum * np.fft.rfft(h, n_fft), n_fft, axis=1)
        yield full[:, pad - w + half_width : pad - w + half_width + length]


def fit_fixed(fix: str, seat, body, rel_vel, rel_disp, dt: float, measurement: str, fir, skew_max: float):
    """p (n, 2) of windows (n, W) by the fit with ``fix``'s extra parameter (``rel_vel``, ``rel_disp``: the
    regressors integrated from t0 and cropped, as the data module serves them)."""
    if fix == "gain":
        return fit_gain(seat, body, dt, measurement, fir)
    if fix == "hardening":
        return fit_hardening(seat, rel_vel, rel_disp, fir)
    return fit_skew(seat, body, dt, measurement, fir, skew_max)
