"""Each accelerometer's calibration gain: its output is its true acceleration times its own gain (docs/faults.md).

Its fix, "gain": with g = g_seat / g_body, the recorded seat a_s obeys a_s = -p1 V_s - p2 X_s + g p1 V_b + g p2 X_b,
where (V_s, X_s) and (V_b, X_b) integrate the recorded seat and body on their own: linear in four coefficients, of
which the first two are p. In the likelihood, A S = g B U + I with eta = log g within GAIN_BOX; the noise is the
recorded channels' (the simulator adds it after the gain), so W = |A|^2 + lambda g^2 |B|^2 (physics.eiv.faults).
"""

from __future__ import annotations

import numpy as np

from hybrid_sysid.physics.faults.base import Fault, Setting, value_of
from hybrid_sysid.physics.faults.fix import Fix, lstsq_columns
from hybrid_sysid.physics.integrate import relative_states

GAIN_BOX = (1.0 / 3.0, 3.0)  # g = g_seat / g_body in the likelihood fit


def fit_gain(seat, body, dt: float, measurement: str, fir: np.ndarray) -> np.ndarray:
    """p (n, 2) with each sensor's gain unknown: four regressors, the seat's and the body's integrals apart."""
    zero = np.zeros_like(np.asarray(seat, dtype=np.float64))
    vs, xs = relative_states(seat, zero, dt, measurement)
    vb, xb = relative_states(zero, body, dt, measurement)  # minus the body's: relative_states is linear
    return lstsq_columns([-vs, -xs, -vb, -xb], seat, fir)[:, :2]


class GainFix(Fix):
    name = "gain"

    def least_squares(self, seat, body, rel_vel, rel_disp, dt, measurement, fir, skew_max):
        return fit_gain(seat, body, dt, measurement, fir)

    def eiv_bound(self, skew_max, dt):
        return tuple(np.log(GAIN_BOX))

    def body_factor(self, eta, n_samples):
        g = np.exp(eta)[:, None]
        return g, g, g, g * g, 2.0 * g * g, 4.0 * g * g

    def eiv_fault(self, eta, dt):
        return np.exp(eta)


class Gain(Fault):
    name = "gain"
    settings = (
        Setting(
            "gain_spread",
            0.0,
            "each sensor's calibration gain (sensitivity) error",
            unit="fraction",
            drawn="each sensor's gain uniform in [1 - s, 1 + s]",
            preset="`sensor=gain`: 0.03",
            high=1.0,
            high_open=True,
            allowed="gains in [1 - s, 1 + s]",
            keyed_at_default=True,
        ),
    )
    fix = "gain"  # the ratio of the two gains fitted with p
    fix_code = GainFix()
    fix_rank = 30
    order = 20
    compiled = True

    def draw(self, config, n, rng):
        """(n, 2) gains, seat then body; exactly 1 when off."""
        return 1.0 + value_of(config, self.settings[0]) * rng.uniform(-1.0, 1.0, size=(n, 2))

    def apply(self, seat, body, draw, dt, **context):
        return draw[:, :1] * seat, draw[:, 1:] * body
