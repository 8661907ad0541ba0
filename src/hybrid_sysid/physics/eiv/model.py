"""The errors-in-variables model of a recording: its transfer polynomials, frequency grid, noise weight and
error spectra (physics.eiv's docstring has the likelihood they make).

Models (``model``):

- "discrete": the simulator's symplectic Euler step with the "consistent" recording, derived from
  quarter_car.step: with r_k = w_k - v_k and d_k = z_k - y_k, S_k = -p1 (r_k - dt U_k) - p2 d_k,
  r_{k+1} = r_k + dt (S_k - U_k), d_{k+1} = d_k + dt r_{k+1}, so that S[k] pairs with U[k] (no delay):
  A = 1 + (p1 dt + p2 dt^2 - 2) z^-1 + (1 - p1 dt) z^-2, B = p1 dt + (p2 dt^2 - p1 dt) z^-1, m = 2. Exact: a clean
  consistent window gives p to rounding.
- "continuous": recordings that sample the continuous motion (physics.exact) obey
  G(s) = (p1 s + p2) / (s^2 + p1 s + p2) at s = i omega, and no rational function of z reproduces that exactly.
  s is replaced by a rational approximation of ln(z) / dt = (2 / dt) artanh(w), w = (1 - z^-1) / (1 + z^-1),
  the [5/4] Pade approximant of artanh in w:

      s ~ (2 / dt) w (945 - 735 w^2 + 64 w^4) / (945 - 1050 w^2 + 225 w^4),

  and A, B are s^2 + p1 s + p2 and p1 s + p2 times the denominator squared: polynomials of degree 10 in z^-1, so
  m = 10 transient coefficients, and the noise model stays exact. On the unit circle the map is purely imaginary
  (no damping error) with a relative frequency error of 1e-11 at 10 Hz, 2e-8 at 20 Hz and 7e-5 at 45 Hz at
  dt = 5 ms (the road's highest frequency at 15 m/s is 45 Hz). Measured on clean exact recordings (5 road classes
  x 6 recordings, m3 in 50..200 kg, C3 and K3 spread by 30%, 90 windows of 500 samples at random starts,
  dt = 5 ms): relative error of p mean 1.2e-10 / 1.9e-11 (p1 / p2), worst 1.3e-9 / 2.6e-10; band-passed least
  squares (fit_windows, 4-20 Hz, 151 taps) on the same windows: mean 1.4e-5 / 2.3e-5, worst 5.4e-5 / 8.7e-5. The
  lower-order maps were measured too: Tustin (m = 2) 0.2% / 0.4%, the [3/2] approximant (m = 6) 3e-8 / 3e-8. Ten
  transient coefficients instead of four (the [1/2] approximant) cost 0.3% in the Cramer-Rao bound of these windows.
  The alternative of evaluating A and B at s_k = i omega_k leaves the leakage term a non-polynomial function of
  k (the DFT of a sampled window aliases its edge jumps), which a polynomial I models only approximately.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numpy.polynomial import polynomial as poly

from hybrid_sysid.core.checks import bad, check_choice, check_dt, check_number

MODELS = ("discrete", "continuous")
# lambda beyond it leaves the fit as it is (the body channel then counts as noise alone); near 1e300 the weights
# overflow and no window converges
NOISE_RATIO_MAX = 1e6
CHUNK = 1 << 17  # windows x frequencies in one block: bounds the ~40 arrays of that size an iteration makes

# artanh(w) / w ~ (1 - 735 t / 945 + 64 t^2 / 945) / (1 - 1050 t / 945 + 225 t^2 / 945), t = w^2: its [2/2] Pade
# approximant, the continuous model's map from z to s (module docstring)
_PADE_NUM = (1.0, -735.0 / 945.0, 64.0 / 945.0)
_PADE_DEN = (1.0, -1050.0 / 945.0, 225.0 / 945.0)


def eiv_model(measurement: str) -> str:
    """The model that describes a recording of this measurement (``model`` of fit_eiv and crb_relative_std)."""
    return "continuous" if measurement == "continuous" else "discrete"


class Grid(NamedTuple):
    weight: np.ndarray  # (K,) the half spectrum's multiplicity in the full grid: 1 at DC and Nyquist, else 2
    polys: np.ndarray  # (5, K) complex: a0, a1, a2, b1, b2 on the grid
    basis: np.ndarray  # (K, M) complex: z^-j, -lead <= j < m + lag, the transient's polynomial
    cos: np.ndarray  # (K, M) cos(j theta_k), j < M: the transient's normal matrix is Toeplitz in sum w cos(j theta_k)
    toeplitz: np.ndarray  # (M, M) |i - j|
    basis_re: np.ndarray  # (K, M) basis.real and basis.imag, contiguous: Re(x @ basis) as two real products
    basis_im: np.ndarray


def re_basis(x, grid: Grid, conj: bool = False):
    """Re(x @ basis), or Re(x @ conj(basis)), for complex x (..., K): two real products, where the complex one
    does four and keeps an imaginary part that is thrown away (the skew fix's fit spent a third of its time here)."""
    shape = x.shape
    x = x.reshape(-1, shape[-1])  # one product for a stack: matmul would loop over the leading axes
    # contiguous copies: the strided .real view would keep matmul off BLAS
    real = np.ascontiguousarray(x.real) @ grid.basis_re
    imag = np.ascontiguousarray(x.imag) @ grid.basis_im
    return (real + imag if conj else real - imag).reshape(shape[:-1] + (-1,))


def transfer_polynomials(model: str, dt: float) -> np.ndarray:
    """a0, a1, a2, b1, b2 as polynomials in z^-1 (ascending powers), rows of one length m + 1."""
    if model == "discrete":
        return np.array(
            [
                [1.0, -2.0, 1.0],
                [0.0, dt, -dt],
                [0.0, dt * dt, 0.0],
                [dt, -dt, 0.0],
                [0.0, dt * dt, 0.0],
            ]
        )
    # dt s = 2 num / den with w = (1 - x) / (1 + x), x = z^-1, both brought to degree d over (1 + x)^d
    d = max(2 * len(_PADE_NUM) - 1, 2 * len(_PADE_DEN) - 2)
    nw, dw = np.array([1.0, -1.0]), np.array([1.0, 1.0])

    def homogeneous(coef, odd):
        terms = [
            c * poly.polymul(poly.polypow(nw, 2 * j + odd), poly.polypow(dw, d - 2 * j - odd))
            for j, c in enumerate(coef)
        ]
        return np.sum([np.pad(t, (0, d + 1 - len(t))) for t in terms], axis=0)

    num, den = 2.0 * homogeneous(_PADE_NUM, 1), homogeneous(_PADE_DEN, 0)
    # (s^2 + p1 s + p2) den^2 dt^2 and (p1 s + p2) den^2 dt^2: scaled like the discrete model's
    a1 = dt * poly.polymul(num, den)
    a2 = dt * dt * poly.polymul(den, den)
    return np.stack([poly.polymul(num, num), a1, a2, a1, a2])


@lru_cache(maxsize=16)
def frequency_grid(model: str, dt: float, n_samples: int, lead: int = 0, lag: int = 0) -> Grid:
    """The frequency grid of windows of n_samples, the transient's basis widened by ``lead`` powers of z and
    ``lag`` more of z^-1 (the skew fix's edges)."""
    coef = transfer_polynomials(model, dt)
    m = coef.shape[1] - 1
    k = np.arange(n_samples // 2 + 1)
    x = np.exp(-2j * np.pi * k / n_samples)
    weight = np.full(len(k), 2.0)
    weight[0] = 1.0
    if n_samples % 2 == 0:
        weight[-1] = 1.0
    basis = x[:, None] ** np.arange(-lead, m + lag)
    j = np.arange(basis.shape[1])
    cos = basis.real.copy() if lead == 0 else (x[:, None] ** j).real
    polys = np.stack([poly.polyval(x, c) for c in coef])
    grid = Grid(weight, polys, basis, cos, np.abs(j[:, None] - j[None, :]), basis.real.copy(), basis.imag.copy())
    for array in grid:  # shared by every call through the cache
        array.flags.writeable = False
    return grid


def weight_coefficients(grid: Grid, lam: float) -> np.ndarray:
    """W = |A|^2 + lam |B|^2 = q0 + 2 p1 q1 + 2 p2 q2 + p1^2 q3 + 2 p1 p2 q4 + p2^2 q5 on the grid: (6, K)."""
    a0, a1, a2, b1, b2 = grid.polys

    def dot(u, v):
        return (u.conj() * v).real

    return np.stack(
        [
            dot(a0, a0),
            dot(a0, a1),
            dot(a0, a2),
            dot(a1, a1) + lam * dot(b1, b1),
            dot(a1, a2) + lam * dot(b1, b2),
            dot(a2, a2) + lam * dot(b2, b2),
        ]
    )


def noise_weight(p, q):
    p1, p2 = p[:, :1], p[:, 1:]
    return q[0] + p1 * (2.0 * q[1] + p1 * q[3]) + p2 * (2.0 * q[2] + 2.0 * p1 * q[4] + p2 * q[5])


def error_spectra(seat, body, grid):
    """E0, E1, E2 (3, n, K): A S - B U = E0 + p1 E1 + p2 E2 is affine in p."""
    s, u = np.fft.rfft(seat, axis=-1), np.fft.rfft(body, axis=-1)
    a0, a1, a2, b1, b2 = grid.polys
    return np.stack([a0 * s, a1 * s - b1 * u, a2 * s - b2 * u])


def as_windows(seat, body):
    seat = np.asarray(seat, dtype=np.float64)
    body = np.asarray(body, dtype=np.float64)
    if seat.ndim == 1 and body.ndim == 1:
        seat, body = seat[None], body[None]
    if seat.ndim != 2 or seat.shape != body.shape:
        bad("body", f"shape {body.shape}", f"the seat's shape {seat.shape}, windows (n, N)")
    good = np.isfinite(seat).all(axis=1) & np.isfinite(body).all(axis=1)
    seat = np.where(good[:, None], seat, 0.0)
    body = np.where(good[:, None], body, 0.0)
    good &= (seat != 0).any(axis=1) | (body != 0).any(axis=1)
    return seat, body, good


def check_noise_ratio(noise_ratio) -> float:
    """lambda = sigma_body^2 / sigma_seat^2 in [0, NOISE_RATIO_MAX]: the one check of every noise_ratio (fit_eiv,
    crb_relative_std, the eiv baselines); returns it."""
    return check_number("noise_ratio", noise_ratio, 0, NOISE_RATIO_MAX, unit="sigma_body^2 / sigma_seat^2")


def setup_windows(seat, body, dt, noise_ratio, model):
    check_choice("model", model, MODELS)
    dt = check_dt(dt)
    lam = check_noise_ratio(noise_ratio)
    seat, body, good = as_windows(seat, body)
    grid = frequency_grid(model, dt, seat.shape[1])
    m = grid.basis.shape[1]
    if seat.shape[1] < m + 3:
        bad("seat", f"windows of {seat.shape[1]} samples", f"at least {m + 3} samples for the {model} model")
    return seat, body, good, grid, weight_coefficients(grid, lam)
