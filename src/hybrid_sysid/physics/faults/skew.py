"""The body sensor's clock against the seat sensor's: the body channel delayed by tau seconds, drawn per recording.

Conventions: a delay of d samples gives out[k] = x(k - d), so d > 0 is a late sensor; a skew tau seconds is a
delay of tau / dt samples of the body channel against the seat channel (docs/faults.md, "Skew").

Its fix, "skew" (``SkewFix``): least squares moves the body channel back by each offset of a grid and keeps the
offset whose fit leaves the least residual; the likelihood advances the body by a Kaiser-windowed sinc whose
delay is fitted with p (physics.eiv.faults explains the edges and the accuracy).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from hybrid_sysid.core.checks import bad, check_number
from hybrid_sysid.physics.faults.base import Fault, Setting, value_of
from hybrid_sysid.physics.faults.fix import Fix
from hybrid_sysid.physics.filters import fir_valid
from hybrid_sysid.physics.integrate import relative_states
from hybrid_sysid.physics.seat_fit import fit_seat

# Kaiser window of the fractional-delay interpolator: beta grows with the half width up to where rounding, not
# the window, sets the error (docs/faults.md: the measured accuracy against the analytic shift)
BETA_PER_TAP = 1.75
BETA_MAX = 40.0
# the dataset's interpolator: 25 taps, within ~1.2e-8 of the signal's peak up to half the Nyquist frequency
# (docs/faults.md), below the float32 rounding of the stored channels (6e-8 of a value)
DELAY_HALF_WIDTH = 12
SKEW_HALF_WIDTH = 8  # the likelihood's advance: a Kaiser-windowed sinc of 2 x 8 + 2 taps (physics.eiv.faults)
SKEW_STEP = 1.0  # samples between the offsets of the likelihood's coarse search over [-skew_max, skew_max]


def check_skew_max(skew_max) -> float:
    """The largest offset of the body sensor the skew fix considers: seconds >= 0, the one check of fit_eiv's and
    the baselines' skew_max; returns it."""
    return check_number("skew_max", skew_max, 0, unit="seconds")


class SkewFix(Fix):
    name = "skew"

    def least_squares(self, seat, body, rel_vel, rel_disp, dt, measurement, fir, skew_max):
        return fit_skew(seat, body, dt, measurement, fir, skew_max)

    def eiv_bound(self, skew_max, dt):
        return -skew_max / dt, skew_max / dt

    def eiv_edges(self, skew_max, dt):
        """The advance's reach and its sinc's half width."""
        reach = skew_max / dt
        return int(np.floor(reach)) + SKEW_HALF_WIDTH + 1, int(np.ceil(reach)) + SKEW_HALF_WIDTH

    def eiv_starts(self, lo, hi):
        return np.linspace(lo[2], hi[2], 2 * int(np.ceil(hi[2] / SKEW_STEP)) + 1)

    def body_factor(self, eta, n_samples):
        h, h1, h2 = advance(eta, n_samples, SKEW_HALF_WIDTH)
        return h, h1, h2, abs2(h), 2.0 * (h.conj() * h1).real, 2.0 * (abs2(h1) + (h.conj() * h2).real)

    def eiv_fault(self, eta, dt):
        return eta * dt


class Skew(Fault):
    name = "skew"
    settings = (
        Setting(
            "skew_max",
            0.0,
            "the body sensor's clock offset against the seat sensor's",
            unit="s",
            drawn="the body channel's delay uniform in [-skew_max, skew_max]",
            preset="`sensor=skewed`: 0.01",
            allowed="seconds",
            keyed_at_default=True,
        ),
    )
    fix = "skew"  # the body's offset fitted with p
    fix_code = SkewFix()
    fix_rank = 20
    order = 30
    compiled = True

    def validate(self, config, dt, window=None, measurement=None):
        super().validate(config, dt, window, measurement)
        skew_max = value_of(config, self.settings[0])
        if window is not None and skew_max >= window * dt:
            bad(
                "sensor.skew_max",
                skew_max,
                f"must be < data.window x data.dt = {window * dt:g} s: a skew beyond the window",
            )

    def draw(self, config, n, rng):
        """(n,) seconds, the body sensor's delay; exactly 0 when off."""
        return value_of(config, self.settings[0]) * rng.uniform(-1.0, 1.0, size=n)

    def apply(self, seat, body, draw, dt, **context):
        if np.any(draw != 0):
            body = fractional_delay(body, draw / dt, context.get("half_width", 32))
        return seat, body

    def margin(self, config, dt):
        """The delay's reach with the dataset's interpolator (data.dataset pads each recording by it)."""
        skew_max = value_of(config, self.settings[0])
        return DELAY_HALF_WIDTH + math.ceil(skew_max / dt) + 1 if skew_max else 0


def delay_taps(delay, half_width: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """(whole, taps): each delay split into the nearest integer and a fraction f in [-0.5, 0.5], and the
    2 half_width + 1 taps h_j = sinc(j - f) w(j - f), j = -half_width..half_width, of a Kaiser window w of
    half-length half_width + 1. A whole delay (f = 0) gets the unit impulse, so it shifts exactly."""
    delay = np.atleast_1d(np.asarray(delay, dtype=np.float64))
    whole = np.rint(delay)
    frac = delay - whole
    u = np.arange(-half_width, half_width + 1) - frac[:, None]
    beta = min(BETA_PER_TAP * half_width, BETA_MAX)
    window = np.i0(beta * np.sqrt(np.clip(1.0 - (u / (half_width + 1)) ** 2, 0.0, None))) / np.i0(beta)
    taps = np.sinc(u) * window
    taps[frac == 0] = np.arange(-half_width, half_width + 1) == 0
    return whole.astype(np.int64), taps


def fractional_delay(x: np.ndarray, delay, half_width: int = 32) -> np.ndarray:
    """x (n, T) with row i delayed by delay[i] samples (fractional, either sign): out[k] = x(k - d), the
    band-limited interpolation of the samples by a Kaiser-windowed sinc of 2 half_width + 1 taps.

    Exact for a whole number of samples. Otherwise the error is below 3e-13 of the signal's peak for content up
    to half the Nyquist frequency at half_width >= 24, 5e-11 at 16 (docs/faults.md). Beyond the array the
    signal is taken as its edge value, so the first and last half_width + ceil(|d|) samples of a row are not
    exact; the dataset pads each recording with what lies there instead (data.dataset)."""
    x = np.asarray(x, dtype=np.float64)
    n, length = x.shape
    whole, taps = delay_taps(np.broadcast_to(delay, (n,)), half_width)
    pad = half_width + int(np.abs(whole).max(initial=0))
    padded = np.pad(x, ((0, 0), (pad, pad)), mode="edge")
    # row i from padded index pad - whole_i - half_width on: its sample k + q is x[k - whole_i - (half_width - q)]
    start = pad - whole - half_width
    shifted = np.take_along_axis(padded, start[:, None] + np.arange(length + 2 * half_width), axis=1)
    out = np.zeros_like(x)
    for q in range(2 * half_width + 1):
        out += taps[:, 2 * half_width - q, None] * shifted[:, q : q + length]
    return out


def fit_skew(seat, body, dt: float, measurement: str, fir: np.ndarray, skew_max: float, grid: int = 21) -> np.ndarray:
    """p (n, 2) with the body sensor's time offset unknown, searched per window over ``grid`` offsets in
    [-skew_max, skew_max] seconds, then refined by the parabola through the best offset and its neighbours.

    The body window is moved back by each offset (``fractional_delay``) and re-integrated from the window's start;
    the delay's inexact edge samples only shift the integrals by a constant and a ramp at the start, which the
    band-pass removes, and lie in the part 'valid' drops at the end."""
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
    ``delay_taps``, zero for |u| >= half_width + 1, where the sinc itself vanishes as a tap enters or leaves, so
    the advance is continuous in the delay. The derivatives by central differences: the kernel is analytic within
    its support, and their error (1e-10, 1e-8) is far below what the Newton steps need."""
    support = half_width + 1
    beta = min(BETA_PER_TAP * half_width, BETA_MAX)

    def k(v):
        t = np.sqrt(np.clip(1.0 - (v / support) ** 2, 0.0, None))
        return np.where(np.abs(v) < support, np.sinc(v) * np.i0(beta * t), 0.0) / np.i0(beta)

    e1, e2 = 1e-5, 1e-4
    # the five points in one call: np.i0's cost is mostly its per-call overhead at these sizes
    k0, k1p, k1m, k2p, k2m = k(np.stack([u, u + e1, u - e1, u + e2, u - e2]))
    return k0, (k1p - k1m) / (2.0 * e1), (k2p - 2.0 * k0 + k2m) / (e2 * e2)


def advance(delay, n_samples: int, half_width: int):
    """H_k = sum_p K(p - d) z_k^p over the taps |p - d| < half_width + 1, and its first two derivatives in d, on
    the half spectrum (n, K): the body channel advanced by d samples (the skew fix)."""
    whole = np.floor(delay)
    low, high = int(whole.min()) - half_width, int(whole.max()) + half_width + 1
    taps = advance_kernel(np.arange(low, high + 1) - delay[:, None], half_width)
    h = np.concatenate(taps) @ unit_powers(n_samples, low, high)
    n = len(delay)
    return h[:n], -h[n : 2 * n], h[2 * n :]
