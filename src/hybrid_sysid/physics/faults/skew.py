"""The body sensor's clock against the seat sensor's: the body channel delayed by tau seconds, drawn per recording.

Conventions: a delay of d samples gives out[k] = x(k - d), so d > 0 is a late sensor; a skew tau seconds is a
delay of tau / dt samples of the body channel against the seat channel (docs/faults.md, "Skew").
"""

from __future__ import annotations

import math

import numpy as np

from hybrid_sysid.core.checks import bad
from hybrid_sysid.physics.faults.base import Fault, Setting, value_of

# Kaiser window of the fractional-delay interpolator: beta grows with the half width up to where rounding, not
# the window, sets the error (docs/faults.md: the measured accuracy against the analytic shift)
BETA_PER_TAP = 1.75
BETA_MAX = 40.0
# the dataset's interpolator: 25 taps, within ~1.2e-8 of the signal's peak up to half the Nyquist frequency
# (docs/faults.md), below the float32 rounding of the stored channels (6e-8 of a value)
DELAY_HALF_WIDTH = 12


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
    fix = "skew"  # the body's offset fitted with p (baselines.fixes.fit_skew, physics.eiv "skew")
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
