"""Recording faults of the two accelerometers (docs/faults.md): calibration gain, time skew, anti-alias low-pass.

A recording's seat and body channels are what two real sensors would give: each has its own gain error and its
own analogue low-pass before sampling, and the body sensor's clock may run ahead of or behind the seat sensor's.
``SensorFaults`` holds the magnitudes (``sensor.*`` config keys), ``draw`` gives each recording its own faults,
``apply`` puts them on the clean signals. Plain numpy; the dataset runs the same arithmetic compiled
(physics.compiled_sensors, tested equal).

Conventions: a delay of d samples gives out[k] = x(k - d), so d > 0 is a late sensor; a skew tau seconds is a
delay of tau / dt samples of the body channel against the seat channel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from hybrid_sysid.core.checks import bad, check_number

# Kaiser window of the fractional-delay interpolator: beta grows with the half width up to where rounding, not
# the window, sets the error (docs/faults.md: the measured accuracy against the analytic shift)
BETA_PER_TAP = 1.75
BETA_MAX = 40.0


class FaultDraws(NamedTuple):
    """Per recording: ``gains`` (n, 2) seat then body; ``skews`` (n,) seconds, the body sensor's delay against the
    seat sensor; ``cutoffs`` (n, 2) Hz, seat then body, or None (no low-pass)."""

    gains: np.ndarray
    skews: np.ndarray
    cutoffs: np.ndarray | None


@dataclass(frozen=True)
class SensorFaults:
    """The faults' magnitudes; every one off by default. Each recording draws its own values (``draw``)."""

    gain_spread: float = 0.0  # each sensor's gain uniform in [1 - s, 1 + s]
    skew_max: float = 0.0  # seconds: the body sensor's delay against the seat sensor uniform in [-skew_max, skew_max]
    lowpass_hz: tuple | None = None  # (seat, body) cut-offs, Hz, the same for every recording
    lowpass_range_hz: tuple | None = None  # (lo, hi) Hz: each sensor of each recording draws its cut-off there

    def __post_init__(self):
        # a config's list as a tuple of floats: hashable, and [20, 40] gives the cache key of [20.0, 40.0]
        for name in ("lowpass_hz", "lowpass_range_hz"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, (str, int, float)):
                try:
                    value = tuple(float(v) for v in value)
                except (TypeError, ValueError):
                    value = tuple(value)  # validate names it
                object.__setattr__(self, name, value)

    @property
    def active(self) -> bool:
        lowpass = self.lowpass_hz is not None or self.lowpass_range_hz is not None
        return bool(self.gain_spread or self.skew_max or lowpass)

    def validate(self, dt: float, window: int | None = None) -> None:
        """ConfigError naming ``sensor.<key>``; ``window``: the steps a network reads, which a skew must stay within."""
        check_number("sensor.gain_spread", self.gain_spread, 0, 1, high_open=True, unit="gains in [1 - s, 1 + s]")
        check_number("sensor.skew_max", self.skew_max, 0, unit="seconds")
        if window is not None and self.skew_max >= window * dt:
            bad(
                "sensor.skew_max",
                self.skew_max,
                f"must be < data.window x data.dt = {window * dt:g} s: a skew beyond the window",
            )
        if self.lowpass_hz is not None and self.lowpass_range_hz is not None:
            bad("sensor.lowpass_range_hz", list(self.lowpass_range_hz), "null when sensor.lowpass_hz is set")
        nyquist = 0.5 / dt
        for name, pair in (("lowpass_hz", self.lowpass_hz), ("lowpass_range_hz", self.lowpass_range_hz)):
            if pair is None:
                continue
            values = list(pair) if isinstance(pair, tuple) else pair
            ok = (
                isinstance(pair, tuple)
                and len(values) == 2
                and all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and 0 < v < nyquist
                    for v in values
                )
            )
            if not ok:
                bad(f"sensor.{name}", values, f"two cut-offs in (0, {nyquist:g}) Hz (below Nyquist, 0.5 / data.dt)")
            if name == "lowpass_range_hz" and values[0] > values[1]:
                bad(f"sensor.{name}", values, "[lo, hi] with lo <= hi (Hz)")

    def draw(self, n: int, rng: np.random.Generator) -> FaultDraws:
        """Each recording's faults. Every fault's unit variates are drawn always, in one order (gains, skews,
        cut-offs), and scaled after: turning one fault on or off leaves the others' draws as they were."""
        u_gain = rng.uniform(-1.0, 1.0, size=(n, 2))
        u_skew = rng.uniform(-1.0, 1.0, size=n)
        u_cut = rng.uniform(0.0, 1.0, size=(n, 2))
        cutoffs = None
        if self.lowpass_hz is not None:
            cutoffs = np.tile(np.asarray(self.lowpass_hz, dtype=np.float64), (n, 1))
        elif self.lowpass_range_hz is not None:
            lo, hi = self.lowpass_range_hz
            cutoffs = lo + (hi - lo) * u_cut
        return FaultDraws(1.0 + self.gain_spread * u_gain, self.skew_max * u_skew, cutoffs)


def butterworth(cutoff_hz, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of the 2nd-order Butterworth low-pass per cut-off, by the bilinear transform with the cut-off
    pre-warped (scipy.signal.butter's design): rows (n, 3) each, a[:, 0] = 1."""
    k = np.tan(np.pi * np.asarray(cutoff_hz, dtype=np.float64) * dt)
    norm = 1.0 / (1.0 + math.sqrt(2.0) * k + k * k)
    b0 = k * k * norm
    b = np.stack([b0, 2.0 * b0, b0], axis=-1)
    a = np.stack([np.ones_like(k), 2.0 * (k * k - 1.0) * norm, (1.0 - math.sqrt(2.0) * k + k * k) * norm], axis=-1)
    return b, a


def lowpass(x: np.ndarray, cutoff_hz, dt: float) -> np.ndarray:
    """Each row of x (n, T) through its own causal 2nd-order Butterworth low-pass (``cutoff_hz``: (n,) or a
    scalar), from rest: what an analogue anti-alias filter does, phase lag included. Transposed direct form II,
    as scipy.signal.lfilter."""
    x = np.asarray(x, dtype=np.float64)
    b, a = butterworth(np.broadcast_to(cutoff_hz, x.shape[:1]), dt)
    b0, b1, b2, a1, a2 = b[:, 0], b[:, 1], b[:, 2], a[:, 1], a[:, 2]
    out = np.empty_like(x)
    z1, z2 = np.zeros(len(x)), np.zeros(len(x))
    for k in range(x.shape[1]):
        xk = x[:, k]
        yk = b0 * xk + z1
        z1 = b1 * xk - a1 * yk + z2
        z2 = b2 * xk - a2 * yk
        out[:, k] = yk
    return out


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


def apply(seat: np.ndarray, body: np.ndarray, draws: FaultDraws, dt: float, half_width: int = 32):
    """The faulted (seat, body), each (n, T) float64: each sensor's own low-pass, then its gain, then the body
    channel's skew (a fractional delay of skew / dt samples; its edges as ``fractional_delay`` says)."""
    seat, body = np.asarray(seat, dtype=np.float64), np.asarray(body, dtype=np.float64)
    if draws.cutoffs is not None:
        seat, body = lowpass(seat, draws.cutoffs[:, 0], dt), lowpass(body, draws.cutoffs[:, 1], dt)
    seat = draws.gains[:, :1] * seat
    body = draws.gains[:, 1:] * body
    if np.any(draws.skews != 0):
        body = fractional_delay(body, draws.skews / dt, half_width)
    return seat, body
