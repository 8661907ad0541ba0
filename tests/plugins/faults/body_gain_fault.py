"""A fault with a fix of its own, declared outside hybrid_sysid (tests/baselines/test_fix_plugin.py): the body
sensor's gain b alone is off, and its fix "body_gain" fits it with p by least squares and by the likelihood."""

import numpy as np

from hybrid_sysid.physics.faults import Fault, Fix, Setting, lstsq_columns, value_of
from hybrid_sysid.physics.integrate import relative_states


class BodyGainFix(Fix):
    """The recorded body is b u, so the seat a_s = -p1 V_s - p2 X_s + (p1 / b) V_b + (p2 / b) X_b, where V, X
    integrate each recorded channel on its own; in the likelihood A S = (1 / b) B U, eta = -log b."""

    name = "body_gain"
    calls = 0  # how often a fit ran this code: the test's proof that the fit used it

    def least_squares(self, seat, body, rel_vel, rel_disp, dt, measurement, fir, skew_max):
        type(self).calls += 1
        zero = np.zeros_like(np.asarray(seat, dtype=np.float64))
        vs, xs = relative_states(seat, zero, dt, measurement)
        vb, xb = relative_states(zero, body, dt, measurement)
        return lstsq_columns([-vs, -xs, -vb, -xb], seat, fir)[:, :2]

    def eiv_bound(self, skew_max, dt):
        return -np.log(2.0), np.log(2.0)  # b within [1/2, 2]

    def body_factor(self, eta, n_samples):
        type(self).calls += 1
        phi = np.exp(eta)[:, None]
        return phi, phi, phi, phi * phi, 2.0 * phi * phi, 4.0 * phi * phi

    def eiv_fault(self, eta, dt):
        return np.exp(-eta)  # b


class BodyGain(Fault):
    name = "body_gain"
    settings = (
        Setting(
            "body_gain_spread",
            0.0,
            "the body sensor's gain error",
            unit="fraction",
            drawn="the body sensor's gain uniform in [1 - s, 1 + s]",
            high=0.5,
        ),
    )
    fix = "body_gain"
    fix_code = BodyGainFix()
    fix_rank = 5  # before the package's fixes, when it is on with them
    order = 21  # after the gain

    def draw(self, config, n, rng):
        return 1.0 + value_of(config, self.settings[0]) * rng.uniform(-1.0, 1.0, size=n)

    def apply(self, seat, body, draw, dt, **context):
        return seat, draw[:, None] * body
