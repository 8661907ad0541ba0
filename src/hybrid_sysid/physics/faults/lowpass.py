"""Each sensor's analogue anti-alias filter: a 2nd-order Butterworth low-pass per sensor, fixed or drawn per recording
(docs/faults.md, "Low-pass")."""

from __future__ import annotations

import math

import numpy as np

from hybrid_sysid.core.checks import bad
from hybrid_sysid.physics.faults.base import Fault, Setting, value_of


class Lowpass(Fault):
    name = "lowpass"
    settings = (
        Setting(
            "lowpass_hz",
            None,
            "each sensor's analogue anti-alias filter, the same on every recording",
            unit="Hz, [seat, body]",
            pair=True,
            keyed_at_default=True,
        ),
        Setting(
            "lowpass_range_hz",
            None,
            "each sensor's anti-alias filter, different in every recording",
            unit="Hz, [lo, hi]",
            drawn="each sensor's cut-off uniform in [lo, hi]",
            preset="`sensor=lowpass`: [20, 40]",
            pair=True,
            keyed_at_default=True,
        ),
    )
    # in the seat band a low-pass that differs between the sensors is close to a delay: the skew's fix
    fix = "skew"
    fix_rank = 20
    order = 10
    compiled = True

    def validate(self, config, dt, window=None, measurement=None):
        fixed, ranged = (value_of(config, s) for s in self.settings)
        if fixed is not None and ranged is not None:
            bad("sensor.lowpass_range_hz", list(ranged), "null when sensor.lowpass_hz is set")
        nyquist = 0.5 / dt
        for name, pair in (("lowpass_hz", fixed), ("lowpass_range_hz", ranged)):
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

    def draw(self, config, n, rng):
        """(n, 2) cut-offs in Hz, seat then body, or None (no low-pass)."""
        u_cut = rng.uniform(0.0, 1.0, size=(n, 2))
        fixed, ranged = (value_of(config, s) for s in self.settings)
        if fixed is not None:
            return np.tile(np.asarray(fixed, dtype=np.float64), (n, 1))
        if ranged is not None:
            lo, hi = ranged
            return lo + (hi - lo) * u_cut
        return None

    def apply(self, seat, body, draw, dt, **context):
        if draw is None:
            return seat, body
        return lowpass(seat, draw[:, 0], dt), lowpass(body, draw[:, 1], dt)


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
